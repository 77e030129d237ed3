"""
Helpers for processes that talk to the simulator from outside: poses, waits, CLI.

Shared by the ``demo`` and ``drive`` executables, the cross-process tests and
the benchmarks.
"""

import argparse
import math
import os
from pathlib import Path
import sys
import time
from typing import Callable, List, NamedTuple, Optional, Sequence

from nav_msgs.msg import Odometry
from rclpy.utilities import remove_ros_args

from r2d2_sim.drive import quaternion_to_yaw


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


def finite_number(text: str) -> float:
    """Parse a command-line number that must be finite (an argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be a number, got {text!r}') from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'must be a finite number, got {text!r}')
    return value


def non_negative_number(text: str) -> float:
    """Parse a finite command-line number >= 0 (an argparse type)."""
    value = finite_number(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f'must be >= 0, got {text!r}')
    return value


def positive_number(text: str) -> float:
    """Parse a finite command-line number > 0 (an argparse type)."""
    value = finite_number(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f'must be > 0, got {text!r}')
    return value


def non_ros_args(argv: Sequence[str], prog: str) -> List[str]:
    """
    Return the arguments after the program name that are not for ROS.

    Malformed ``--ros-args`` end the program like an argparse error: one line
    on stderr and exit status 2.
    """
    try:
        return remove_ros_args(list(argv))[1:]
    except Exception as exc:  # rcl's parse errors come as assorted exception types
        print(f'{prog}: error: bad ROS arguments: {exc}', file=sys.stderr)
        raise SystemExit(2)


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
