"""
What any ROS client of the simulator needs: poses, deadline waits, child processes.

Used by the ``demo`` and ``drive`` executables, the benchmarks and the testing
API alike, so none of them reaches into another for a small helper. Imports
rclpy message types only (no PyBullet, no pytest). For child processes: their
environment (:func:`ros_child_env`) and their lifetime, which ``sim_node``
ties to the process that started it (:func:`end_with_parent`).
"""

import json
import math
import numbers
import os
from pathlib import Path
import select
import signal
import sys
import threading
import time
from typing import Any, Callable, NamedTuple, Optional, TYPE_CHECKING

from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry

from r2d2_sim.errors import StartupError
from r2d2_sim.model.timing import stamp_ns, stamp_of
from r2d2_sim.model.transforms import quaternion_to_yaw

if TYPE_CHECKING:  # typing only
    from rclpy.executors import Executor

__all__ = ['Pose2D', 'pose_from_odometry', 'spin_until', 'wait_for', 'step_count',
           'sim_seconds', 'ros_child_env',
           'numbers_alike', 'ros_arg', 'stamp_ns', 'twist_message', 'twist_stamped_message',
           'command_twist',
           'UNKNOWN_NODE_NAME', 'PARENT_PID_ENV', 'end_with_parent']

# What rmw reports as the node of an endpoint whose node it has not yet discovered.
UNKNOWN_NODE_NAME = '_NODE_NAME_UNKNOWN_'
# The process id of the process a child must not outlive (ChildProcess sets it).
PARENT_PID_ENV = 'R2D2_SIM_PARENT_PID'
# After that process has ended: SIGTERM (a clean stop) at once, SIGKILL this much later (s).
ORPHAN_KILL_AFTER_S = 10.0
# How often the watch checks the ancestry where the kernel has no pidfd (s).
ANCESTRY_POLL_S = 0.5


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


def twist_message(linear: float = 0.0, angular: float = 0.0) -> Twist:
    """Return a Twist of ``linear`` m/s along x and ``angular`` rad/s about z."""
    twist = Twist()
    twist.linear.x, twist.angular.z = float(linear), float(angular)
    return twist


def command_twist(linear: Any = 0.0, angular: Any = 0.0,
                  twist: Optional[Any] = None) -> Any:
    """
    Return the command to send: ``twist`` as given, or a Twist of ``linear`` and ``angular``.

    ValueError (one line, naming the field) for a value that is not a finite
    number: the simulator refuses NaN and inf and keeps the last command, so
    a test sending one would go on with the robot driving as before.
    """
    if twist is None:
        for name, value in (('linear', linear), ('angular', angular)):
            number = float(value) if isinstance(value, numbers.Real) else math.nan
            if isinstance(value, bool) or not math.isfinite(number):
                raise ValueError(f'send_cmd_vel: {name} must be a finite number, got {value!r}')
        return twist_message(linear, angular)
    inner = getattr(twist, 'twist', twist)  # a TwistStamped's, or the Twist itself
    for part in ('linear', 'angular'):
        for axis in 'xyz':
            value = getattr(getattr(inner, part, None), axis, None)
            if not isinstance(value, float) or not math.isfinite(value):
                raise ValueError(f'send_cmd_vel: twist.{part}.{axis} must be a finite number, '
                                 f'got {value!r}')
    return twist


def twist_stamped_message(linear: float = 0.0, angular: float = 0.0, *, stamp_ns: int = 0,
                          frame_id: str = '', twist: Optional[Twist] = None) -> TwistStamped:
    """
    Return a TwistStamped (Nav2's ``cmd_vel`` on Jazzy) of ``twist`` or ``linear``/``angular``.

    A zero ``stamp_ns`` means "now" to the simulator, as Nav2's and teleop's
    unstamped senders fill it.
    """
    msg = TwistStamped()
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_of(stamp_ns)
    msg.header.frame_id = frame_id
    msg.twist = twist if twist is not None else twist_message(linear, angular)
    return msg


def spin_until(executor: 'Executor', condition: Callable[[], bool], timeout_s: float,
               abort: Optional[Callable[[], bool]] = None) -> bool:
    """
    Spin ``executor`` until ``condition()`` holds; False at the deadline or on ``abort()``.

    :param executor: an rclpy executor, spun in this thread
    :param timeout_s: wall-clock seconds
    :param abort: checked between spins; True ends the wait early (False returned)
    """
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


def step_count(value: Any, what: str = 'steps') -> int:
    """
    Return ``value`` as a number of steps; ValueError (one line) unless a whole number >= 0.

    A float is refused, even 2.0: ``advance(2.0)`` meant seconds, which go by
    keyword. Checked before any request is sent (a negative count reached
    ``step_simulation`` as a huge unsigned one).
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        hint = ' (simulated time goes as seconds=...)' if isinstance(value, float) else ''
        raise ValueError(f'{what} must be a whole number >= 0, got {value!r}{hint}')
    count = int(value)  # numpy's integers too
    if count < 0:
        raise ValueError(f'{what} must be a whole number >= 0, got {count}')
    return count


def sim_seconds(value: Any) -> float:
    """Return ``value`` as simulated seconds; ValueError (one line) unless a finite number >= 0."""
    seconds = float(value) if isinstance(value, numbers.Real) else math.nan  # numpy's too
    if isinstance(value, bool) or not 0.0 <= seconds < math.inf:
        raise ValueError(f'simulated time must be a finite number >= 0 s, got {value!r}')
    return seconds


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


def numbers_alike(value: Any) -> Any:
    """Return a list of numbers with a float among them as all floats; anything else as is."""
    if (isinstance(value, (list, tuple)) and value
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
            and any(isinstance(v, float) for v in value)):
        return [float(v) for v in value]
    return value


def ros_arg(value: Any) -> str:
    """
    Write a value as the right-hand side of ``-p name:=value``, keeping its type.

    ROS reads the text as YAML: JSON is YAML, so strings stay strings (even
    ``'true'`` or ``'1'``), lists stay lists, and a float keeps its point
    (``1.0``, ``1e-05``, both doubles on Jazzy's rcl). A list of numbers with
    a float among them is written all floats (rcl refuses mixed lists).
    """
    return json.dumps(numbers_alike(value))


def end_with_parent() -> None:
    """
    End this process when the one named in ``R2D2_SIM_PARENT_PID`` ends; do nothing if unset.

    A test process killed by a CI timeout (SIGKILL), or dying of an exception
    outside ``with``, stops none of its children: ``sim_node`` calls this at
    start-up so that it does not run on, in a domain whose lease it keeps
    held. A daemon thread waits for that process (a pidfd, or where the kernel
    has none, its place among our ancestors every 0.5 s), then sends this
    process SIGTERM and, should that not end it, SIGKILL 10 s later. It
    watches the process by id, not the thread that started us (which
    ``PR_SET_PDEATHSIG`` would: a harness started from a short-lived thread
    would lose its simulator with that thread). The variable is removed
    from the environment. Raises :class:`~r2d2_sim.errors.StartupError` if
    it is not a process id, or names no ancestor of ours: that process has
    ended already (the race of a parent dying while we started).
    """
    text = os.environ.pop(PARENT_PID_ENV, '').strip()
    if not text:
        return
    try:
        pid = int(text)
    except ValueError:
        raise StartupError(f'{PARENT_PID_ENV} must be a process id, got {text!r}') from None
    try:  # opened before the check: if the check passes, it is that process
        pidfd = os.pidfd_open(pid)
    except (AttributeError, OSError):  # gone, or no pidfds here (Linux < 5.3, not Linux)
        pidfd = None
    if not _has_ancestor(pid):
        if pidfd is not None:
            os.close(pidfd)
        raise StartupError(f'the process that started this one ({PARENT_PID_ENV}={pid}) '
                           'has ended: it is not among the ancestors of this process')
    threading.Thread(target=_end_after, args=(pid, pidfd), name='end_with_parent',
                     daemon=True).start()


def _parent_of(pid: int) -> Optional[int]:
    """Return the parent process id of ``pid`` from /proc (None if unknown)."""
    try:
        with open(f'/proc/{pid}/stat', 'rb') as stat_file:
            text = stat_file.read()
    except OSError:
        return None
    return int(text[text.rindex(b')') + 1:].split()[1])  # after "pid (comm)": state, ppid


def _has_ancestor(pid: int) -> bool:
    """Return True if ``pid`` is our parent or one of its ancestors (a wrapper between us)."""
    ancestor: Optional[int] = os.getppid()
    for _ in range(64):  # process trees are not that deep; a bound all the same
        if ancestor == pid:
            return True
        if ancestor is None or ancestor <= 1:
            return False
        ancestor = _parent_of(ancestor)
    return False


def _end_after(pid: int, pidfd: Optional[int]) -> None:
    """Wait for process ``pid`` to end, then stop this process (SIGTERM, later SIGKILL)."""
    if pidfd is not None:
        watch = select.poll()
        watch.register(pidfd, select.POLLIN)
        watch.poll()  # readable once that process has ended
    else:
        while _has_ancestor(pid):  # no event to wait for: once it ends, we are re-parented
            time.sleep(ANCESTRY_POLL_S)
    sys.stderr.write(f'the process that started this one (pid {pid}) has ended: stopping\n')
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(ORPHAN_KILL_AFTER_S)  # a grace period, not a wait for an event
    os.kill(os.getpid(), signal.SIGKILL)
