"""
Testing code against the simulator: harnesses, deadline waits, ROS domains, processes.

:class:`SimHarness` runs the simulator inside the test's process, in an rclpy
context of its own, and moves simulated time only when told (``advance``).
:class:`SimProcess` runs the ``sim_node`` executable in a process of its own
and drives it through its services. Each gets a ROS domain that no other
harness on this machine uses (:func:`lease_domain`), so tests can run in
parallel (``pytest -n auto``). The pytest fixtures built on these are in
:mod:`r2d2_sim.pytest_plugin`; this module needs no pytest.

Also used by the ``demo`` and ``drive`` executables and the benchmarks
(:class:`Pose2D`, :func:`pose_from_odometry`, :func:`spin_until`,
:func:`ros_child_env`).
"""

from contextlib import contextmanager
import errno
import fcntl
import itertools
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import threading
import time
from typing import (
    Any, Callable, Dict, Iterator, List, Mapping, NamedTuple, Optional, Sequence)

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import rclpy
from rclpy.context import Context
from rclpy.executors import (
    ConditionReachedException, ExternalShutdownException, ShutdownException,
    SingleThreadedExecutor, TimeoutException)
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_srvs.srv import SetBool, Trigger

from r2d2_sim.kinematics import quaternion_to_yaw

# Domain ids handed out by lease_domain. Fast DDS maps domain d to UDP ports
# from 7400 + 250 * d: up to about 100 they stay below the kernel's ephemeral
# range (32768+), where another program's socket could already hold them.
# Domain 0, the default, is left to the user's own ROS graph.


def _domain_ids_from_env() -> range:
    """Return the ids harnesses may lease: ``R2D2_SIM_DOMAIN_IDS`` ("first-last") or 1-100."""
    text = os.environ.get('R2D2_SIM_DOMAIN_IDS', '1-100')
    try:
        first, last = (int(part) for part in text.split('-'))
    except ValueError:
        raise ValueError(f'R2D2_SIM_DOMAIN_IDS must be "first-last", e.g. "1-100", '
                         f'got {text!r}') from None
    if not 0 <= first <= last <= 232:
        raise ValueError(f'R2D2_SIM_DOMAIN_IDS must lie within 0-232, got {text!r}')
    return range(first, last + 1)


DOMAIN_IDS = _domain_ids_from_env()
# A directory for the per-domain lock files instead of the default below.
DOMAIN_LOCK_DIR_ENV = 'R2D2_SIM_DOMAIN_LOCK_DIR'
# How often a waiting lease_domain tries again (s).
DOMAIN_RETRY_S = 0.05
# The spinning thread looks for a stop request at least this often (s).
SPIN_POLL_S = 0.05
# Name of the node through which a harness talks to the simulator (the
# leading underscore hides it from `ros2 node list`).
LINK_NODE_NAME = '_r2d2_sim_harness'
# SimProcess sends an idempotent query (get_status, get_joint_info) again after
# this long without a reply (wall s); a reply sent before the server had found
# our reply reader is lost. Replies take 0.5-1.5 ms here.
STATUS_RESEND_S = 1.0


class Pose2D(NamedTuple):
    """A planar pose with the time stamp of the message it came from."""

    stamp_s: float
    x_m: float
    y_m: float
    yaw_rad: float


def pose_from_odometry(msg: Odometry) -> Pose2D:
    """Extract the planar pose and stamp of an Odometry message."""
    pose = msg.pose.pose
    q = pose.orientation
    stamp = msg.header.stamp
    return Pose2D(stamp.sec + stamp.nanosec * 1e-9, pose.position.x, pose.position.y,
                  quaternion_to_yaw(q.x, q.y, q.z, q.w))


def spin_until(executor, condition: Callable[[], bool], timeout_s: float,
               abort: Optional[Callable[[], bool]] = None) -> bool:
    """Spin ``executor`` until ``condition()`` holds; False at the deadline or on ``abort()``."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        remaining = deadline - time.monotonic()
        if remaining <= 0.0 or (abort is not None and abort()):
            return False
        executor.spin_once(timeout_sec=min(remaining, 0.05))
    return True


def wait_for(condition: Callable[[], Any], timeout_s: float = 10.0,
             interval_s: float = 0.002) -> Any:
    """
    Poll ``condition`` until it returns a truthy value or ``timeout_s`` (wall clock) passes.

    Returns the last value, so ``assert wait_for(...)`` fails at the deadline.
    For conditions that another thread (an executor) makes true.
    """
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value or time.monotonic() > deadline:
            return value
        time.sleep(interval_s)


def ros_child_env(domain_id: Optional[int] = None) -> dict:
    """
    Return this process's environment for a child ROS process that runs r2d2_sim.

    The child imports the same r2d2_sim as this process, keeps discovery on this
    host unless the caller chose otherwise, joins ``domain_id`` when given, and
    writes its output unbuffered (it is usually read through a pipe or a file).
    """
    env = dict(os.environ)
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    if domain_id is not None:
        env['ROS_DOMAIN_ID'] = str(domain_id)
    env['PYTHONUNBUFFERED'] = '1'
    package_root = Path(__file__).resolve().parent.parent
    on_path = {Path(p).resolve() for p in sys.path if p}
    # Only when this copy is not found anyway: a whole site-packages early on
    # PYTHONPATH could shadow the standard library.
    if package_root not in on_path:
        env['PYTHONPATH'] = os.pathsep.join(
            p for p in (str(package_root), env.get('PYTHONPATH')) if p)
    return env


def stamp_ns(stamp) -> int:
    """Return a ``builtin_interfaces/Time`` (a header stamp, a Clock) in integer nanoseconds."""
    return stamp.sec * 10**9 + stamp.nanosec


# -- ROS domains ------------------------------------------------------------------


class DomainUnavailable(RuntimeError):
    """No ROS domain could be leased before the deadline."""


class DomainLease:
    """
    An exclusive claim on one ROS domain id among the processes of this machine.

    Held as an ``flock`` on a file per domain id, so it ends when released or
    when the process dies, and two leases never share a domain, whether they
    are in one process or in several (pytest-xdist workers).
    """

    def __init__(self, domain_id: int, fd: int) -> None:
        self.domain_id = domain_id
        self._fd: Optional[int] = fd

    @property
    def held(self) -> bool:
        """Return True until released."""
        return self._fd is not None

    def release(self) -> None:
        """Give the domain back (closing the file drops the lock); safe to call twice."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> 'DomainLease':
        return self

    def __exit__(self, *exc_info) -> None:
        self.release()

    def __repr__(self) -> str:
        return f'DomainLease({self.domain_id}, held={self.held})'


# Where the next free-domain search starts in this process: spread by process
# id so xdist workers do not all race for domain 1, then rotated so a domain
# just released is not reused at once.
_search_starts = itertools.count(os.getpid())


def domain_lock_dir() -> Path:
    """Return the directory of the per-domain lock files (shared by every user of the machine)."""
    configured = os.environ.get(DOMAIN_LOCK_DIR_ENV)
    path = Path(configured) if configured else Path(tempfile.gettempdir()) / 'r2d2_sim-domains'
    if not path.is_dir():
        path.mkdir(parents=True, exist_ok=True)
        try:  # sticky and writable for all: another user's tests lock here too
            path.chmod(0o1777)
        except OSError:
            pass
    return path


def _try_lock(directory: Path, domain_id: int) -> Optional[int]:
    """Return an fd holding the lock of ``domain_id``, or None if another holder has it."""
    path = directory / f'domain-{domain_id}.lock'
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except PermissionError:  # another user's file: flock works on a read-only fd
        fd = os.open(path, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        if exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
            return None
        raise
    return fd


def lease_domain(domain_id: Optional[int] = None, timeout_s: float = 60.0) -> DomainLease:
    """
    Lease a ROS domain id that no other lease on this machine holds.

    Without ``domain_id``, any free id of :data:`DOMAIN_IDS`; with one, that id
    (waiting for its current holder). Waits up to ``timeout_s`` for one to come
    free, then raises :class:`DomainUnavailable`. Release the lease when done
    (or use it as a context manager); the harnesses do.
    """
    if domain_id is not None and not 0 <= domain_id <= 232:
        raise ValueError(f'a ROS domain id is 0-232, got {domain_id}')
    directory = domain_lock_dir()
    deadline = time.monotonic() + timeout_s
    while True:
        if domain_id is not None:
            candidates = [domain_id]
        else:
            start = next(_search_starts)
            candidates = [DOMAIN_IDS[(start + i) % len(DOMAIN_IDS)]
                          for i in range(len(DOMAIN_IDS))]
        for candidate in candidates:
            fd = _try_lock(directory, candidate)
            if fd is not None:
                return DomainLease(candidate, fd)
        if time.monotonic() > deadline:
            wanted = f'domain {domain_id}' if domain_id is not None else 'a free domain'
            raise DomainUnavailable(f'could not lease {wanted} within {timeout_s:g} s: other '
                                    f'harnesses hold the locks in {directory}')
        time.sleep(DOMAIN_RETRY_S)


def _env_domain_id() -> Optional[int]:
    value = os.environ.get('ROS_DOMAIN_ID', '').strip()
    if not value:
        return None
    try:
        return int(value)
    except ValueError:
        raise ValueError(f'ROS_DOMAIN_ID must be an integer, got {value!r}') from None


# -- in-process harnesses -----------------------------------------------------------


class HarnessError(RuntimeError):
    """The harness or the simulator did not do what was asked before the deadline."""


class CallbackError(HarnessError):
    """A callback in the harness's executor raised; the original exception is the cause."""


def parameter_overrides(parameters: Mapping[str, Any]) -> List[Parameter]:
    """Turn ``{'name': value}`` into the ``parameter_overrides`` list of an rclpy Node."""
    return [Parameter(name, value=value) for name, value in parameters.items()]


class RosHarness:
    """
    One rclpy context on a leased domain, with an executor spinning in a thread.

    The base of :class:`SimHarness`; on its own, a place to build simulator
    nodes by hand. Nodes added here are destroyed by :meth:`close`, which stops
    the spinning thread before it shuts the executor down: shutting an executor
    down while another thread spins it races in rclpy 7.1 (a callback made
    ready meanwhile fails on a destroyed guard condition). An exception raised
    by a callback is raised again, as :class:`CallbackError`, by the next
    harness call (or by :meth:`close`). ``timeout_s`` bounds every wait (wall
    clock). Use it as a context manager, or call :meth:`close`.

    Attributes: ``context``, ``executor``, ``nodes``, ``domain_id`` and its
    ``lease`` (:class:`DomainLease`, released on close).
    """

    def __init__(self, *, domain_id: Optional[int] = None, timeout_s: float = 10.0) -> None:
        self.timeout_s = timeout_s
        self.lease = lease_domain(domain_id, timeout_s=max(timeout_s, 60.0))
        self.domain_id = self.lease.domain_id
        self.nodes: List[Node] = []
        self._closed = False
        self._error: Optional[BaseException] = None
        self._stop = threading.Event()
        # The caller's thread takes the executor over (the spinning thread
        # parks) to run callbacks to idleness itself: see _own_executor().
        self._state = threading.Condition()
        self._park_requests = 0
        self._parked = False
        self._owned = 0
        # Discovery must stay on this host (a default, set before rclpy.init).
        os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        self.context = Context()
        try:
            rclpy.init(context=self.context, domain_id=self.domain_id)
        except BaseException:
            self.lease.release()
            raise
        self.executor = SingleThreadedExecutor(context=self.context)
        self._thread = threading.Thread(target=self._spin, daemon=True,
                                        name=f'ros-harness-{self.domain_id}')
        self._thread.start()

    # -- nodes ------------------------------------------------------------------

    def create_node(self, name: str, *, use_sim_time: bool = True, **node_kwargs) -> Node:
        """
        Create an rclpy Node in this context, spun by the harness's executor.

        ``use_sim_time`` (on by default) makes the node's clock and timers
        follow the simulator's ``/clock``. Other keywords go to ``Node``.
        """
        overrides = list(node_kwargs.pop('parameter_overrides', None) or [])
        if use_sim_time and not any(p.name == 'use_sim_time' for p in overrides):
            overrides.append(Parameter('use_sim_time', value=True))
        node = Node(name, context=self.context, parameter_overrides=overrides, **node_kwargs)
        return self.add_node(node, use_sim_time=False)

    def add_node(self, node: Node, *, use_sim_time: bool = True) -> Node:
        """
        Spin ``node`` (built with ``context=harness.context``) and destroy it on close.

        ``use_sim_time`` (on by default) switches the node to the simulator's
        clock: its timers then count from the first ``/clock`` it receives.
        """
        if node.context is not self.context:
            raise ValueError(f'node {node.get_name()} belongs to another context: build it '
                             'with context=harness.context')
        if use_sim_time and not node.get_parameter('use_sim_time').value:
            node.set_parameters([Parameter('use_sim_time', value=True)])
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    # -- running callbacks -----------------------------------------------------

    @contextmanager
    def _own_executor(self) -> Iterator[None]:
        """
        Run the executor in the caller's thread for the duration of the block.

        The spinning thread parks; :meth:`settle` then runs callbacks directly,
        with no hand-over between threads for each one. Nests.
        """
        if self._owned:
            self._owned += 1
            try:
                yield
            finally:
                self._owned -= 1
            return
        with self._state:
            self._park_requests += 1
        try:
            self.executor.wake()
            with self._state:
                parked = self._state.wait_for(
                    lambda: self._parked or not self._thread.is_alive(), self.timeout_s)
            if not parked:
                raise HarnessError('the executor thread is stuck in a callback')
            self._owned = 1
            try:
                yield
            finally:
                self._owned = 0
        finally:
            with self._state:
                self._park_requests -= 1
                self._state.notify_all()

    def settle(self, timeout_s: Optional[float] = None) -> None:
        """
        Return once every callback that is ready has run, and those they made ready too.

        Publications within one context are delivered synchronously, so after
        ``settle`` every node here has handled what was published before the
        call, and whatever it published in response. Raises HarnessError at the
        deadline (callbacks that never stop making work).
        """
        with self._own_executor():
            self._run_until_idle(self.timeout_s if timeout_s is None else timeout_s)
        self.raise_callback_error()

    def _run_until_idle(self, timeout_s: float) -> None:
        """Run ready callbacks in this thread (which owns the executor) until a poll finds none."""
        deadline = time.monotonic() + timeout_s
        worked = False
        while True:
            try:
                # A zero timeout polls; every batch ends with TimeoutException,
                # and a batch that yielded nothing means idle.
                handler, _, _ = self.executor.wait_for_ready_callbacks(0.0)
            except TimeoutException:
                if not worked:
                    return
                worked = False
                if time.monotonic() > deadline:
                    raise HarnessError(f'callbacks kept coming for {timeout_s:g} s') from None
                continue
            except (ShutdownException, ExternalShutdownException):
                raise HarnessError('the harness was shut down') from None
            worked = True
            self._run(handler)

    def _run(self, handler) -> None:
        handler()
        error = handler.exception()
        if error is not None:
            with self._state:
                if self._error is None:
                    self._error = error

    def _wait(self, condition: Callable[[], Any], what: str) -> Any:
        """Wait for ``condition`` (by deadline) while callbacks run; HarnessError with ``what``."""
        if self._owned:
            def check():
                self._run_until_idle(self.timeout_s)
                return condition()
        else:
            check = condition
        value = wait_for(check, self.timeout_s, interval_s=0.0005)
        self.raise_callback_error()
        if not value:
            raise HarnessError(f'{what} within {self.timeout_s:g} s')
        return value

    def raise_callback_error(self) -> None:
        """Raise (once) what a callback raised in the executor, if anything did."""
        with self._state:
            error, self._error = self._error, None
        if error is not None:
            raise CallbackError(f'a callback raised {type(error).__name__}: {error}') from error

    def _park_wanted(self) -> bool:
        return self._park_requests > 0

    def _spin(self) -> None:
        """Serve callbacks until stopped, parking while a caller drives."""
        executor = self.executor
        while not self._stop.is_set():
            if self._park_requests:
                with self._state:
                    self._parked = True
                    self._state.notify_all()
                    self._state.wait_for(lambda: not self._park_requests or self._stop.is_set())
                    self._parked = False
                continue
            try:
                handler, _, _ = executor.wait_for_ready_callbacks(
                    SPIN_POLL_S, None, self._park_wanted)
            except (TimeoutException, ConditionReachedException):
                continue
            except (ShutdownException, ExternalShutdownException):
                break
            self._run(handler)
        with self._state:
            self._state.notify_all()

    # -- teardown -----------------------------------------------------------------

    def close(self) -> None:
        """
        Stop spinning, shut the executor down, destroy the nodes, shut the context down.

        In that order (see the class). Releases the domain; safe to call twice.
        Raises CallbackError if a callback raised and no harness call reported it.
        """
        if self._closed:
            return
        self._closed = True
        problems: List[BaseException] = []
        try:
            self._stop.set()
            with self._state:
                self._state.notify_all()
            self.executor.wake()
            self._thread.join(timeout=max(self.timeout_s, 1.0))
            self.executor.shutdown(timeout_sec=1.0)
            for node in reversed(self.nodes):
                try:
                    node.destroy_node()
                except Exception as exc:  # destroy the others, then report it
                    problems.append(exc)
            self.nodes.clear()
            rclpy.try_shutdown(context=self.context)
        finally:
            self.lease.release()
        if problems:
            raise problems[0]
        self.raise_callback_error()

    def __enter__(self) -> 'RosHarness':
        return self

    def __exit__(self, exc_type, exc_value, traceback) -> None:
        try:
            self.close()
        except CallbackError:
            if exc_type is None:  # do not hide the exception already on its way out
                raise


class SimHarness(RosHarness):
    """
    The simulator in this process, advanced only when told, plus nodes of your own.

    ``SimHarness(cmd_vel_timeout=0.0, urdf='r2d2.urdf')``: keywords other than
    the harness's own are the simulator's ROS parameters (``sim_node`` takes
    the same names). ``node_name`` and ``namespace`` place the simulator (its
    services are ``<namespace>/<node_name>/pause`` and so on). Raises
    :class:`r2d2_sim.node.StartupError` when the parameters are unusable.

    Simulated time moves only in :meth:`advance` and :meth:`advance_until`.
    With nodes of your own (:meth:`create_node`, :meth:`add_node`), they go
    one control period at a time and let every callback that a period's
    publications trigger run before the next one (lockstep): a controller
    that answers ``odom`` with ``cmd_vel`` sees every state, its command takes
    effect at the next step, and a run repeats bit for bit.
    """

    def __init__(self, node_name: str = 'r2d2_sim', *, namespace: str = '',
                 domain_id: Optional[int] = None, timeout_s: float = 10.0,
                 **parameters: Any) -> None:
        super().__init__(domain_id=domain_id, timeout_s=timeout_s)
        self.namespace = namespace
        self.sim = None  # the SimNode
        self._link: Optional[Node] = None
        self._cmd_vel = None
        self._lockstep = False
        self._types = {'joint_states': JointState, 'odom': Odometry, 'ground_truth': Odometry}
        self._latest: Dict[str, Optional[bytes]] = dict.fromkeys(self._types)
        try:
            from r2d2_sim.node import SimNode  # PyBullet: only when a simulator is wanted
            # Without parameter services or rosout: fewer entities for the
            # executor to gather on every wait of a lockstep run.
            link = self._link = Node(LINK_NODE_NAME, context=self.context,
                                     namespace=namespace or None,
                                     start_parameter_services=False, enable_rosout=False)
            RosHarness.add_node(self, link, use_sim_time=False)
            # Subscribed before the simulator exists: it publishes its first
            # state from its constructor, and delivery within one context is
            # synchronous once matched. Depth 1: only the latest matters here.
            # Raw bytes, deserialized only when asked for: a lockstep run
            # takes every publication.
            for topic, msg_type in self._types.items():
                link.create_subscription(msg_type, topic, self._keeper(topic), 1, raw=True)
            self._cmd_vel = link.create_publisher(Twist, 'cmd_vel', 10)
            self.sim = SimNode(node_name, context=self.context, namespace=namespace or None,
                               parameter_overrides=parameter_overrides(parameters))
            RosHarness.add_node(self, self.sim, use_sim_time=False)
            if not wait_for(lambda: self._cmd_vel.get_subscription_count() > 0, timeout_s):
                raise HarnessError('the simulator did not subscribe cmd_vel')
        except BaseException:
            self.close()
            raise

    def _keeper(self, topic: str) -> Callable[[Any], None]:
        def keep(msg) -> None:
            self._latest[topic] = msg
        return keep

    def create_node(self, name: str, *, use_sim_time: bool = True, **node_kwargs) -> Node:
        """Create a node of yours (in the simulator's namespace unless given one); see add_node."""
        node_kwargs.setdefault('namespace', self.namespace or None)
        return super().create_node(name, use_sim_time=use_sim_time, **node_kwargs)

    def add_node(self, node: Node, *, use_sim_time: bool = True) -> Node:
        """Spin a node of yours with the simulator; from now on advance in lockstep with it."""
        self._lockstep = True
        return super().add_node(node, use_sim_time=use_sim_time)

    # -- commands -----------------------------------------------------------------

    def send_cmd_vel(self, linear: float = 0.0, angular: float = 0.0, *,
                     twist: Optional[Twist] = None) -> None:
        """
        Publish a Twist on ``cmd_vel`` and return once the simulator has taken it.

        ``linear`` m/s along x and ``angular`` rad/s about z, or a whole
        ``twist``. Raises HarnessError if the command does not arrive in time.
        """
        if twist is None:
            twist = Twist()
            twist.linear.x, twist.angular.z = float(linear), float(angular)
        before = self.sim.commands_received
        self._cmd_vel.publish(twist)
        self._wait(lambda: self.sim.commands_received > before,
                   'the simulator did not take cmd_vel')

    # -- simulated time -----------------------------------------------------------

    @property
    def physics_rate_hz(self) -> float:
        """Return physics steps per simulated second."""
        return self.sim.config.physics_rate_hz

    def advance(self, steps: Optional[int] = None, *, seconds: Optional[float] = None) -> int:
        """
        Step the physics ``steps`` times, or for ``seconds`` of simulated time; return the steps.

        Seconds are rounded to whole physics steps. With neither, one control
        period: up to and including the next state publication (as ``~/step``).
        Pause does not apply here: the harness decides when time moves.
        """
        if steps is not None and seconds is not None:
            raise ValueError('give steps or seconds, not both')
        if seconds is not None:
            steps = self._steps(seconds)
        elif steps is None:
            steps = self.sim.steps_to_next_publish()
        if steps < 0:
            raise ValueError(f'cannot advance by {steps} steps')
        self.raise_callback_error()
        if not self._lockstep:
            self.sim.advance(steps)
            return steps
        with self._own_executor():
            self._run_periods(steps)
        return steps

    def advance_until(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """
        Advance one control period at a time until ``predicate()`` is true.

        ``timeout_s`` is simulated time. Returns True as soon as the predicate
        holds (checked first before any step, then after each publication),
        False when the time is up: write ``assert harness.advance_until(...)``,
        or ``assert not ...`` for something that must not happen.
        """
        limit = self._steps(timeout_s)
        # Driven from this thread: each period's messages are handled before
        # the predicate looks, with no hand-over to the executor thread.
        with self._own_executor():
            return predicate() or self._run_periods(limit, predicate)

    def _run_periods(self, steps: int,
                     predicate: Optional[Callable[[], bool]] = None) -> bool:
        """
        Advance ``steps`` one control period at a time, handling each period's messages.

        Returns True as soon as ``predicate`` holds after a period (False if
        it never did, or without one).
        """
        done = 0
        while done < steps:
            chunk = min(self.sim.steps_to_next_publish(), steps - done)
            self.sim.advance(chunk)
            done += chunk
            self._run_until_idle(self.timeout_s)
            self.raise_callback_error()
            if predicate is not None and predicate():
                return True
        return False

    def _steps(self, seconds: float) -> int:
        if not seconds >= 0.0:
            raise ValueError(f'simulated time must be >= 0 s, got {seconds}')
        return round(seconds * self.physics_rate_hz)

    # -- state --------------------------------------------------------------------

    def ground_truth(self) -> Odometry:
        """Return the latest ``ground_truth`` (true pose in the world frame, twist in the body)."""
        return self._wait_latest('ground_truth')

    def odom(self) -> Odometry:
        """Return the latest ``odom`` (wheel odometry); HarnessError for a robot without wheels."""
        if not self.sim.has_wheels:
            raise HarnessError('this robot has no wheels, so the simulator publishes no odom')
        return self._wait_latest('odom')

    def joint_states(self) -> JointState:
        """Return the latest ``joint_states`` (every movable joint)."""
        return self._wait_latest('joint_states')

    def last_publication_ns(self) -> int:
        """Return the simulated time (ns) of the simulator's latest state publication."""
        return self.sim.last_publication_ns

    def _wait_latest(self, topic: str):
        """Wait until the message of the latest publication has been delivered; return it."""
        # The simulator publishes from advance(), in this thread; the messages
        # reach the harness's subscriptions through the executor.
        wanted = self.last_publication_ns()

        found = []

        def arrived():
            raw = self._latest[topic]
            if raw is None:
                return False
            msg = deserialize_message(raw, self._types[topic])
            found[:] = [msg]
            return stamp_ns(msg.header.stamp) == wanted
        self._wait(arrived, f'{topic} of t={wanted / 1e9:.6f} s did not arrive')
        return found[0]

    def reset(self) -> Dict[str, Any]:
        """
        Put the robot back at its initial pose through ``~/reset``; return the reply's JSON.

        The node publishes the reset robot at its next publication (never a
        second state at a stamp already published), so this then advances one
        control period: simulated time goes on, and the state readers return
        the reset robot.
        """
        topics = ['joint_states', 'ground_truth'] + (['odom'] if self.sim.has_wheels else [])
        for topic in topics:  # nothing older may arrive after the reset
            self._wait_latest(topic)
        for topic in topics:
            self._latest[topic] = None
        reply = self._call(Trigger, self.sim.get_fully_qualified_name() + '/reset',
                           Trigger.Request())
        self.advance()
        return json.loads(reply.message)

    def _call(self, srv_type, name: str, request):
        client = self._link.create_client(srv_type, name)
        try:
            self._wait(client.service_is_ready, f'service {name} was not available')
            future = client.call_async(request)
            self._wait(future.done, f'{name} did not answer')
            return future.result()
        finally:
            self._link.destroy_client(client)

    def __enter__(self) -> 'SimHarness':
        return self


# -- another process ----------------------------------------------------------------


class RemoteProbe:
    """
    A node in a context of its own on ``domain_id``, spun in the caller's thread.

    For talking to a simulator in another process: create subscriptions,
    publishers and clients on :attr:`node`, then :meth:`spin_until` a
    condition holds. Close it when done (or use it as a context manager).
    """

    def __init__(self, domain_id: int, name: str = 'remote_probe', *,
                 namespace: Optional[str] = None) -> None:
        os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        self.domain_id = domain_id
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        try:
            self.node = Node(name, context=self.context, namespace=namespace)
            self.executor = SingleThreadedExecutor(context=self.context)
            self.executor.add_node(self.node)
        except BaseException:
            rclpy.try_shutdown(context=self.context)
            raise

    def spin_until(self, condition: Callable[[], bool], timeout_s: float) -> bool:
        """Spin until ``condition()`` holds (True) or the deadline passes (False)."""
        return spin_until(self.executor, condition, timeout_s)

    def call(self, srv_type, name: str, request, timeout_s: float = 10.0,
             resend_after_s: Optional[float] = None):
        """
        Call service ``name`` and return its response; HarnessError at the deadline.

        ``resend_after_s``: see :meth:`call_client` (idempotent services only).
        """
        client = self.node.create_client(srv_type, name)
        try:
            if not self.spin_until(client.service_is_ready, timeout_s):
                raise HarnessError(f'service {name} is not available')
            response = self.call_client(client, request, timeout_s, resend_after_s)
            if response is None:
                raise HarnessError(f'{name} did not answer within {timeout_s:g} s')
            return response
        finally:
            self.node.destroy_client(client)

    def call_client(self, client, request, timeout_s: float,
                    resend_after_s: Optional[float] = None,
                    abort: Optional[Callable[[], bool]] = None):
        """
        Send ``request`` through ``client`` and spin for the reply (None: deadline or abort()).

        ``resend_after_s``, for idempotent requests only: send the request
        again if no reply came in that long. A reply can be lost for good:
        rmw_fastrtps drops it when, 100 ms after the request came in, the
        server has still not discovered the client's reply reader, which a
        busy machine does (seen once with one core kept busy beside the test
        suite). A late reply to an earlier send is dropped.
        """
        deadline = time.monotonic() + timeout_s
        while True:
            future = client.call_async(request)
            wait_s = deadline - time.monotonic()
            if resend_after_s is not None:
                wait_s = min(wait_s, resend_after_s)
            spin_until(self.executor, lambda: future.done() or (abort is not None and abort()),
                       max(wait_s, 0.0))
            if future.done():
                return future.result()
            client.remove_pending_request(future)
            if (abort is not None and abort()) or time.monotonic() >= deadline:
                return None

    def close(self) -> None:
        """Shut the executor down, destroy the node, shut the context down; safe twice."""
        if self.context.ok():
            self.executor.shutdown(timeout_sec=1.0)
            self.node.destroy_node()
            rclpy.try_shutdown(context=self.context)

    def __enter__(self) -> 'RemoteProbe':
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


class ProcessResult(NamedTuple):
    """How a process ended: its exit status and everything it wrote."""

    returncode: int
    stdout: str
    stderr: str


def stop_process(process: subprocess.Popen, sig: int = signal.SIGINT,
                 timeout_s: float = 10.0) -> ProcessResult:
    """
    Send ``sig``, wait up to ``timeout_s`` for the exit, kill as a last resort.

    Returns the exit status and the output read from pipes ('' for output
    that went elsewhere).
    """
    if process.poll() is None:
        process.send_signal(sig)
    try:
        out, err = process.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
    return ProcessResult(process.returncode, out or '', err or '')


def sim_node_command(parameters: Optional[Mapping[str, Any]] = None,
                     ros_args: Sequence[str] = (),
                     command: Optional[Sequence[str]] = None) -> List[str]:
    """
    Return the command line that runs the simulator with these parameters.

    ``command`` defaults to this interpreter's ``-m r2d2_sim`` (the same code
    as ``sim_node``). Values are written as JSON, which ROS reads as YAML:
    strings stay strings, lists stay lists.
    """
    args = list(command or [sys.executable, '-m', 'r2d2_sim'])
    ros = []
    for name, value in (parameters or {}).items():
        ros += ['-p', f'{name}:={json.dumps(value)}']
    ros += list(ros_args)
    return args + (['--ros-args'] + ros if ros else [])


class SimProcess:
    """
    The ``sim_node`` executable in a process of its own, driven through its services.

    ``SimProcess(start_paused=True, publish_rate=20.0)``: keywords other than
    the harness's own are the simulator's ROS parameters; ``ros_args`` are
    appended after ``--ros-args`` (remaps, ``--params-file``). Starts the
    process and returns once it serves its services, its topics are linked
    to this object's node and, unless it starts paused, ``/clock`` arrives.

    The domain: ``domain_id`` if given; else ``ROS_DOMAIN_ID`` if the
    environment sets it and ``use_env_domain`` is true (so your own ROS tools
    see the simulator), else a free one. Either way it is leased, so two
    harnesses on this machine never share it: they take turns instead.
    ``timeout_s`` bounds start-up and every wait (wall clock).
    """

    def __init__(self, *, node_name: str = 'r2d2_sim', namespace: str = '',
                 domain_id: Optional[int] = None, use_env_domain: bool = True,
                 ros_args: Sequence[str] = (), command: Optional[Sequence[str]] = None,
                 timeout_s: float = 30.0, **parameters: Any) -> None:
        if domain_id is None and use_env_domain:
            domain_id = _env_domain_id()
        self.timeout_s = timeout_s
        self.result: Optional[ProcessResult] = None
        self.paused = False
        self.last_status: Dict[str, Any] = {}
        self._not_before_ns = 0  # state readers take no message stamped before (a reset)
        self.process: Optional[subprocess.Popen] = None
        self.probe: Optional[RemoteProbe] = None
        self._latest: Dict[str, Any] = {'joint_states': None, 'odom': None,
                                        'ground_truth': None, 'clock': None}
        self._subscriptions: Dict[str, Any] = {}
        self._clients: Dict[str, Any] = {}
        self._cmd_vel = None
        self.lease = lease_domain(domain_id, timeout_s=max(timeout_s, 60.0))
        self.domain_id = self.lease.domain_id
        namespace = '/' + namespace.strip('/') if namespace.strip('/') else ''
        self.node_path = f'{namespace}/{node_name}'
        remaps = (['-r', f'__node:={node_name}'] if node_name != 'r2d2_sim' else []) + \
            (['-r', f'__ns:={namespace}'] if namespace else [])
        self.command = sim_node_command(parameters, remaps + list(ros_args), command)
        self._stdout = tempfile.TemporaryFile('w+', encoding='utf-8', errors='replace')
        self._stderr = tempfile.TemporaryFile('w+', encoding='utf-8', errors='replace')
        try:
            # Files, not pipes: nobody reads while it runs, and a full pipe
            # would block the simulator.
            self.process = subprocess.Popen(self.command, env=ros_child_env(self.domain_id),
                                            stdout=self._stdout, stderr=self._stderr,
                                            stdin=subprocess.DEVNULL)
            self.probe = RemoteProbe(self.domain_id, '_r2d2_sim_process_client',
                                     namespace=namespace or None)
            self._connect()
            self._wait_ready()
        except BaseException:
            self.stop()
            raise

    def _connect(self) -> None:
        """Create this side's subscriptions, cmd_vel publisher and service clients."""
        node = self.probe.node
        for topic, msg_type in (('joint_states', JointState), ('odom', Odometry),
                                ('ground_truth', Odometry), ('/clock', Clock)):
            key = topic.lstrip('/')
            self._subscriptions[key] = node.create_subscription(
                msg_type, topic, self._keeper(key), 1)
        self._cmd_vel = node.create_publisher(Twist, 'cmd_vel', 10)
        self._clients = {name: node.create_client(srv, f'{self.node_path}/{name}')
                         for name, srv in (('pause', SetBool), ('step', Trigger),
                                           ('reset', Trigger), ('get_joint_info', Trigger),
                                           ('get_status', Trigger))}

    def _keeper(self, key: str) -> Callable[[Any], None]:
        def keep(msg) -> None:
            self._latest[key] = msg
        return keep

    def _exited(self) -> bool:
        return self.process.poll() is not None

    def _wait_ready(self) -> None:
        # odom is left out: a robot without wheels has none.
        state = [self._subscriptions[key] for key in ('joint_states', 'ground_truth', 'clock')]

        def linked():
            return self._exited() or (all(c.service_is_ready() for c in self._clients.values())
                                      and self._cmd_vel.get_subscription_count() > 0
                                      and all(s.get_publisher_count() > 0 for s in state))
        if not self.probe.spin_until(linked, self.timeout_s) or self._exited():
            self._fail_start('did not serve its services')
        # Paused or not (start_paused may come from a --params-file). get_status's
        # client is created last: the server learns of our reply readers in the
        # order we made them, so once it answers here it can answer every client.
        self.status()
        if not self.paused and not self.probe.spin_until(
                lambda: self._latest['clock'] is not None or self._exited(), self.timeout_s):
            self._fail_start('published no /clock')

    def _fail_start(self, what: str) -> None:
        if self._exited():
            result = self.stop()
            raise HarnessError(f'sim_node exited with status {result.returncode} while '
                               f'starting: {result.stderr.strip()[-2000:]}')
        raise HarnessError(f'sim_node {what} within {self.timeout_s:g} s')

    # -- services -------------------------------------------------------------------

    def _request(self, name: str, request, resend_after_s: Optional[float] = None
                 ) -> Dict[str, Any]:
        if self._exited():
            raise HarnessError(f'sim_node has exited (status {self.process.returncode})')
        reply = self.probe.call_client(self._clients[name], request, self.timeout_s,
                                       resend_after_s, abort=self._exited)
        if reply is None:
            raise HarnessError(f'{self.node_path}/{name} did not answer within '
                               f'{self.timeout_s:g} s')
        facts = json.loads(reply.message)
        if name != 'get_joint_info':
            self.last_status = facts
            self.paused = facts['paused']
        if not reply.success:
            raise HarnessError(f'~/{name} failed: {facts.get("error", reply.message)}')
        return facts

    def pause(self, paused: bool = True) -> Dict[str, Any]:
        """Pause (or with False resume) through ``~/pause``; return the reply's JSON state."""
        request = SetBool.Request()
        request.data = paused
        return self._request('pause', request)

    def resume(self) -> Dict[str, Any]:
        """Let simulated time run again; return the reply's JSON state."""
        return self.pause(False)

    def status(self) -> Dict[str, Any]:
        """
        Return the simulator's state without changing it.

        Asks ``~/get_status`` and returns its JSON reply: ``paused``, ``step``,
        ``sim_time_ns``, ``sim_time``, ``commands_received``.
        """
        return self._request('get_status', Trigger.Request(), STATUS_RESEND_S)

    def step(self, count: int = 1) -> Dict[str, Any]:
        """
        Advance a paused simulator ``count`` control periods through ``~/step``.

        Returns the last reply with ``steps``, the physics steps of all the
        calls. Raises HarnessError if it is running (pause it first).
        """
        total = 0
        facts: Dict[str, Any] = {}
        for _ in range(count):
            facts = self._request('step', Trigger.Request())
            total += facts['steps']
        facts['steps'] = total
        return facts

    def reset(self) -> Dict[str, Any]:
        """
        Put the robot back at its initial pose through ``~/reset``; return the reply's JSON.

        The node publishes the reset robot at its next publication: the state
        readers wait for one after the reply's time (while paused, step() first).
        """
        facts = self._request('reset', Trigger.Request())
        self._not_before_ns = facts['sim_time_ns'] + 1
        return facts

    def joint_info(self) -> Dict[str, Any]:
        """Return ``~/get_joint_info``'s JSON: ``robot``, ``urdf`` and ``joints``."""
        return self._request('get_joint_info', Trigger.Request(), STATUS_RESEND_S)

    # -- topics -------------------------------------------------------------------

    def send_cmd_vel(self, linear: float = 0.0, angular: float = 0.0, *,
                     twist: Optional[Twist] = None) -> None:
        """
        Publish a Twist on ``cmd_vel`` and return once the simulator has counted it.

        Confirmed through the ``commands_received`` of its control services.
        """
        if twist is None:
            twist = Twist()
            twist.linear.x, twist.angular.z = float(linear), float(angular)
        before = self.status()['commands_received']
        self._cmd_vel.publish(twist)
        deadline = time.monotonic() + self.timeout_s
        while self.status()['commands_received'] <= before:
            if time.monotonic() > deadline:
                raise HarnessError(f'the simulator did not take cmd_vel within '
                                   f'{self.timeout_s:g} s')
            self.probe.spin_until(lambda: False, 0.002)

    def ground_truth(self) -> Odometry:
        """Return the latest ``ground_truth`` (when paused: of the time the last reply gave)."""
        return self._wait_latest('ground_truth')

    def odom(self) -> Odometry:
        """Return the latest ``odom`` (wheel odometry; when paused: of the last reply's time)."""
        return self._wait_latest('odom')

    def joint_states(self) -> JointState:
        """Return the latest ``joint_states`` (when paused: of the time the last reply gave)."""
        return self._wait_latest('joint_states')

    def _wait_latest(self, key: str):
        """
        Paused: wait for the message stamped with the last reply's time. Running: the newest.

        A paused simulator has published its state at the time its last reply
        gives (pause lands on a publication, a step ends with one).
        """
        if not (self.paused and self.last_status):
            self.status()  # running: wait for what is published from now on
        wanted = self.last_status['sim_time_ns']
        if self.paused and wanted < self._not_before_ns:
            raise HarnessError(f'no {key} yet: the reset robot is published at the next '
                               'publication; step() first')
        floor = max(wanted, self._not_before_ns)

        def arrived():
            msg = self._latest[key]
            if msg is None:
                return False
            stamp = stamp_ns(msg.header.stamp)
            return stamp == wanted if self.paused else stamp >= floor
        if not self.probe.spin_until(arrived, self.timeout_s):
            hint = (': a simulator that started paused has published nothing since this '
                    'client connected; step() it first'
                    if self.paused and self.last_status.get('step') == 0 else '')
            raise HarnessError(f'no {key} of t={wanted / 1e9:.6f} s within '
                               f'{self.timeout_s:g} s{hint}')
        return self._latest[key]

    # -- teardown -----------------------------------------------------------------

    def stop(self, timeout_s: float = 10.0) -> ProcessResult:
        """
        Stop the simulator with SIGINT (SIGKILL after ``timeout_s``); return how it ended.

        Also closes this object's node and releases the domain. Safe to call
        twice: later calls return the first result.
        """
        if self.result is not None:
            return self.result
        try:
            if self.process is not None:
                code = stop_process(self.process, signal.SIGINT, timeout_s).returncode
            else:
                code = -1
            outputs = []
            for handle in (self._stdout, self._stderr):
                handle.seek(0)
                outputs.append(handle.read())
                handle.close()
            self.result = ProcessResult(code, *outputs)
        finally:
            if self.probe is not None:
                self.probe.close()
            self.lease.release()
        return self.result

    def __enter__(self) -> 'SimProcess':
        return self

    def __exit__(self, *exc_info) -> None:
        self.stop()
