"""
``sim_node`` with ``outputs_process``: the same messages across processes, paced or stepped.

At real time the loop never waits for the outputs process; a ``~/step``
answers once its messages are out; stopping the simulator ends the child too.
"""

import os
from pathlib import Path
import signal
import subprocess
import time

from helpers import next_domain_id, ros_env
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock

from r2d2_sim.testing import SimProcess
from r2d2_sim.testing.process import sim_node_command


def relay_children(parent_pid):
    """Return the pids of outputs processes whose parent is ``parent_pid``."""
    found = []
    for stat in Path('/proc').glob('[0-9]*/stat'):
        try:
            fields = stat.read_text().rsplit(')', 1)[1].split()
            cmdline = (stat.parent / 'cmdline').read_bytes()
        except OSError:
            continue
        if int(fields[1]) == parent_pid and b'r2d2_sim.ros.relay_child' in cmdline:
            found.append(int(stat.parent.name))
    return found


def test_paced_and_stepped_sim_node_publish_through_the_outputs_process():
    sim = SimProcess(outputs_process=True, scan_rate=0.0)
    node = sim.probe.node
    clocks, odoms = [], []
    subscriptions = [node.create_subscription(Clock, '/clock', clocks.append, 1000),
                     node.create_subscription(Odometry, 'odom', odoms.append, 1000)]
    pid, children = sim.process.process.pid, []
    try:
        assert sim.probe.spin_until(
            lambda: all(s.get_publisher_count() > 0 for s in subscriptions), 10.0)
        # ~/get_readers counts the outputs process's writers, and wait_heard waits for them.
        sim.wait_heard()
        readers = sim.readers()
        assert readers['/odom'] >= 1 and readers['/clock'] >= 1, readers
        children = relay_children(pid)
        assert len(children) == 1
        # Paced at real time: the clock runs and odom follows, a message a step.
        assert sim.probe.spin_until(lambda: len(odoms) >= 48, 10.0)
        stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in odoms[-24:]]
        assert all(b - a in (10**9 // 240, 10**9 // 240 + 1) for a, b in zip(stamps, stamps[1:]))
        sim.pause()
        heard = len(odoms)
        reply = sim.step()  # answered once the step's messages are out
        assert reply['steps'] >= 1
        assert sim.probe.spin_until(lambda: len(odoms) >= heard + reply['steps']
                                    and clocks[-1].clock == odoms[-1].header.stamp, 10.0)
    finally:
        code, out, err = sim.stop()
    assert code == 0, err
    assert not any(Path(f'/proc/{child}').exists() for child in children)  # ended with it


def test_robots_spawned_after_a_delete_reuse_the_freed_publishers_rightly():
    """Spawn, delete, spawn again through the standard: the new robot's topics are its own."""
    with SimProcess(outputs_process=True, cmd_vel_timeout=0.0, scan_rate=0.0,
                    start_paused=True) as sim:
        sim.spawn('package://r2d2_sim/urdf/r2d2.urdf', name='c', namespace='c',
                  position=(0.0, 2.0, 0.48))
        sim.step_physics(24)
        sim.delete_entity('c')
        sim.step_physics(24)
        name = sim.spawn('package://r2d2_sim/urdf/r2d2.urdf', name='d', namespace='d',
                         position=(0.0, -2.0, 0.48))
        d = sim.robot(name)
        d.send_cmd_vel(linear=0.3)
        sim.step_physics(240)
        truth = d.ground_truth()
        assert truth.header.frame_id == 'world' and truth.child_frame_id == 'd/base_link'
        assert truth.pose.pose.position.x > 0.2 and truth.pose.pose.position.y < -1.9
        assert d.odom().header.frame_id == 'd/odom'
        assert abs(sim.ground_truth().pose.pose.position.x) < 0.01  # r2d2 stood still


def test_a_ctrl_c_at_start_up_reaches_the_simulator_alone():
    """A session of its own: the terminal's SIGINT goes to sim_node only, which ends the child."""
    process = subprocess.Popen(sim_node_command(ros_args=['-p', 'outputs_process:=true']),
                               env=ros_env(next_domain_id()), stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 30.0
    while not relay_children(process.pid) and time.monotonic() < deadline:
        time.sleep(0.005)
    children = relay_children(process.pid)
    assert children, 'no outputs process appeared'
    os.killpg(process.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole foreground group
    out, err = process.communicate(timeout=30)
    assert process.returncode == 0, err
    assert 'Traceback' not in err + out and 'KeyboardInterrupt' not in err + out, err
    assert 'outputs process failed' not in err + out, err
    assert not any(Path(f'/proc/{child}').exists() for child in children)


def test_a_killed_simulator_leaves_a_finished_recording():
    """The child holds the recording: SIGKILL of sim_node closes its pipe, the file is ended."""
    from r2d2_sim.testing import read_recording
    import tempfile
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / 'run.mcap'
        sim = SimProcess(outputs_process=True, scan_rate=0.0, record=str(path),
                         start_paused=True, cmd_vel_timeout=0.0)
        pid = sim.process.process.pid
        try:
            children = relay_children(pid)
            assert len(children) == 1
            sim.step_physics(48)  # answered once the child has logged them
            os.kill(pid, signal.SIGKILL)
            deadline = time.monotonic() + 20.0
            while Path(f'/proc/{children[0]}').exists() and time.monotonic() < deadline:
                time.sleep(0.01)
            assert not Path(f'/proc/{children[0]}').exists()
        finally:
            sim.stop()
        odom = read_recording(str(path), topics=['/odom'])['/odom']
        assert [r.log_time_ns for r in odom] == [step * 10**9 // 240 for step in range(49)]
