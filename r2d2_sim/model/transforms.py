"""
Rigid transforms and quaternions, for TF publishing, sensor mounts and poses.

Pure math, free of ROS and PyBullet.  A ``Transform`` maps points of a child
frame into its parent frame, as a tf2 transform from ``frame_id`` to
``child_frame_id`` does.  Quaternions are (x, y, z, w), as in ROS and
PyBullet; translations are in metres and angles in radians.  Single transforms
are plain tuples of floats: for objects this small, numpy's per-call overhead
would cost more than the arithmetic.

A URDF's link tree (its joints as transforms) is in :mod:`r2d2_sim.model.link_tree`.
"""

import math
from typing import NamedTuple, Sequence

__all__ = [
    'Vector3',
    'Quaternion',
    'Transform',
    'IDENTITY',
    'BaseState',
    'in_body_frame',
    'quaternion_multiply',
    'normalised',
    'quaternion_from_rpy',
    'quaternion_from_axis_angle',
    'unit_vector',
    'rotate',
    'compose',
    'inverse',
    'apply',
    'yaw_of',
    'yaw_to_quaternion',
    'quaternion_to_yaw',
    'split_yaw',
    'rotation_matrix',
    'rotate_inverse',
]

Vector3 = tuple[float, float, float]
Quaternion = tuple[float, float, float, float]  # (x, y, z, w)


class Transform(NamedTuple):
    """Pose of a child frame in its parent frame: rotate by ``rotation``, then translate."""

    translation: Vector3  # metres, child origin in parent coordinates
    rotation: Quaternion  # unit quaternion (x, y, z, w)


IDENTITY = Transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))


class BaseState(NamedTuple):
    """
    Where a body's frame is and how it moves: the pose in the world, the twist.

    A body's base state, an entity's state: the reader says in which frame
    the twist is given (the body frame for odometry, the world for entities).
    """

    position: Vector3
    orientation: Quaternion
    linear_velocity: Vector3
    angular_velocity: Vector3


def quaternion_multiply(a: Quaternion, b: Quaternion) -> Quaternion:
    """Return the Hamilton product a * b: the rotation b followed by the rotation a."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def normalised(q: Quaternion) -> Quaternion:
    """Return ``q`` scaled to unit length (PyBullet's are off by up to ~1e-8); q if it has none."""
    x, y, z, w = q
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not (norm > 0.0 and math.isfinite(norm)):
        return q
    return (x / norm, y / norm, z / norm, w / norm)


def quaternion_from_rpy(roll_rad: float, pitch_rad: float, yaw_rad: float) -> Quaternion:
    """
    Return the quaternion of URDF ``rpy``: R = Rz(yaw) Ry(pitch) Rx(roll).

    That is roll about the fixed x axis first, then pitch about fixed y, then
    yaw about fixed z (the same as tf2's ``setRPY`` and PyBullet's
    ``getQuaternionFromEuler``).
    """
    cr, sr = math.cos(roll_rad / 2.0), math.sin(roll_rad / 2.0)
    cp, sp = math.cos(pitch_rad / 2.0), math.sin(pitch_rad / 2.0)
    cy, sy = math.cos(yaw_rad / 2.0), math.sin(yaw_rad / 2.0)
    return (sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy)


def unit_vector(vector: Sequence[float], what: str) -> Vector3:
    """Return ``vector`` scaled to length 1; ValueError naming ``what`` if that is impossible."""
    x, y, z = (float(c) for c in vector)
    norm = math.sqrt(x * x + y * y + z * z)
    if not (norm > 0.0 and math.isfinite(norm)):
        raise ValueError(f'{what} must be a finite non-zero vector, got {tuple(vector)!r}')
    return (x / norm, y / norm, z / norm)


def quaternion_from_axis_angle(axis: Sequence[float], angle_rad: float) -> Quaternion:
    """Return the rotation of ``angle_rad`` about ``axis`` (normalised here; zero refused)."""
    x, y, z = unit_vector(axis, 'axis')
    s, c = math.sin(angle_rad / 2.0), math.cos(angle_rad / 2.0)
    return (x * s, y * s, z * s, c)


def rotate(rotation: Quaternion, vector: Sequence[float]) -> Vector3:
    """Rotate ``vector`` by the unit quaternion ``rotation``."""
    qx, qy, qz, qw = rotation
    vx, vy, vz = vector
    # v' = v + w t + q x t with t = 2 q x v: 15 multiplications instead of two products.
    tx = 2.0 * (qy * vz - qz * vy)
    ty = 2.0 * (qz * vx - qx * vz)
    tz = 2.0 * (qx * vy - qy * vx)
    return (vx + qw * tx + qy * tz - qz * ty,
            vy + qw * ty + qz * tx - qx * tz,
            vz + qw * tz + qx * ty - qy * tx)


def rotation_matrix(rotation: Quaternion) -> tuple[Vector3, Vector3, Vector3]:
    """Return the rows of the 3x3 matrix of a unit quaternion (R v == rotate(q, v))."""
    x, y, z, w = rotation
    return ((1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - z * w), 2.0 * (x * z + y * w)),
            (2.0 * (x * y + z * w), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - x * w)),
            (2.0 * (x * z - y * w), 2.0 * (y * z + x * w), 1.0 - 2.0 * (x * x + y * y)))


def rotate_inverse(rotation: Quaternion, vector: Sequence[float]) -> Vector3:
    """Rotate ``vector`` by the inverse of the unit quaternion ``rotation``."""
    x, y, z, w = rotation
    return rotate((-x, -y, -z, w), vector)


def in_body_frame(world: BaseState) -> BaseState:
    """Return ``world`` (its twist in the world frame) with the twist in the body's own frame."""
    position, orientation, linear, angular = world
    return BaseState(position, orientation, rotate_inverse(orientation, linear),
                     rotate_inverse(orientation, angular))


def compose(a: Transform, b: Transform) -> Transform:
    """Return a * b, where b is expressed in a's child frame (tf2's ``operator*``)."""
    (ax, ay, az), rotation_a = a
    bx, by, bz = rotate(rotation_a, b[0])
    return Transform((ax + bx, ay + by, az + bz), quaternion_multiply(rotation_a, b[1]))


def inverse(t: Transform) -> Transform:
    """Return the transform that undoes ``t`` (parent and child swapped)."""
    (tx, ty, tz), (qx, qy, qz, qw) = t
    conjugate = (-qx, -qy, -qz, qw)
    x, y, z = rotate(conjugate, (tx, ty, tz))
    return Transform((-x, -y, -z), conjugate)


def apply(t: Transform, point: Sequence[float]) -> Vector3:
    """Map a point from t's child frame into its parent frame."""
    (tx, ty, tz), rotation = t
    x, y, z = rotate(rotation, point)
    return (x + tx, y + ty, z + tz)


def yaw_of(q: Quaternion) -> float:
    """
    Return the yaw of ``q`` in (-pi, pi]: the heading of its x axis seen from above.

    This is the Z of a Z-Y-X (yaw, pitch, roll) decomposition; it is undefined
    when the x axis points straight up or down (pitch +-pi/2).  Any non-zero
    scale of ``q`` gives the same yaw.
    """
    x, y, z, w = q
    return math.atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z)


def yaw_to_quaternion(yaw_rad: float) -> Quaternion:
    """Return the (x, y, z, w) quaternion of a pure rotation by yaw about +z (finite yaw)."""
    if not math.isfinite(yaw_rad):
        raise ValueError(f'yaw_rad must be finite, got {yaw_rad!r}')
    half_rad = yaw_rad / 2.0
    return 0.0, 0.0, math.sin(half_rad), math.cos(half_rad)


def quaternion_to_yaw(x: float, y: float, z: float, w: float) -> float:
    """
    Return the yaw (ZYX Euler convention) of a quaternion, in (-pi, pi].

    :func:`yaw_of` with checks, for quaternions from outside (messages): it
    need not be normalised; roll and pitch are ignored. Non-finite or
    all-zero quaternions raise ValueError.
    """
    for name, value in (('x', x), ('y', y), ('z', z), ('w', w)):
        if not math.isfinite(value):
            raise ValueError(f'{name} must be finite, got {value!r}')
    if x == 0.0 and y == 0.0 and z == 0.0 and w == 0.0:
        raise ValueError('quaternion (0, 0, 0, 0) has no orientation')
    yaw_rad = yaw_of((x, y, z, w))
    return math.pi if yaw_rad == -math.pi else yaw_rad


def split_yaw(q: Quaternion) -> tuple[Quaternion, Quaternion]:
    """
    Split ``q`` into (yaw, tilt) with q = yaw * tilt and ``yaw_of(tilt) == 0``.

    ``yaw`` turns about z only; ``tilt`` is the remaining pitch and roll, so a
    base_footprint frame takes ``yaw`` and base_footprint -> base_link takes ``tilt``.
    """
    half_yaw_rad = yaw_of(q) / 2.0
    yaw = (0.0, 0.0, math.sin(half_yaw_rad), math.cos(half_yaw_rad))
    return yaw, quaternion_multiply((0.0, 0.0, -yaw[2], yaw[3]), q)
