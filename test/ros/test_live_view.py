"""
The node's live view and recording: its own outputs, byte for byte, to a viewer and a file.

A real WebSocket client (the Foxglove protocol, ``foxglove.sdk.v1``) against
the node's server, in this process. The recording of sim_node in a process of
its own, read back by two independent readers and replayed into another
process, is system/test_live_view_system.py's; the outputs both check
(``OUTPUTS``) are in helpers.py.
"""

import socket

from helpers import LATCHED, OUTPUTS, SENSORS, stamp_of
import pytest
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message

from foxglove_viewer import Viewer
from r2d2_sim.apps.replay import message_class
from r2d2_sim.testing import SimHarness, StartupError


def free_port():
    """Return a TCP port nothing listens on now (the node binds it a moment later)."""
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


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
