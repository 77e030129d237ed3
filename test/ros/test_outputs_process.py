"""
``outputs_process``: a second process publishes the outputs, and subscribers see no difference.

The physics thread builds each message as before and hands a step's bytes to
the child (r2d2_sim/ros/relay.py); the child owns the publishers. What a
subscriber hears must be the very bytes, in the same order, of the node
publishing itself; a lockstep step returns once its messages are out;
the outputs still build only what someone takes; robots' publishers come
and go with the robots; a child that dies costs one error line, not the
physics; and destroying the node ends the child. The live view and the
recording move to the child with the publishing: the same MCAP file, byte
for byte, and a live view still builds only what a viewer takes. A child
whose disk is slow is waited for while its file grows; told to stop, it
drops what the disk has not taken and still finishes the file; a Ctrl-C
while it opens its sink leaves no child behind. A child behind but still
taking from the pipe is waited for past the deadline; one that takes nothing
until it passes is ended, and its publishers leave the graph.
"""

import json
import os
import random
import signal
import time

from nav_msgs.msg import Odometry
import pytest
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from helpers import make_sim, wait_for
from test_outputs_on_demand import drive_and_listen, NOISY, TOPICS

from r2d2_sim.errors import StartupError
from r2d2_sim.ros.relay import RelayedPublisher
from r2d2_sim.ros.robot_interfaces import DESCRIPTION_QOS
from r2d2_sim.testing import read_recording, SimHarness


def test_subscribers_hear_the_same_bytes_from_the_outputs_process(ros):
    direct, direct_sim = drive_and_listen(ros, 0)
    direct_state = direct_sim.simulation.robot.body.base_state()
    direct_sim.destroy_node()
    relayed, relayed_sim = drive_and_listen(ros, 0, outputs_process=True)
    assert relayed_sim.relay is not None
    assert isinstance(relayed_sim.robots[0].outputs.state[0]._publisher, RelayedPublisher)
    for topic in TOPICS:  # the same bytes in the same order (dicts keep arrival order)
        assert relayed[topic] and list(relayed[topic].items()) == list(direct[topic].items()), \
            topic
    assert relayed_sim.simulation.robot.body.base_state() == direct_state


def test_the_topics_belong_to_the_outputs_node_and_keep_their_qos(ros):
    sim = make_sim(ros, outputs_process=True)
    node = ros.create_node('looker', use_sim_time=False)
    assert wait_for(lambda: node.count_publishers('/odom') == 1
                    and node.count_publishers('/clock') == 1)
    assert wait_for(lambda: node.get_publishers_info_by_topic('/odom')[0].node_name
                    == 'r2d2_sim_outputs')
    info = node.get_publishers_info_by_topic('/odom')[0]
    expected = sim.robots[0].outputs.state[2]._publisher.qos_profile
    assert (info.qos_profile.reliability, info.qos_profile.durability) == (
        expected.reliability, expected.durability)
    # The latched description: a late joiner still gets it from the child.
    heard = []
    description = node.create_subscription(String, 'robot_description', heard.append,
                                           DESCRIPTION_QOS)
    assert wait_for(lambda: description.get_publisher_count() == 1)
    assert wait_for(lambda: len(heard) == 1) and heard[0].data.startswith('<?xml')


def test_a_lockstep_step_returns_once_its_messages_are_out(ros):
    sim = make_sim(ros, outputs_process=True)
    node = ros.create_node('listener', use_sim_time=False)
    clocks, states = [], []
    node.create_subscription(Clock, '/clock', clocks.append, 1000)
    joints = node.create_subscription(JointState, 'joint_states', states.append, 1000)
    assert wait_for(lambda: joints.get_publisher_count() == 1)
    publishers = [sim.robots[0].outputs.state[0]._publisher, sim._clock_output._publisher]
    # The child's matched events: what its writers publish before they match never arrives.
    assert wait_for(lambda: all(p.get_subscription_count() == 1 for p in publishers))
    sent = sim.relay.frames_sent
    sim.advance(10)
    assert sim.relay.frames_sent == sent + 11  # a frame a step, and the one asking for the answer
    assert sim.relay._acknowledged == sim.relay._sequence  # answered before advance returned
    # Out before advance returned: with the child stopped, every message still arrives.
    os.kill(sim.relay.process.pid, signal.SIGSTOP)
    try:
        assert wait_for(lambda: len(states) == 10)
    finally:
        os.kill(sim.relay.process.pid, signal.SIGCONT)
    assert [m.header.stamp.nanosec for m in states] == [
        step * 10**9 // 240 for step in range(1, 11)]
    assert wait_for(lambda: clocks and clocks[-1].clock.nanosec == 10 * 10**9 // 240)


def test_an_output_nobody_takes_is_not_handed_over(ros):
    sim = make_sim(ros, outputs_process=True, scan_rate=0.0, imu_rate=0.0)
    odom = sim.robots[0].outputs.state[2]._publisher
    handed = []
    publish = sim.relay.publish
    sim.relay.publish = lambda index, data: (handed.append(index), publish(index, data))
    sim.advance(24)
    assert odom.index not in handed
    node = ros.create_node('listener', use_sim_time=False)
    heard = []
    node.create_subscription(Odometry, 'odom', heard.append, 100)
    assert wait_for(lambda: odom.get_subscription_count() == 1)
    sim.advance(24)
    assert handed.count(odom.index) == 24
    assert wait_for(lambda: len(heard) == 24)


def test_a_deleted_robots_topics_leave_with_it(ros):
    sim = make_sim(ros, outputs_process=True, robots=['a', 'b'],
                   **{'b.initial_pose': [2.0, 0.0, 0.0]})
    node = ros.create_node('looker', use_sim_time=False)
    assert wait_for(lambda: node.count_publishers('/b/odom') == 1)
    held = sim.relay.describe()[1]
    with sim.lock:
        sim.simulation.delete_entity('b')
    assert sim.relay.describe()[1] < held
    sim.advance(1)
    assert wait_for(lambda: node.count_publishers('/b/odom') == 0)
    assert node.count_publishers('/a/odom') == 1


def test_a_dead_outputs_process_costs_one_error_line_not_the_physics(ros):
    sim = make_sim(ros, outputs_process=True)
    errors = []
    sim.relay._log_error = errors.append
    sim.advance(1)  # answered: the child runs, its handlers installed
    # SIGTERM: it ends at once but as an exit (SIGKILL would leave its shared memory behind).
    os.kill(sim.relay.process.pid, signal.SIGTERM)
    sim.relay.process.wait(10)
    before = sim.step_count
    for _ in range(3):
        sim.advance(24)
    assert sim.step_count == before + 72
    assert len(errors) == 1, errors
    assert 'the outputs process failed (it ended with status 143)' in errors[0]
    assert json.loads(sim.status())['outputs']['running'] is False


def test_the_status_says_whether_the_outputs_process_runs(ros):
    """~/get_status carries it: a dead child is found by asking, not only at the next write."""
    sim = make_sim(ros, outputs_process=True, scan_rate=0.0, imu_rate=0.0)
    sim.advance(1)  # answered: the child runs
    outputs = json.loads(sim.status())['outputs']
    assert outputs['running'] is True and outputs['frames'] >= 2 and outputs['publishers'] >= 5
    errors = []
    sim.relay._log_error = errors.append
    os.kill(sim.relay.process.pid, signal.SIGTERM)
    sim.relay.process.wait(10)
    assert json.loads(sim.status())['outputs']['running'] is False  # nothing published since
    assert len(errors) == 1 and errors[0].endswith('it ended; nothing more is published')
    assert 'outputs' not in json.loads(make_sim(ros, scan_rate=0.0).status())


def test_destroying_the_node_ends_the_outputs_process(ros):
    sim = make_sim(ros, outputs_process=True)
    process = sim.relay.process
    sim.advance(24)
    sim.destroy_node()
    assert process.poll() == 0
    assert sim.relay.process is None


def test_what_the_outputs_process_publishes_deserializes(ros):
    sim = make_sim(ros, outputs_process=True)
    node = ros.create_node('listener', use_sim_time=False)
    heard = []
    subscription = node.create_subscription(Odometry, 'odom', heard.append, 100, raw=True)
    assert wait_for(lambda: subscription.get_publisher_count() == 1)
    assert wait_for(lambda: sim.robots[0].outputs.state[2]._publisher.get_subscription_count())
    sim.advance(2)
    assert wait_for(lambda: len(heard) == 2)
    odom = deserialize_message(heard[-1], Odometry)
    assert (odom.header.frame_id, odom.child_frame_id) == ('odom', 'base_link')


def test_a_recording_gets_every_message_through_the_outputs_process(ros, tmp_path):
    """The child's sink logs the bytes it publishes, at the simulated time of their step."""
    recording = tmp_path / 'run.mcap'
    sim = make_sim(ros, outputs_process=True, cmd_vel_timeout=0.0, record=str(recording),
                   scan_rate=0.0)
    node = ros.create_node('listener', use_sim_time=False)
    heard = []
    subscription = node.create_subscription(Odometry, 'odom', heard.append, 1000)
    assert wait_for(lambda: subscription.get_publisher_count() == 1)
    # And the child's writer saw the reader: what it publishes before that never arrives.
    assert wait_for(lambda: sim.robots[0].outputs.state[2]._publisher.get_subscription_count())
    sim.simulation.robot.command(0.3, 0.0)
    sim.advance(120)
    assert wait_for(lambda: heard and heard[-1].header.stamp.nanosec == 120 * 10**9 // 240)
    assert heard[-1].pose.pose.position.x > 0.0
    sim.destroy_node()  # the recording is readable once closed
    recorded = read_recording(str(recording), topics=['/odom'])['/odom']
    assert [r.log_time_ns for r in recorded] == [step * 10**9 // 240 for step in range(121)]
    assert recorded[-1].message == heard[-1]


def test_the_in_process_harness_refuses_it_in_one_line():
    """Lockstep needs delivery within one process: SimHarness says so before anything starts."""
    with pytest.raises(StartupError) as refused:
        SimHarness(outputs_process=True)
    assert 'outputs_process' in str(refused.value) and 'SimProcess' in str(refused.value)
    assert '\n' not in str(refused.value)
    # A value of the wrong type is the node's own refusal, not this one.
    for wrong in ('false', 1):
        with pytest.raises(StartupError) as refused:
            SimHarness(outputs_process=wrong)
        assert 'must be true or false' in str(refused.value), str(refused.value)


def test_the_outputs_process_records_the_same_file_byte_for_byte(ros, tmp_path):
    """Every default output, noisy, recorded in the simulator's process and in the child."""
    files = []
    for relayed in (False, True):
        path = tmp_path / f'run_{relayed}.mcap'
        sim = make_sim(ros, outputs_process=relayed, record=str(path), **NOISY)
        assert (sim.sink is None) == relayed  # the child holds it
        status = json.loads(sim.status())
        assert (status['recording'], status['live_view']) == (str(path), None)
        sim.simulation.robot.command(0.4, 0.8)
        sim.advance(120)
        sim.reset_simulation(time=True)  # the time goes back: the log times count on
        sim.simulation.robot.command(0.4, -0.8)
        sim.advance(120)
        sim.destroy_node()
        files.append(path.read_bytes())
    topics = read_recording(str(tmp_path / 'run_True.mcap'))
    assert {'/odom', '/scan', '/imu', '/tf', '/tf_static', '/clock'} <= set(topics)
    odom_times = [record.log_time_ns for record in topics['/odom']]
    assert len(odom_times) == 241 and odom_times == sorted(odom_times)
    assert odom_times[120] == 120 * 10**9 // 240 and odom_times[-1] == 2 * odom_times[120]
    assert files[0] == files[1]


def test_a_live_view_in_the_outputs_process_builds_what_a_viewer_takes(ros):
    """The child's server: its clock; nothing built until a viewer subscribes, then each step."""
    import socket
    import time
    from r2d2_sim.testing import LiveViewClient
    from test_outputs_on_demand import CountingPublisher
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        port = sock.getsockname()[1]
    sim = make_sim(ros, outputs_process=True, foxglove_port=port, cmd_vel_timeout=0.0)
    assert json.loads(sim.status())['live_view'] == f'ws://127.0.0.1:{port}'
    assert json.loads(sim.status())['recording'] is None
    odom = sim.robots[0].outputs.state[2]
    assert odom._publisher.topic_name == '/odom'
    counter = CountingPublisher(odom)
    sim.simulation.robot.command(0.3, 0.0)
    sim.advance(24)
    assert counter.calls == 0
    with LiveViewClient(port) as viewer:
        viewer.wait_for_channels(['/odom'])
        # The viewer's clock runs though nothing is built (the server sends it at most 30
        # times a second: a step after a pause is sent), and goes back with a reset.
        time.sleep(0.05)
        sim.advance(1)
        assert viewer.pump(lambda: viewer.times and viewer.times[-1] == 25 * 10**9 // 240)
        sim.reset_simulation(time=True)
        assert viewer.pump(lambda: viewer.times[-1] == 0)
        sim.advance(24)
        viewer.subscribe(['/odom'])
        index = odom._publisher.index
        assert viewer.pump(lambda: sim.relay.sink_taken[index] == 1)
        sim.advance(24)
        assert counter.calls == 24
        heard = viewer.wait_for_messages('/odom', 24)
        assert heard[-1].log_time_ns == round(48 / 240 * 1e9)
        viewer.unsubscribe(['/odom'])
        assert viewer.pump(lambda: sim.relay.sink_taken[index] == 0)
        sim.advance(24)
        assert counter.calls == 24
    sim.destroy_node()


def test_a_sink_the_outputs_process_cannot_open_is_one_line(ros, tmp_path):
    """A recording that exists is refused by the child; the node says the sink's line."""
    taken = tmp_path / 'taken.mcap'
    taken.write_bytes(b'mine')
    with pytest.raises(StartupError) as refused:
        make_sim(ros, outputs_process=True, record=str(taken))
    assert str(refused.value) == f'{taken} exists: choose another file name'
    assert taken.read_bytes() == b'mine'


def test_every_qos_field_reaches_the_outputs_process():
    """The child's publisher offers the QoS asked for, deadlines and liveliness included."""
    from rclpy.duration import Duration
    from rclpy.qos import LivelinessPolicy, QoSProfile, ReliabilityPolicy
    from r2d2_sim.ros.relay import qos_from_dict, qos_to_dict
    qos = QoSProfile(depth=7, reliability=ReliabilityPolicy.BEST_EFFORT,
                     deadline=Duration(seconds=1, nanoseconds=5), lifespan=Duration(seconds=2),
                     liveliness=LivelinessPolicy.MANUAL_BY_TOPIC,
                     liveliness_lease_duration=Duration(seconds=3),
                     avoid_ros_namespace_conventions=True)
    rebuilt = qos_from_dict(json.loads(json.dumps(qos_to_dict(qos))))
    assert rebuilt == qos and rebuilt != QoSProfile(depth=7)


# The child's disk made slow: each write of the recording of more than 4 KiB waits.
SLOW_DISK = '''
import os
import time
from r2d2_sim.recording import mcap_file
_write = mcap_file.McapOutput.write


def write(self, data):
    if len(memoryview(data)) > 4096:
        time.sleep(float(os.environ['R2D2_SIM_TEST_SLOW_WRITE_S']))
    return _write(self, data)


mcap_file.McapOutput.write = write
'''
BLOBS = 20


def blob(index):
    """Return 100 kB that do not compress (the file's chunks are written as they fill)."""
    return random.Random(index).randbytes(100_000)


def recording_relay(ros, monkeypatch, tmp_path, write_s):
    """Return (relay, path): a relay recording, its child's disk ``write_s`` slow a write."""
    from std_msgs.msg import UInt8MultiArray
    from rclpy.qos import QoSProfile
    from r2d2_sim.ros.relay import OutputRelay
    (tmp_path / 'slow').mkdir()
    (tmp_path / 'slow' / 'sitecustomize.py').write_text(SLOW_DISK)
    monkeypatch.setenv('PYTHONPATH', os.pathsep.join(
        p for p in (str(tmp_path / 'slow'), os.environ.get('PYTHONPATH')) if p))
    monkeypatch.setenv('R2D2_SIM_TEST_SLOW_WRITE_S', str(write_s))
    path, now = tmp_path / 'run.mcap', [0]
    relay = OutputRelay(ros.domain_id, 'slow_disk_outputs', '/', print,
                        sink={'port': None, 'record_path': str(path)}, time_ns=lambda: now[0])
    publisher = relay.create_publisher(UInt8MultiArray, '/blob', QoSProfile(depth=1))
    for index in range(BLOBS):
        now[0] = index * 1000
        publisher.publish(UInt8MultiArray(data=blob(index)))
    assert relay.wait()  # published: the recording is still queued for the disk
    return relay, path


def test_closing_waits_while_a_slow_disk_takes_the_recording(ros, monkeypatch, tmp_path):
    """The child's file still grows after the close's timeout: it is waited for, not killed."""
    relay, path = recording_relay(ros, monkeypatch, tmp_path, write_s=0.02)
    assert relay.close(timeout_s=0.3) == 0
    recorded = read_recording(path)['/blob']
    assert [bytes(each.message.data) for each in recorded] == [blob(i) for i in range(BLOBS)]
    assert [each.log_time_ns for each in recorded] == [i * 1000 for i in range(BLOBS)]


def test_a_recording_child_told_to_stop_still_finishes_its_file(ros, monkeypatch, tmp_path):
    """SIGTERM drops what the disk has not taken; the file ends, readable, after the rest."""
    relay, path = recording_relay(ros, monkeypatch, tmp_path, write_s=0.05)
    process = relay.process
    process.send_signal(signal.SIGTERM)
    # A deadline, not a speed: the child ends its participant and its file, which took over
    # 10 s once on a loaded 2-core CI machine (ci130; 4 s here, 11 s beside another test).
    assert process.wait(30.0) == 128 + signal.SIGTERM
    with open(path, 'rb') as recorded:  # the summary and the footer were written
        recorded.seek(-8, os.SEEK_END)
        assert recorded.read() == b'\x89MCAP0\r\n'
    # A prefix, maybe empty: the signal can come before the slow disk took the first blob.
    kept = [bytes(each.message.data) for each in read_recording(path).get('/blob', ())]
    assert kept == [blob(i) for i in range(len(kept))] and len(kept) < BLOBS
    relay.close()


def test_a_ctrl_c_while_the_child_opens_its_sink_leaves_no_child(ros, monkeypatch, tmp_path):
    """Interrupted before the child's start report: the relay closes its child, then raises."""
    from r2d2_sim.ros.relay import OutputRelay
    started = []

    def interrupted(relay):
        started.append(relay.process)
        raise KeyboardInterrupt
    monkeypatch.setattr(OutputRelay, '_await_report', interrupted)
    with pytest.raises(KeyboardInterrupt):
        OutputRelay(ros.domain_id, 'interrupted_outputs', '/', print,
                    sink={'port': None, 'record_path': str(tmp_path / 'run.mcap')},
                    time_ns=lambda: 0)
    assert started[0].poll() is not None  # ended and reaped


# The child's pipe made slow: it reads a frame's payload 64 KiB at a time, each after a pause.
SLOW_PIPE = '''
import os
import time
_read = os.read


def read(fd, size):
    if size > 4096:
        time.sleep(float(os.environ['R2D2_SIM_TEST_SLOW_READ_S']))
        size = min(size, 65536)
    return _read(fd, size)


os.read = read
'''


def test_a_child_behind_but_taking_is_waited_for_past_the_deadline(ros, monkeypatch, tmp_path):
    """A frame of 3.5 pipes, taken 64 KiB every 50 ms: each write that moved on waits anew."""
    from std_msgs.msg import UInt8MultiArray
    from rclpy.qos import QoSProfile
    from r2d2_sim.ros import relay as relay_module
    (tmp_path / 'slow').mkdir()
    (tmp_path / 'slow' / 'sitecustomize.py').write_text(SLOW_PIPE)
    monkeypatch.setenv('PYTHONPATH', os.pathsep.join(
        p for p in (str(tmp_path / 'slow'), os.environ.get('PYTHONPATH')) if p))
    monkeypatch.setenv('R2D2_SIM_TEST_SLOW_READ_S', '0.05')
    errors = []
    relay = relay_module.OutputRelay(ros.domain_id, 'slow_pipe_outputs', '/', errors.append)
    try:
        publisher = relay.create_publisher(UInt8MultiArray, '/blob', QoSProfile(depth=1))
        assert relay.wait(30.0)  # started: importing rclpy took the time it takes
        monkeypatch.setattr(relay_module, 'WAIT_S', 1.0)  # the seam: 1 s, not 10
        started = time.monotonic()
        relay.begin()
        for index in range(35):  # 3.5 MB in one frame; the pipe holds 1 MiB
            publisher.publish(UInt8MultiArray(data=blob(index)))
        relay.end()
        # About 2.5 MB after the first pipeful at 1.3 MB/s: longer than the deadline.
        assert time.monotonic() - started > 1.0
        assert errors == [] and relay.wait(30.0)
    finally:
        relay.close()


def test_a_stuck_child_is_ended_with_its_publishers(ros, monkeypatch):
    """Stopped past the deadline: one error line says so, and the child ends, its topics too."""
    from std_msgs.msg import UInt8MultiArray
    from rclpy.qos import QoSProfile
    from r2d2_sim.ros import relay as relay_module
    errors = []
    relay = relay_module.OutputRelay(ros.domain_id, 'stuck_outputs', '/', errors.append)
    process = relay.process
    try:
        publisher = relay.create_publisher(UInt8MultiArray, '/blob', QoSProfile(depth=1))
        node = ros.create_node('looker', use_sim_time=False)
        assert wait_for(lambda: node.count_publishers('/blob') == 1)
        monkeypatch.setattr(relay_module, 'WAIT_S', 0.5)  # the seam: 0.5 s, not 10
        os.kill(process.pid, signal.SIGSTOP)  # a load, a debugger, swap...
        for index in range(100):  # 10 MB at most: the pipe (1 MiB) is full long before
            publisher.publish(UInt8MultiArray(data=blob(index)))
            if relay.broken:
                break
        assert relay.broken
        assert process.wait(30.0) == 128 + signal.SIGTERM  # stopped, it still took SIGTERM
        assert errors == ['the outputs process failed: it took nothing for 0.5 s; ending it '
                          '(its publishers leave the graph): nothing more is published']
        assert wait_for(lambda: node.count_publishers('/blob') == 0)
        assert not relay.running and relay.close() == 128 + signal.SIGTERM
    finally:
        if process.poll() is None:
            os.kill(process.pid, signal.SIGCONT)
        relay.close()
