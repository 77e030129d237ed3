"""
One robot of the simulator, seen from a test: send it commands, read its state.

A simulator can hold several robots, each in its own namespace. Both
harnesses give a handle per robot (``harness.robot('robot_a')``):
:class:`LocalRobot` for :class:`~r2d2_sim.testing.harness.SimHarness` (the
simulator in this process) and :class:`RemoteRobot` for
:class:`~r2d2_sim.testing.sim_process.SimProcess`. The harnesses' own
``send_cmd_vel``, ``ground_truth``, ``odom`` and ``joint_states`` are those
of their first robot (the one robot, by default).
"""

from typing import Any, Callable, Dict, List, Mapping, Optional, Protocol, Tuple, TYPE_CHECKING

from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription
from sensor_msgs.msg import JointState

from r2d2_sim.client import command_twist, stamp_ns, twist_message, twist_stamped_message
from r2d2_sim.sim.settings.given import checked_parameters
from r2d2_sim.sim.settings.robots import robot_namespaces
from r2d2_sim.sim.settings.table import ConfigError
from r2d2_sim.testing.executor import HarnessError
from r2d2_sim.testing.lockstep import TakenOnDemand
from r2d2_sim.testing.process import ChildProcess
from r2d2_sim.testing.remote import ask_until, RemoteProbe
from r2d2_sim.testing.tf import TfListener, TransformLookup

if TYPE_CHECKING:  # the simulator's side needs PyBullet, which a remote test never loads
    from r2d2_sim.ros.node import SimNode
    from r2d2_sim.ros.robot_interfaces import RobotInterfaces

__all__ = ['LocalRobot', 'RemoteRobot', 'LocalHost', 'RemoteHost', 'STATE_TYPES',
           'flatten_robots', 'simulator_parameters', 'expected_namespaces']

STATE_TYPES = {'joint_states': JointState, 'odom': Odometry, 'ground_truth': Odometry}
TWIST_STAMPED_TYPE = 'geometry_msgs/msg/TwistStamped'


class LocalHost(Protocol):
    """
    What a :class:`LocalRobot` uses of its :class:`~r2d2_sim.testing.harness.SimHarness`.

    The harness makes its handles and hands each itself; a handle calls back
    only through this, so this module never imports the harnesses' modules.
    """

    sim: 'SimNode'

    def check_open(self) -> None:
        """Raise HarnessError (one line) once the harness is closed."""

    def _wait(self, condition: Callable[[], Any], what: str) -> Any:
        """Wait for ``condition`` while the harness's callbacks run; HarnessError with ``what``."""

    def _tf_wait(self, condition: Callable[[], bool]) -> bool:
        """Wait for ``condition`` as a transform lookup does; False at the timeout."""

    def _tf_frozen(self) -> bool:
        """Return True when no transform can arrive until the harness steps."""

    def last_publication_ns(self) -> int:
        """Return the simulated time (ns) of the simulator's latest state publication."""


class RemoteHost(Protocol):
    """
    What a :class:`RemoteRobot` uses of its :class:`~r2d2_sim.testing.sim_process.SimProcess`.

    The process makes its handles and hands each itself, as a harness does
    (:class:`LocalHost`).
    """

    probe: RemoteProbe
    process: ChildProcess
    timeout_s: float

    def status(self) -> Dict[str, Any]:
        """Return the simulator's state (its ``~/get_status`` reply)."""

    def check_open(self) -> None:
        """Raise HarnessError (one line) once the process was stopped."""

    def _wait_latest(self, key: str, latest: Dict[str, Any], what: str) -> Any:
        """Return the state message ``key`` of the latest publication (paused) or the newest."""

    def _tf_topics(self) -> Tuple[str, str]:
        """Return the process's two TF topics, resolved."""

    def listen_tf(self) -> TfListener:
        """Return the process's TF listener (listening since the start)."""

    def wait_heard(self) -> None:
        """Wait until the simulator's writers match every reader of the process's node."""


def simulator_parameters(parameters: Mapping[str, Any],
                         refused: Callable[[str], Exception]) -> Dict[str, Any]:
    """
    Return a harness's keywords as the simulator's parameters; raise ``refused`` for a typo.

    ``robots`` given as a dict spelled out (:func:`flatten_robots`), a None
    value left out (the node's default). A name the simulator does not read
    raises ``refused(line)`` (the node's own words, with its did-you-mean):
    ROS ignores undeclared overrides and the node only warns, but a
    harness's keyword nothing reads is a mistake, said before anything starts.
    """
    robots = parameters.get('robots')
    if isinstance(robots, Mapping):
        for name, own in robots.items():
            if own is not None and not isinstance(own, Mapping):
                raise refused(f'robots: robot {name!r} takes a dict of its parameters '
                              f'(or None), got {type(own).__name__} {own!r:.40}')
    return checked_parameters(
        {k: v for k, v in flatten_robots(parameters).items() if v is not None}, refused)


def flatten_robots(parameters: Mapping[str, Any]) -> Dict[str, Any]:
    """
    Return the simulator's parameters with ``robots`` given as a dict spelled out.

    ``robots={'a': {}, 'b': {'initial_pose': [2.0, 0.0, 3.14]}}`` becomes
    ``robots=['a', 'b']`` and ``'b.initial_pose': [2.0, 0.0, 3.14]``, as a
    parameter file would give them; a list of names stays as it is.
    """
    flat = dict(parameters)
    robots = flat.get('robots')
    if isinstance(robots, Mapping):
        flat['robots'] = list(robots)
        for name, own in robots.items():
            for key, value in (own or {}).items():
                flat[f'{name}.{key}'] = value
    return flat


def expected_namespaces(parameters: Mapping[str, Any], namespace: str) -> List[str]:
    """Return the namespaces of the robots the parameters ask for (default: ``namespace``)."""
    base = '/' + namespace.strip('/') if namespace.strip('/') else '/'
    try:
        listed = robot_namespaces(parameters, base)
    except (AttributeError, TypeError, ConfigError):  # the simulator will say what, in one line
        listed = {}
    return list(listed.values()) or [base]


def _unused(msg: Any) -> None:
    """Stand in as the readers' callback, never called: no executor runs their group."""


def _topic(namespace: str, name: str) -> str:
    return f'{namespace.rstrip("/")}/{name}'


class FirstRobot:
    """
    A harness's own verbs, its first robot's: ``robot()``'s, for a test of one robot.

    In-process, the readers take the latest state publication; across
    processes, paused, the one of the node's latest publication (see
    :class:`LocalRobot` and :class:`RemoteRobot`).
    """

    def robot(self, name: Optional[str] = None) -> '_RobotHandle':
        raise NotImplementedError

    def send_cmd_vel(self, linear: float = 0.0, angular: float = 0.0, *,
                     twist: Optional[Any] = None) -> None:
        """
        Publish a command on the first robot's ``cmd_vel``; return once the simulator has it.

        ``linear`` m/s along x and ``angular`` rad/s about z, or a whole
        ``twist``. A simulator with ``enable_stamped_cmd_vel`` gets a
        TwistStamped. Raises HarnessError if the command does not arrive in
        time. ``robot(name).send_cmd_vel`` commands another robot.
        """
        self.robot().send_cmd_vel(linear, angular, twist=twist)

    def ground_truth(self) -> Odometry:
        """Return the first robot's latest ``ground_truth`` (world pose, twist in the body)."""
        return self.robot().ground_truth()

    def odom(self) -> Odometry:
        """Return the first robot's latest ``odom``; HarnessError for a robot without wheels."""
        return self.robot().odom()

    def joint_states(self) -> JointState:
        """Return the first robot's latest ``joint_states`` (every movable joint)."""
        return self.robot().joint_states()


class _RobotHandle(TransformLookup):
    """
    What both handles share: the robot's name and namespace, three state readers, TF.

    ``lookup_transform`` listens on the robot's own TF topics: ``/tf`` and
    ``/tf_static`` (``tf_layout`` shared, frames prefixed ``NAME/``), or its
    namespace's ``tf`` and ``tf_static`` (namespaced, frames unprefixed).
    """

    name: Optional[str] = None
    namespace: str = '/'
    tf_topics: Tuple[str, str] = ('/tf', '/tf_static')

    def _tf_topics(self) -> Tuple[str, str]:
        return self.tf_topics

    def send_cmd_vel(self, linear: float = 0.0, angular: float = 0.0, *,
                     twist: Optional[Any] = None) -> None:
        """Publish a command (``linear`` m/s, ``angular`` rad/s, or a whole ``twist``)."""
        raise NotImplementedError

    def ground_truth(self) -> Odometry:
        """Return the robot's latest ``ground_truth`` (world pose, twist in the body frame)."""
        return self._wait_latest('ground_truth')

    def odom(self) -> Odometry:
        """Return the robot's latest ``odom`` (wheel odometry)."""
        return self._wait_latest('odom')

    def joint_states(self) -> JointState:
        """Return the robot's latest ``joint_states`` (every movable joint)."""
        return self._wait_latest('joint_states')

    def _wait_latest(self, topic: str) -> Any:
        raise NotImplementedError

    def __repr__(self) -> str:
        return f'{type(self).__name__}({self.name!r}, namespace={self.namespace!r})'


class LocalRobot(_RobotHandle):
    """
    One robot of a :class:`~r2d2_sim.testing.harness.SimHarness`, through the harness's nodes.

    Its state topics are subscribed on ``link`` when the handle is made
    (before the simulator publishes, for the robots the parameters list), in
    a callback group no executor runs: the latest message is taken when asked
    for (depth 1 keeps it), as raw bytes deserialized only then, and a
    lockstep period spends nothing on them. :meth:`attach` binds the handle
    to the simulator's robot once that exists.
    """

    def __init__(self, harness: LocalHost, link: Node, namespace: str) -> None:
        self.namespace = namespace
        self._harness = harness
        self._link = link
        self._interfaces: Optional[RobotInterfaces] = None  # attach() binds it
        self._cmd_vel: Optional[Publisher] = None  # from attach() to close()
        self._stamped = False
        self._latest: Dict[str, Optional[bytes]] = dict.fromkeys(STATE_TYPES)
        on_demand = TakenOnDemand()
        self._subscriptions = [
            link.create_subscription(msg_type, _topic(namespace, topic), _unused, 1,
                                     raw=True, callback_group=on_demand)
            for topic, msg_type in STATE_TYPES.items()]

    def _take(self, topic: str) -> Optional[bytes]:
        """Take what arrived on ``topic`` since the last time; return the latest (bytes)."""
        subscription = self._subscriptions[list(STATE_TYPES).index(topic)]
        with subscription.handle:
            while True:
                taken = subscription.handle.take_message(subscription.msg_type, True)
                if taken is None:
                    return self._latest[topic]
                self._latest[topic] = taken[0]

    def attach(self, interfaces: 'RobotInterfaces') -> 'LocalRobot':
        """Bind to the simulator's robot ``interfaces``: its name, and cmd_vel of its type."""
        self._interfaces = interfaces
        self.name = interfaces.name
        self.tf_topics = interfaces.tf_topics
        # The type the simulator takes: one participant cannot hold a Twist
        # publisher and a TwistStamped subscription on one topic ("invalid
        # allocator"), and the middleware would not deliver it anyway.
        self._stamped = interfaces.robot.config.enable_stamped_cmd_vel
        cmd_vel = self._cmd_vel = self._link.create_publisher(
            TwistStamped if self._stamped else Twist, _topic(self.namespace, 'cmd_vel'), 10)
        state = [s for topic, s in zip(STATE_TYPES, self._subscriptions)
                 if topic != 'odom' or self.has_wheels]
        self._harness._wait(lambda: cmd_vel.get_subscription_count() > 0 and all(
            s.get_publisher_count() > 0 for s in state),
            f'the robot {self.name} did not link its topics')
        return self

    def _bound(self) -> 'RobotInterfaces':
        """Return the simulator's robot this handle is bound to; HarnessError before attach."""
        self._harness.check_open()
        if self._interfaces is None:
            raise HarnessError(f'{self!r} is not bound to a robot of the simulator yet')
        return self._interfaces

    @property
    def has_wheels(self) -> bool:
        """Return True when cmd_vel drives the robot's wheels."""
        return self._bound().robot.controller is not None

    @property
    def commands_received(self) -> int:
        """Return the number of cmd_vel messages the robot took, refused ones included."""
        return self._bound().cmd_vel.received

    def send_cmd_vel(self, linear: float = 0.0, angular: float = 0.0, *,
                     twist: Optional[Twist] = None) -> None:
        """
        Publish a command on the robot's ``cmd_vel``; return once the simulator has taken it.

        ``linear`` m/s along x and ``angular`` rad/s about z, or a whole
        ``twist``. A robot with ``enable_stamped_cmd_vel`` gets a
        TwistStamped stamped with the simulated time now. Raises HarnessError
        if the command does not arrive in time, or the robot left the world, and
        ValueError (one line, naming the field, nothing sent) for NaN or inf.
        """
        self._harness.check_open()
        publisher = self._cmd_vel
        if publisher is None:  # closed: the robot was deleted, or a reset left it out
            raise HarnessError(f'the robot {self.name} is not in the world any more')
        twist = command_twist(linear, angular, twist)
        if self._stamped and not isinstance(twist, TwistStamped):
            twist = twist_stamped_message(twist=twist,
                                          stamp_ns=self._harness.sim.sim_time_ns)
        before = self.commands_received
        publisher.publish(twist)
        self._harness._wait(lambda: self.commands_received > before,
                            f'the robot {self.name} did not take cmd_vel')

    def odom(self) -> Odometry:
        """Return the robot's latest ``odom``; HarnessError for a robot without wheels."""
        if not self.has_wheels:
            raise HarnessError(f'the robot {self.name} has no wheels, so the simulator '
                               'publishes no odom')
        return self._wait_latest('odom')

    def _wait_latest(self, topic: str) -> Any:
        """Wait until the message of the latest publication has been delivered; return it."""
        harness = self._harness
        harness.check_open()
        if not harness.sim.world_is_loaded:  # nothing publishes: said now, not in 10 s
            raise HarnessError('no world is loaded (unload_world): load_world first')
        if self._interfaces is None or not harness.sim.simulation.robots.count(
                self._interfaces.robot):
            raise HarnessError(f'the robot {self.name} is not in the world any more')
        wanted = harness.last_publication_ns()
        found: List[Any] = []

        def arrived() -> bool:
            raw = self._take(topic)
            if raw is None:
                return False
            msg = deserialize_message(raw, STATE_TYPES[topic])
            found[:] = [msg]
            return stamp_ns(msg.header.stamp) == wanted
        harness._wait(arrived, f'{_topic(self.namespace, topic)} of t={wanted / 1e9:.6f} s '
                               'did not arrive')
        return found[0]

    def _tf_node(self) -> Node:
        self._harness.check_open()
        return self._link

    def _tf_default_time_ns(self) -> int:
        return self._harness.last_publication_ns()  # the current state, never one on its way

    def _tf_sent_before(self) -> Tuple[bytes, ...]:
        tf = self._interfaces.outputs.tf if self._interfaces is not None else None
        return (tf.latest,) if tf is not None and tf.latest else ()

    def _tf_wait(self, condition: Callable[[], bool]) -> bool:
        return self._harness._tf_wait(condition)

    def _tf_frozen(self) -> bool:
        return self._harness._tf_frozen()

    def bound_to(self, interfaces: Optional['RobotInterfaces']) -> bool:
        """Return True if this handle is of the robot ``interfaces`` (the very same robot)."""
        return interfaces is not None and interfaces is self._interfaces

    def forget(self) -> None:
        """Drop what was received: the state readers wait for the next publication."""
        for topic in self._latest:
            self._take(topic)
            self._latest[topic] = None

    def close(self) -> None:
        """Stop listening (the robot left the world)."""
        for subscription in self._subscriptions:
            self._link.destroy_subscription(subscription)
        self._subscriptions = []
        self._stop_tf()
        if self._cmd_vel is not None:
            self._link.destroy_publisher(self._cmd_vel)
            self._cmd_vel = None


class RemoteRobot(_RobotHandle):
    """
    One robot of a :class:`~r2d2_sim.testing.sim_process.SimProcess`, through its probe's node.

    The state readers follow the process's rules (paused: the message of the
    last reply's time). :meth:`linked` says when its topics are matched;
    :meth:`attach` then makes the ``cmd_vel`` publisher of the type the node takes.
    """

    def __init__(self, process: RemoteHost, namespace: str, name: Optional[str] = None,
                 facts: Optional[Mapping[str, Any]] = None, *, subscribe: bool = True) -> None:
        self.namespace = namespace
        self.name = name
        if name is not None and facts is not None:
            self.bind(name, facts)
        self._process = process
        node = process.probe.node
        self._node = node
        self._cmd_vel: Optional[Publisher] = None  # from attach() to close()
        self._stamped = False
        self._latest: Dict[str, Any] = dict.fromkeys(STATE_TYPES)
        # subscribe=False: no state subscriptions (a benchmark must not add a subscriber).
        self._subscriptions: Dict[str, Subscription] = {
            topic: node.create_subscription(msg_type, _topic(namespace, topic),
                                            self._keeper(topic), 1)
            for topic, msg_type in STATE_TYPES.items()} if subscribe else {}

    def _keeper(self, topic: str) -> Callable[[Any], None]:
        def keep(msg: Any) -> None:
            self._latest[topic] = msg
        return keep

    def bind(self, name: str, facts: Mapping[str, Any]) -> 'RemoteRobot':
        """Take the node's name for the robot and its facts from ``~/get_status`` (TF topic)."""
        self.name = name
        self.tf_topics = (facts['tf'], facts['tf'] + '_static')
        return self

    def connect(self) -> 'RemoteRobot':
        """
        Wait (by deadline) until linked, make the ``cmd_vel`` publisher, wait for its match.

        Then until the simulator's writers match this handle's readers (TF's
        too): a step taken at once is then heard.
        """
        process = self._process
        if not process.probe.spin_until(lambda: self.linked() or process.process.exited(),
                                        process.timeout_s):
            self.close()
            raise HarnessError(f'the robot {self.name} did not link its topics within '
                               f'{process.timeout_s:g} s')
        self.attach()
        if not process.probe.spin_until(self.cmd_vel_linked, process.timeout_s):
            self.close()
            raise HarnessError(f'the robot {self.name} did not subscribe cmd_vel within '
                               f'{process.timeout_s:g} s')
        if self._subscriptions:  # not for a benchmark's handle, which adds no subscriber
            self._listen_tf_from_now()
        try:
            process.wait_heard()
        except BaseException:
            self.close()  # its readers must not stay on the probe's node
            raise
        return self

    def cmd_vel_type(self) -> Optional[str]:
        """Return the type the node subscribes the robot's ``cmd_vel`` with, once seen."""
        node = self._node
        for info in node.get_subscriptions_info_by_topic(_topic(self.namespace, 'cmd_vel')):
            if info.node_name != node.get_name():
                return info.topic_type
        return None

    def linked(self) -> bool:
        """Return True once the robot's state topics and ``cmd_vel`` are matched here."""
        # odom is left out: a robot without wheels has none.
        return (self.cmd_vel_type() is not None
                and all(self._subscriptions[t].get_publisher_count() > 0
                        for t in ('joint_states', 'ground_truth') if t in self._subscriptions))

    def attach(self) -> 'RemoteRobot':
        """Make the ``cmd_vel`` publisher of the type the node takes (Twist or TwistStamped)."""
        # Twist or TwistStamped (enable_stamped_cmd_vel, maybe from a params
        # file): publish what the node takes, which the middleware delivers.
        self._stamped = self.cmd_vel_type() == TWIST_STAMPED_TYPE
        msg_type = type(twist_stamped_message() if self._stamped else twist_message())
        self._cmd_vel = self._node.create_publisher(
            msg_type, _topic(self.namespace, 'cmd_vel'), 10)
        return self

    def cmd_vel_linked(self) -> bool:
        """Return True once the node's ``cmd_vel`` subscription matches the publisher."""
        return self._cmd_vel is not None and self._cmd_vel.get_subscription_count() > 0

    def commands_received(self) -> int:
        """Ask the node how many cmd_vel messages the robot took (``~/get_status``)."""
        robots = self._process.status().get('robots', {})
        if self.name not in robots:
            raise HarnessError(f'the robot {self.name} is not in the world any more')
        return robots[self.name]['commands_received']

    def send_cmd_vel(self, linear: float = 0.0, angular: float = 0.0, *,
                     twist: Optional[Any] = None) -> None:
        """
        Publish a command on the robot's ``cmd_vel``; return once the simulator has counted it.

        ``linear`` m/s along x and ``angular`` rad/s about z, or a whole
        ``twist``. A node with ``enable_stamped_cmd_vel`` gets a TwistStamped
        stamped 0 ("now"). Confirmed through the node's ``~/get_status``.
        ValueError (one line, naming the field, nothing sent) for NaN or inf.
        """
        publisher = self._cmd_vel
        if publisher is None:  # closed: the robot left the world
            raise HarnessError(f'the robot {self.name} is not in the world any more')
        twist = command_twist(linear, angular, twist)
        if self._stamped and not hasattr(twist, 'header'):
            twist = twist_stamped_message(twist=twist)
        before = self.commands_received()
        publisher.publish(twist)
        process = self._process
        if not ask_until(lambda: self.commands_received() > before, process.probe.spin_until,
                         process.timeout_s):
            raise HarnessError(f'the robot {self.name} did not take cmd_vel within '
                               f'{process.timeout_s:g} s')

    def _wait_latest(self, topic: str) -> Any:
        return self._process._wait_latest(topic, self._latest,
                                          _topic(self.namespace, topic))

    def listen_tf(self) -> TfListener:
        """
        Start taking the robot's TF (once); return the listener.

        On the simulator's own TF topics (``tf_layout`` shared) it is the
        process's listener, which has listened since the start: a listener per
        robot would add two readers a robot to every ``/tf`` writer of the
        simulator, and each spawn and delete would make and unmake them.
        """
        process = self._process
        process.check_open()
        if self.tf_topics == tuple(map(self._node.resolve_topic_name, process._tf_topics())):
            return process.listen_tf()
        return super().listen_tf()

    def _tf_node(self) -> Node:
        self._process.check_open()
        return self._node

    def _tf_wait(self, condition: Callable[[], bool]) -> bool:
        return self._process.probe.spin_until(condition, self._process.timeout_s)

    def forget(self) -> None:
        """Drop what was received: the state readers wait for newer messages."""
        for topic in self._latest:
            self._latest[topic] = None

    def close(self) -> None:
        """Stop listening (the robot left the world)."""
        for subscription in self._subscriptions.values():
            self._node.destroy_subscription(subscription)
        self._subscriptions = {}
        self._stop_tf()
        if self._cmd_vel is not None:
            self._node.destroy_publisher(self._cmd_vel)
            self._cmd_vel = None
