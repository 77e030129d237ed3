"""
The node's recording: sim_node records in its own process; the file read back and replayed.

Read back by two independent readers (``mcap``'s and rosbags'), then replayed
into a subscriber in another process. The live view in process, and the
outputs both check (``OUTPUTS``, in helpers.py), are ros/test_live_view.py's.
"""

import subprocess
import sys

from helpers import LATCHED, OUTPUTS, SENSORS, stamp_of
from mcap.reader import make_reader
import pytest
from rclpy.serialization import deserialize_message
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability

from r2d2_sim.apps.replay import message_class
from r2d2_sim.testing import lease_domain, ros_child_env, SimProcess, stop_process
from topic_listener import read_listener, start_listener


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
    # In the recording's order (--loop may wrap around between what was heard first and
    # last, as it did once under load): the robot drove forward.
    odometry.sort(key=lambda m: (m.header.stamp.sec, m.header.stamp.nanosec))
    assert odometry[-1].pose.pose.position.x > odometry[0].pose.pose.position.x
    assert heard['/robot_description']
