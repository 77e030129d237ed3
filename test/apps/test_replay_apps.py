"""
The ``replay`` command's QoS, read back from a recording's metadata, in this process.

The command itself, publishing to another process, is system/test_replay.py's.
"""

import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from r2d2_sim.apps.replay import DEFAULT_DEPTH, qos_from_metadata
from r2d2_sim.recording.message_definitions import offered_qos_profiles


@pytest.mark.parametrize('qos', [
    QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL),
    QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT),
    QoSProfile(history=HistoryPolicy.KEEP_ALL),
])
def test_recorded_qos_comes_back(qos):
    """The QoS written by the sink is the one replay publishes with."""
    back = qos_from_metadata(offered_qos_profiles(qos))
    assert (back.history, back.reliability, back.durability) == \
        (qos.history, qos.reliability, qos.durability)
    if qos.history == HistoryPolicy.KEEP_LAST:
        assert back.depth == qos.depth


def test_qos_as_rosbag2_records_it_from_the_graph():
    """rosbag2's history 'unknown', depth 0 and infinite durations: keep-last 10, defaults."""
    text = '\n'.join([
        '- history: unknown', '  depth: 0', '  reliability: reliable',
        '  durability: transient_local', '  deadline:', '    sec: 9223372036',
        '    nsec: 854775807', '  lifespan:', '    sec: 9223372036', '    nsec: 854775807',
        '  liveliness: automatic', '  liveliness_lease_duration:', '    sec: 9223372036',
        '    nsec: 854775807', '  avoid_ros_namespace_conventions: false'])
    qos = qos_from_metadata(text)
    assert qos.history == HistoryPolicy.KEEP_LAST and qos.depth == DEFAULT_DEPTH
    assert qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert qos.deadline.nanoseconds == 0
    assert qos_from_metadata(None).durability == DurabilityPolicy.VOLATILE


def test_qos_as_rosbag2_before_jazzy_numbers_it():
    """Humble and Iron write rmw's enum numbers: /tf_static stays latched, a scan best effort."""
    humble = '\n'.join([
        '- history: 3', '  depth: 0', '  reliability: 1', '  durability: 1', '  deadline:',
        '    sec: 9223372036', '    nsec: 854775807', '  lifespan:', '    sec: 9223372036',
        '    nsec: 854775807', '  liveliness: 1', '  liveliness_lease_duration:',
        '    sec: 9223372036', '    nsec: 854775807', '  avoid_ros_namespace_conventions: false'])
    latched = qos_from_metadata(humble)
    assert (latched.reliability, latched.durability) == (ReliabilityPolicy.RELIABLE,
                                                         DurabilityPolicy.TRANSIENT_LOCAL)
    assert latched.history == HistoryPolicy.KEEP_LAST and latched.depth == DEFAULT_DEPTH
    scan = qos_from_metadata(humble.replace('reliability: 1', 'reliability: 2')
                             .replace('durability: 1', 'durability: 2')
                             .replace('history: 3', 'history: 2'))
    assert (scan.reliability, scan.durability, scan.history) == (
        ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE, HistoryPolicy.KEEP_ALL)
    unknown = qos_from_metadata(humble.replace('reliability: 1', 'reliability: 0')
                                .replace('durability: 1', 'durability: 99'))
    assert (unknown.reliability, unknown.durability) == (ReliabilityPolicy.RELIABLE,
                                                         DurabilityPolicy.VOLATILE)
