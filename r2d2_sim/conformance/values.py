"""
Numbers out of geometry_msgs, and compared: what the clauses and the Target's parts share.

The clauses read positions and orientations as tuples and compare them with
a tolerance (a quaternion and its negative are one rotation); requests are
written by the standard's client. These few helpers are kept apart from the
Target so that a clause can use them without it.
"""

import math
from typing import Iterable, Sequence, Tuple, TYPE_CHECKING, Union

if TYPE_CHECKING:  # typing only: no ROS is loaded here
    from geometry_msgs.msg import Point, Quaternion, Vector3


def _close(a: Sequence[float], b: Sequence[float], tolerance: float) -> bool:
    return all(abs(x - y) <= tolerance for x, y in zip(a, b))


def vector(v: 'Union[Vector3, Point]') -> Tuple[float, float, float]:
    """Return a geometry_msgs Vector3 or Point as a tuple."""
    return (v.x, v.y, v.z)


def quaternion(q: 'Quaternion') -> Tuple[float, float, float, float]:
    """Return a geometry_msgs Quaternion as an (x, y, z, w) tuple."""
    return (q.x, q.y, q.z, q.w)


def yaw_quaternion(yaw: float) -> Tuple[float, float, float, float]:
    """Return the quaternion of a turn by ``yaw`` radians about z."""
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


def same_rotation(a: Sequence[float], b: Sequence[float], tolerance: float = 1e-3) -> bool:
    """Return True when two quaternions turn alike (q and -q are one rotation)."""
    return _close(a, b, tolerance) or _close(a, [-v for v in b], tolerance)


def close(a: Sequence[float], b: Sequence[float], tolerance: float = 1e-3) -> bool:
    """Return True when two vectors agree within ``tolerance`` on every axis."""
    return _close(a, b, tolerance)


def fmt(values: Iterable[float]) -> str:
    """Return numbers as a short tuple for a reason: (1.0, 2.5, 0.0)."""
    return '(' + ', '.join(f'{v:.4g}' for v in values) + ')'
