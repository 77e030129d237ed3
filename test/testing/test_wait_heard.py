"""
SimProcess waits until the simulator's writers match its readers, not only the reverse.

A DDS writer learns of a new reader on its own, a moment after the reader
learned of the writer; what it publishes in between never reaches the reader
(a first step's ``/tf`` was lost so, once in a CI run). ``wait_heard`` polls
``~/get_readers`` until each topic counts every reader the graph shows that
the simulator's writers can match. The simulator's side and the graph are
stood in for here, so each answer is chosen: the real reply is
test/ros/test_control.py's.
"""

from types import SimpleNamespace

import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from r2d2_sim.testing import HarnessError, SimProcess
from r2d2_sim.testing.robots import RemoteRobot
from r2d2_sim.testing.sim_process import matchable_readers

ODOM = 'nav_msgs/msg/Odometry'
RELIABLE = QoSProfile(depth=10)
BEST_EFFORT = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def endpoint(node_name, qos=RELIABLE, topic_type=ODOM):
    """Return what rclpy's graph queries say of one publisher or subscription."""
    return SimpleNamespace(node_name=node_name, topic_type=topic_type, qos_profile=qos)


class Graph:
    """A probe node's view of the graph: its own subscriptions, each topic's endpoints."""

    def __init__(self, topics, writers=None, readers=None):
        self.subscriptions = [SimpleNamespace(topic_name=t) for t in topics]
        self.writers = writers or {}
        self.readers = readers or {}

    def get_publishers_info_by_topic(self, topic):
        return self.writers.get(topic, [])

    def get_subscriptions_info_by_topic(self, topic):
        return self.readers.get(topic, [])


def test_only_readers_every_simulator_writer_can_match_count():
    """Type and QoS must fit each of its writers; another node's writer does not count."""
    graph = Graph(['/odom'], writers={'/odom': [endpoint('r2d2_sim'), endpoint('other')]},
                  readers={'/odom': [endpoint('probe'), endpoint('user', BEST_EFFORT),
                                     endpoint('user', LATCHED),
                                     endpoint('user', topic_type='std_msgs/msg/String')]})
    assert matchable_readers(graph, '/odom', 'r2d2_sim') == 2
    # No writer of the simulator seen yet: the node's own subscriptions.
    assert matchable_readers(graph, '/odom', 'r2d2_other') == 1


def waiting_process(answers, graph, timeout_s=5.0):
    """Return a SimProcess whose readers() replies ``answers`` in turn (the last for good)."""
    process = SimProcess.__new__(SimProcess)
    asked = []

    def readers():
        asked.append(1)
        return answers[min(len(asked), len(answers)) - 1]
    process.probe = SimpleNamespace(node=graph, spin_until=lambda condition, timeout_s: False)
    process.readers = readers
    process.timeout_s = timeout_s
    process.node_path = '/r2d2_sim'
    return process, asked


def two_tf_readers():
    """Return a graph where the probe has two /tf readers and one /odom reader."""
    return Graph(['/tf', '/tf', '/odom', '/c/odom'],
                 writers={'/tf': [endpoint('r2d2_sim', topic_type='tf2_msgs/msg/TFMessage')],
                          '/odom': [endpoint('r2d2_sim')]},
                 readers={'/tf': [endpoint('probe', topic_type='tf2_msgs/msg/TFMessage')] * 2,
                          '/odom': [endpoint('probe')]})


def test_it_asks_until_every_writer_counts_the_readers():
    """Two readers on /tf: one matched is not enough; topics it does not publish do not count."""
    process, asked = waiting_process([{'/tf': 0, '/odom': 1}, {'/tf': 1, '/odom': 1},
                                      {'/tf': 2, '/odom': 0}, {'/tf': 2, '/odom': 1}],
                                     two_tf_readers())
    process.wait_heard()
    assert len(asked) == 4


def test_it_says_which_topics_were_never_matched():
    """A writer that never matches: HarnessError naming the topic, after the deadline."""
    process, asked = waiting_process([{'/tf': 2, '/odom': 0}], two_tf_readers(), timeout_s=0.05)
    with pytest.raises(HarnessError, match=r'readers of /odom within 0.05 s'):
        process.wait_heard()
    assert len(asked) > 1


class ProbeNode(Graph):
    """A probe node that hands out cmd_vel publishers a simulator subscribes at once."""

    def __init__(self):
        super().__init__([], readers={'/c/cmd_vel': [
            endpoint('r2d2_sim', topic_type='geometry_msgs/msg/Twist')]})
        self.destroyed = []

    def get_name(self):
        return '_probe'

    def create_publisher(self, msg_type, topic, qos):
        return SimpleNamespace(topic_name=topic, get_subscription_count=lambda: 1)

    def destroy_publisher(self, publisher):
        self.destroyed.append(publisher.topic_name)


@pytest.mark.parametrize('heard', [True, False])
def test_a_robot_handle_waits_to_be_heard_and_leaves_nothing_when_it_is_not(heard):
    """connect() ends with the wait; when the wait fails, the handle's cmd_vel goes."""
    node = ProbeNode()
    waits = []

    def wait_heard():
        waits.append(1)
        if not heard:
            raise HarnessError('the simulator did not match the readers of /c/odom')
    process = SimpleNamespace(
        probe=SimpleNamespace(node=node, spin_until=lambda condition, timeout_s: condition()),
        process=SimpleNamespace(exited=lambda: False), timeout_s=1.0, wait_heard=wait_heard)
    robot = RemoteRobot(process, '/c', 'c', subscribe=False)
    if heard:
        assert robot.connect() is robot and node.destroyed == []
    else:
        with pytest.raises(HarnessError, match='/c/odom'):
            robot.connect()
        assert node.destroyed == ['/c/cmd_vel']
    assert waits == [1]
