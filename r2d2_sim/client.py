"""
What any ROS client of the simulator needs: poses, deadline waits, child environments.

Used by the ``demo`` and ``drive`` executables, the benchmarks and the testing
API alike, so none of them reaches into another for a small helper. Imports
rclpy message types only (no PyBullet, no pytest).
"""

import json
import os
from pathlib import Path
import sys
import time
from typing import Any, Callable, NamedTuple, Optional

from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry

from r2d2_sim.model.timing import stamp_ns, stamp_of
from r2d2_sim.model.transforms import quaternion_to_yaw

__all__ = ['Pose2D', 'pose_from_odometry', 'spin_until', 'wait_for', 'ros_child_env',
           'numbers_alike', 'ros_arg', 'stamp_ns', 'twist_message', 'twist_stamped_message',
           'UNKNOWN_NODE_NAME']

# What rmw reports as the node of an endpoint whose node it has not yet discovered.
UNKNOWN_NODE_NAME = '_NODE_NAME_UNKNOWN_'


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


def spin_until(executor, condition: Callable[[], bool], timeout_s: float,
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
