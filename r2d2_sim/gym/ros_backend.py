"""
The ``ros`` backend: the simulator node in this process, in lockstep, driven over its topics.

The policy's command goes out as a ``Twist`` on each robot's ``cmd_vel``
and its observation comes back on the robot's ``scan`` and
``ground_truth``, as any ROS node of the robot's would see them: a node of
yours (a safety filter, a controller, a scan filter) can sit between the
policy and the robot by taking other topics (``topics={'command':
'policy/cmd_vel'}``) and answering on the robot's. The simulator is a
:class:`~r2d2_sim.testing.SimHarness` on a ROS domain leased for it alone
(so parallel environments never hear each other); ``ros_nodes(harness)``
adds your nodes to it, and every control period then runs in lockstep
with them: the command is handled (through your nodes) before the physics
steps, and every callback the period's messages trigger runs before the
next one. So a run repeats bit for bit, and equals the ``inproc`` backend's.

An episode begins as in the ``inproc`` backend, on the node's core under
its lock (its saved state back, the world placed, the first reading cast
at once): the first observation of an episode comes from the core, every
step's over the topics.
"""

from contextlib import ExitStack
import struct
from typing import Any, Callable, List, Mapping, NamedTuple, Optional, Sequence, Tuple

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import numpy
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription
from sensor_msgs.msg import LaserScan

from r2d2_sim.client import wait_for
from r2d2_sim.ros.cdr import serialize
from r2d2_sim.gym.arena import Arena, Episode
from r2d2_sim.gym.settings import GymError, NavSettings
from r2d2_sim.gym.task import Command, Outcome, Reading
from r2d2_sim.ros.quiet_node import NO_TYPE_DESCRIPTION_SERVICE, QuietNode
from r2d2_sim.sim.simulation import Simulation
from r2d2_sim.testing import SimHarness
from r2d2_sim.testing.lockstep import TakenOnDemand

__all__ = ['RosBackend', 'Topics', 'NODE_NAME', 'read_scan', 'read_odometry', 'twist_bytes']

NODE_NAME = '_r2d2_gym'
# The latest message is all a step reads.
LATEST = QoSProfile(depth=1)


class Topics(NamedTuple):
    """The topics the policy uses, relative to each robot's namespace (or absolute)."""

    command: str = 'cmd_vel'        # geometry_msgs/Twist out
    scan: str = 'scan'              # sensor_msgs/LaserScan in
    state: str = 'ground_truth'     # nav_msgs/Odometry in: the true pose, the twist in the body


def _topic(namespace: str, name: str) -> str:
    return name if name.startswith('/') else f'{namespace.rstrip("/")}/{name}'


def _unused(msg: Any) -> None:
    """Stand in as the readers' callback, never called: no executor runs their group."""


# A step reads two messages and sends one: read and written as CDR bytes where the
# numbers lie (a LaserScan of 360 beams took 0.1-0.2 ms to deserialize into Python).
# CDR: a 4-byte encapsulation header, then each field aligned to its size from there.
_HEADER = 4


def _after_string(raw: bytes, offset: int) -> int:
    """Return the offset just past the CDR string at ``offset`` (its uint32 length first)."""
    offset = _aligned(offset, 4)
    (length,) = struct.unpack_from('<I', raw, _HEADER + offset)
    return offset + 4 + length


def _aligned(offset: int, size: int) -> int:
    return offset + (-offset % size)


def _stamp(raw: bytes) -> int:
    sec, nanosec = struct.unpack_from('<iI', raw, _HEADER)
    return sec * 1_000_000_000 + nanosec


def read_scan(raw: bytes) -> Tuple[int, numpy.ndarray]:
    """Return a serialized LaserScan's stamp (ns) and its ranges (float32), as sent."""
    offset = _aligned(_after_string(raw, 8), 4) + 7 * 4  # header, then the 7 floats before
    (count,) = struct.unpack_from('<I', raw, _HEADER + offset)
    ranges = numpy.frombuffer(raw, dtype='<f4', count=count, offset=_HEADER + offset + 4)
    return _stamp(raw), ranges.astype(numpy.float32)


def read_odometry(raw: bytes) -> Tuple[int, Tuple[float, ...]]:
    """Return a serialized Odometry's stamp (ns) and pose (7) then twist (6), as sent."""
    offset = _aligned(_after_string(raw, _after_string(raw, 8)), 8)  # frame ids, then doubles
    pose = struct.unpack_from('<7d', raw, _HEADER + offset)
    twist = struct.unpack_from('<6d', raw, _HEADER + offset + (7 + 36) * 8)
    return _stamp(raw), pose + twist


def twist_bytes(linear: float, angular: float) -> bytes:
    """Return a Twist of ``linear`` x and ``angular`` z, serialized."""
    message = Twist()
    message.linear.x = linear
    message.angular.z = angular
    return serialize(message)


_TWIST_LINEAR_X = _HEADER       # the first of Twist's six doubles
_TWIST_ANGULAR_Z = _HEADER + 5 * 8


class _RobotLink:
    """One robot's three topics on the environment's node: its command out, two readers in."""

    def __init__(self, node: QuietNode, namespace: str, topics: Topics) -> None:
        group = TakenOnDemand()
        self.command_topic = _topic(namespace, topics.command)
        self.publisher = node.create_publisher(Twist, self.command_topic, 10)
        self.scan = node.create_subscription(LaserScan, _topic(namespace, topics.scan), _unused,
                                             LATEST, raw=True, callback_group=group)
        self.state = node.create_subscription(Odometry, _topic(namespace, topics.state),
                                              _unused, LATEST, raw=True, callback_group=group)
        self._twist = bytearray(twist_bytes(0.0, 0.0))

    def linked(self) -> bool:
        """Return True once someone takes the command and someone gives both readings."""
        return (self.publisher.get_subscription_count() > 0
                and self.scan.get_publisher_count() > 0 and self.state.get_publisher_count() > 0)

    def send(self, linear: float, angular: float) -> None:
        """Publish the command."""
        twist = self._twist
        struct.pack_into('<d', twist, _TWIST_LINEAR_X, linear)
        struct.pack_into('<d', twist, _TWIST_ANGULAR_Z, angular)
        self.publisher.publish(bytes(twist))

    @staticmethod
    def latest(subscription: Subscription) -> Optional[bytes]:
        """Take everything that arrived; return the last one (bytes), None if nothing did."""
        last = None
        with subscription.handle:
            while True:
                taken = subscription.handle.take_message(subscription.msg_type, True)
                if taken is None:
                    return last
                last = taken[0]

    def read(self, stamp: int) -> Reading:
        """Return the reading of the period stamped ``stamp``; GymError if it did not arrive."""
        scan_raw, state_raw = self.latest(self.scan), self.latest(self.state)
        scan_stamp, ranges = read_scan(scan_raw) if scan_raw is not None else (None, None)
        state_stamp, v = read_odometry(state_raw) if state_raw is not None else (None, ())
        for name, sent in ((self.scan.topic_name, scan_stamp),
                           (self.state.topic_name, state_stamp)):
            if sent != stamp:
                raise GymError(f'{name} of t={stamp / 1e9:.6f} s did not arrive within the step '
                               '(a node between the robot and the policy must answer in it)')
        assert ranges is not None
        return Reading(ranges, (v[0], v[1], v[2]), (v[3], v[4], v[5], v[6]), (v[7], v[8], v[9]),
                       (v[10], v[11], v[12]))


def _topics(topics: Any) -> Topics:
    """Return the policy's topics; GymError (one line) for anything but names of each."""
    if topics is None:
        return Topics()
    if not isinstance(topics, Mapping):
        raise GymError(f'topics must be a dict of {", ".join(Topics._fields)}, got '
                       f'{type(topics).__name__}')
    unknown = sorted(set(map(str, topics)) - set(Topics._fields))
    if unknown:
        raise GymError(f'topics takes {", ".join(Topics._fields)}, got {", ".join(unknown)}')
    from rclpy.validate_topic_name import validate_topic_name
    for key, name in topics.items():
        if not isinstance(name, str):
            raise GymError(f'topics: {key} must be a topic name, got {type(name).__name__}')
        try:
            validate_topic_name(name)
        except Exception as exc:  # rclpy's InvalidTopicNameException, over several lines
            raise GymError(f'topics: {key} {name!r} is not a topic name: '
                           f'{" ".join(str(exc).split())[:160]}') from None
    return Topics(**dict(topics))


class RosBackend:
    """
    The simulator node in a :class:`~r2d2_sim.testing.SimHarness`, in lockstep, over its topics.

    ``ros_nodes(harness)``, if given, adds your nodes (``harness.add_node``,
    ``harness.create_node``); ``topics`` renames the policy's topics
    (:class:`Topics`' fields). ``domain_id`` leases that domain (default:
    any free one). GymError (one line) when nothing takes the command or
    gives the readings within the harness's timeout.
    """

    def __init__(self, settings: NavSettings, *, ros_nodes: Optional[Callable[[Any], Any]] = None,
                 topics: Optional[Mapping[str, str]] = None,
                 domain_id: Optional[int] = None) -> None:
        self._driving: Optional[ExitStack] = None
        self._closed = False
        self.topics = _topics(topics)
        self.harness = SimHarness(domain_id=domain_id, **settings.sim_parameters_for())
        self.arena: Optional[Arena] = None
        self.node: Optional[QuietNode] = None
        try:
            node = self.harness.sim
            simulation = node.simulation if node is not None else None
            if node is None or simulation is None:
                raise GymError('the simulator node did not start')
            self.simulation: Simulation = simulation
            self.lock = node.lock
            with self.lock:
                self.arena = Arena(simulation, settings.pool, settings.box_size,
                                   settings.tip_angle_rad)
            self.node = QuietNode(NODE_NAME, context=self.harness.context,
                                  start_parameter_services=False, enable_rosout=False,
                                  parameter_overrides=[NO_TYPE_DESCRIPTION_SERVICE])
            self.links = [_RobotLink(self.node, self.harness.robot(name).namespace, self.topics)
                          for name in self.harness.robot_names]
            if ros_nodes is not None:
                ros_nodes(self.harness)
            self._wait_linked()
            # This thread drives the executor from now on: no handover twice a step.
            self._driving = ExitStack()
            self._driving.enter_context(self.harness.driving())
        except BaseException:
            self.close()
            raise

    def _wait_linked(self) -> None:
        """Wait (by deadline) until every robot's command is taken and its readings given."""
        if not wait_for(lambda: all(link.linked() for link in self.links),
                        self.harness.timeout_s, interval_s=0.001):
            waiting = [link.command_topic for link in self.links if not link.linked()]
            raise GymError(f'the policy\'s topics did not link within '
                           f'{self.harness.timeout_s:g} s: nothing took '
                           f'{", ".join(waiting)} or gave its readings (topics, ros_nodes)')

    def core(self) -> Any:
        """Return the node's lock: hold it to touch the core directly."""
        return self.lock

    def start(self, episode: Episode) -> List[Reading]:
        """Begin an episode on the node's core (see :meth:`Arena.start`); the first reading."""
        return self._arena().start(episode)

    def _arena(self) -> Arena:
        if self.arena is None:
            raise GymError('the environment is closed: make a new one')
        return self.arena

    def act(self, commands: Sequence[Command]) -> List[Reading]:
        """
        Publish each robot's command, let every node handle it, run one control period, read.

        Each reading is the one stamped with the period's end, as it came
        over the robot's topics (through any node of yours in between).
        """
        harness = self.harness
        for link, (linear, angular) in zip(self.links, commands):
            link.send(linear, angular)
        harness.settle()
        harness.advance()
        stamp = harness.last_publication_ns()
        return [link.read(stamp) for link in self.links]

    def outcomes(self) -> List[Outcome]:
        """Return what each robot's watch saw this episode (see :meth:`Arena.outcomes`)."""
        with self.lock:
            return self._arena().outcomes()

    def close(self) -> None:
        """Close the arena, the environment's node and the harness; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        try:
            if self._driving is not None:
                self._driving.close()
            if self.arena is not None:
                with self.lock:
                    self.arena.close()
            if self.node is not None:
                self.node.destroy_node()
        finally:
            self.harness.close()
