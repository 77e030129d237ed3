"""
Helpers for code that talks to the simulator from outside: poses, deadline waits, processes.

Used by the ``demo`` and ``drive`` executables, the tests and the benchmarks.
"""

import os
from pathlib import Path
import sys
import time
from typing import Callable, NamedTuple, Optional

from nav_msgs.msg import Odometry

from r2d2_sim.kinematics import quaternion_to_yaw


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
