"""
The node's live view and recording: its own outputs, byte for byte, to a viewer and a file.

A real WebSocket client (the Foxglove protocol, ``foxglove.sdk.v1``) against
the node's server; the node's recording read back by two independent readers
(``mcap``'s and rosbags'), then replayed into a subscriber in another process.
"""

import socket
import subprocess
import sys

from mcap.reader import make_reader
import pytest
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability

from foxglove_viewer import Viewer
from r2d2_sim.client import stamp_ns
from r2d2_sim.apps.replay import message_class
from r2d2_sim.testing import (
    lease_domain, ros_child_env, SimHarness, SimProcess, StartupError, stop_process)
from topic_listener import read_listener, start_listener

SENSORS = {'scan_rate': 10.0, 'imu_rate': 60.0, 'camera_rate': 10.0, 'camera_width': 32,
           'camera_height': 24}
# Every output the node has with these parameters, and its type.
OUTPUTS = {
    '/clock': 'rosgraph_msgs/msg/Clock', '/joint_states': 'sensor_msgs/msg/JointState',
    '/odom': 'nav_msgs/msg/Odometry', '/ground_truth': 'nav_msgs/msg/Odometry',
    '/tf': 'tf2_msgs/msg/TFMessage', '/tf_static': 'tf2_msgs/msg/TFMessage',
    '/scan': 'sensor_msgs/msg/LaserScan', '/imu': 'sensor_msgs/msg/Imu',
    '/robot_description': 'std_msgs/msg/String',
    '/camera/image_raw': 'sensor_msgs/msg/Image',
    '/camera/camera_info': 'sensor_msgs/msg/CameraInfo',
}
LATCHED = ('/robot_description', '/tf_static')


def free_port():
    """Return a TCP port nothing listens on now (the node binds it a moment later)."""
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def stamp_of(msg):
    """Return the stamp (ns) of a message with a header, a Clock's time, a TFMessage's first."""
    if hasattr(msg, 'clock'):
        return stamp_ns(msg.clock)
    if hasattr(msg, 'transforms'):
        return stamp_ns(msg.transforms[0].header.stamp)
    return stamp_ns(msg.header.stamp)


class Heard:
    """A DDS subscriber of every stamped output, in the harness, keeping messages by stamp."""

    def __init__(self, harness):
        self.by_topic = {topic: {} for topic in OUTPUTS if topic not in LATCHED}
        node = harness.create_node('dds_subscriber', use_sim_time=False)
        for topic in self.by_topic:
            node.create_subscription(message_class(OUTPUTS[topic]), topic,
                                     self._keeper(topic), QoSProfile(depth=1000))

    def _keeper(self, topic):
        def keep(msg):
            self.by_topic[topic][stamp_of(msg)] = msg
        return keep


def test_every_output_reaches_a_viewer_as_the_dds_subscriber_gets_it():
    """Advertised with its ROS type (cdr, ros2msg); payloads equal DDS messages, stamp by stamp."""
    port = free_port()
    with SimHarness(foxglove_port=port, cmd_vel_timeout=0.0, **SENSORS) as harness:
        heard = Heard(harness)
        with Viewer(port) as viewer:
            assert viewer.pump(lambda: set(OUTPUTS) <= set(viewer.channels)), viewer.channels
            for topic, type_name in OUTPUTS.items():
                channel = viewer.channels[topic]
                assert (channel['encoding'], channel['schemaEncoding']) == ('cdr', 'ros2msg')
                assert channel['schemaName'] == type_name
            viewer.subscribe(OUTPUTS)
            assert viewer.pump(lambda: all(viewer.messages[t] for t in LATCHED))
            harness.send_cmd_vel(linear=0.3, angular=0.2)
            harness.advance(seconds=0.5)  # lockstep: every DDS message handled meanwhile
            assert viewer.pump(lambda: len(viewer.messages['/clock']) >= 100)
            last_ns = harness.last_publication_ns()
            assert viewer.pump(lambda: any(t == last_ns for t, _ in viewer.messages['/odom']))
            times = list(viewer.times)
        for topic, stamped in heard.by_topic.items():
            seen = viewer.messages[topic]
            assert seen, f'no {topic} in the live view'
            for log_time, payload in seen:
                msg = deserialize_message(payload, message_class(OUTPUTS[topic]))
                assert stamp_of(msg) == log_time  # the viewer's time is simulated time
                if log_time in stamped:
                    assert msg == stamped[log_time], topic
            assert sum(t in stamped for t, _ in seen) >= len(seen) // 2, topic
    assert times and all(t == round(t * 240 / 1e9) * 10**9 // 240 for t in times)  # steps
    assert max(times) <= last_ns


def test_a_late_viewer_gets_the_latched_topics():
    """robot_description and /tf_static, published once at start-up, reach a later viewer."""
    port = free_port()
    with SimHarness(foxglove_port=port) as harness:
        harness.advance(seconds=0.2)
        with Viewer(port) as viewer:
            assert viewer.pump(lambda: set(LATCHED) <= set(viewer.channels))
            viewer.subscribe(LATCHED)
            assert viewer.pump(lambda: all(viewer.messages[t] for t in LATCHED))
            description = deserialize_message(viewer.messages['/robot_description'][0][1],
                                              message_class('std_msgs/msg/String'))
            assert description.data == harness.sim.simulation.robot.description
            static = deserialize_message(viewer.messages['/tf_static'][0][1],
                                         message_class(OUTPUTS['/tf_static']))
            assert {t.child_frame_id for t in static.transforms} >= {'base_link', 'base_scan'}


def test_a_mirrored_publisher_refuses_a_wrong_type_as_rclpy_does(tmp_path):
    """A message of another type is a TypeError, sent neither to DDS nor to the recording."""
    from nav_msgs.msg import Odometry
    from std_msgs.msg import String
    with SimHarness(record=str(tmp_path / 'run.mcap')) as harness:
        odom = harness.sim.create_publisher(Odometry, 'mirrored_odom', 10)
        assert type(odom).__name__ == 'MirroredPublisher'
        with pytest.raises(TypeError, match='Odometry'):
            odom.publish(String(data='not an odometry'))
        odom.publish(Odometry())  # the right type goes out


def test_a_taken_port_or_an_existing_recording_is_one_startup_error(tmp_path):
    """The node refuses what the sink cannot do, in one line, and leaves nothing behind."""
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        with pytest.raises(StartupError, match='cannot serve on'):
            SimHarness(foxglove_port=taken.getsockname()[1])
    existing = tmp_path / 'run.mcap'
    existing.write_bytes(b'old')
    with pytest.raises(StartupError, match='exists'):
        SimHarness(record=str(existing))
    assert existing.read_bytes() == b'old'


@pytest.fixture(scope='module')
def recording(tmp_path_factory):
    """Record a second of driving with sim_node in its own process, stopped by SIGINT."""
    path = tmp_path_factory.mktemp('record') / 'run.mcap'
    sim = SimProcess(record=str(path), start_paused=True, cmd_vel_timeout=0.0, **SENSORS)
    try:
        sim.send_cmd_vel(linear=0.3)
        sim.step(240)
    finally:
        result = sim.stop()
    assert result.returncode == 0, result.stderr
    return path


def test_the_recording_reads_back_with_two_readers(recording):
    """Two readers (mcap, rosbags) agree on topics, types, counts; QoS kept; all decodes."""
    with open(recording, 'rb') as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None, 'no summary: the file was not closed'
        assert reader.get_header().profile == 'ros2'
        mcap_counts = {summary.channels[i].topic: n
                       for i, n in summary.statistics.channel_message_counts.items()}
        schemas = {c.topic: summary.schemas[c.schema_id].name
                   for c in summary.channels.values()}
    assert schemas == OUTPUTS
    # t = 0 (published at start-up) and 240 steps; sensors at their rates.
    assert (mcap_counts['/clock'], mcap_counts['/scan'], mcap_counts['/imu']) == (241, 10, 60)
    assert mcap_counts['/robot_description'] == mcap_counts['/tf_static'] == 1
    with AnyReader([recording]) as reader:
        connections = {c.topic: c for c in reader.connections}
        assert {t: c.msgtype for t, c in connections.items()} == OUTPUTS
        assert {t: c.msgcount for t, c in connections.items()} == mcap_counts
        for topic in OUTPUTS:
            durability = connections[topic].ext.offered_qos_profiles[0].durability
            assert (durability == QosDurability.TRANSIENT_LOCAL) == (topic in LATCHED), topic
        decoded = 0
        for connection, time_ns, data in reader.messages():
            msg = deserialize_message(data, message_class(connection.msgtype))
            if connection.topic != '/robot_description':
                assert stamp_of(msg) == time_ns, connection.topic  # logged at simulated time
            decoded += 1
    assert decoded == sum(mcap_counts.values())


def test_the_recording_replays_to_another_process(recording, tmp_path):
    """The replay tool publishes the recorded bytes; another process hears them, latched too."""
    with lease_domain() as lease:
        topics = {'/odom': {'type': OUTPUTS['/odom'], 'distinct': 20},
                  '/robot_description': {'type': 'std_msgs/msg/String', 'distinct': 1,
                                         'durability': 'transient_local'}}
        listener = start_listener(lease.domain_id, topics, tmp_path / 'heard.json')
        replay = subprocess.Popen([sys.executable, '-m', 'r2d2_sim.apps.replay', str(recording),
                                   '--rate', '4', '--loop'], env=ros_child_env(lease.domain_id),
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            heard = read_listener(listener, tmp_path / 'heard.json', 60.0)
        finally:
            stop_process(replay)
    odometry = [deserialize_message(data, message_class(OUTPUTS['/odom']))
                for _, data in heard['/odom']]
    assert odometry[-1].pose.pose.position.x > odometry[0].pose.pose.position.x
    assert heard['/robot_description']
