"""
Rigid transforms and a URDF's kinematic tree, for TF publishing and sensor mounts.

Pure math, free of ROS and PyBullet.  A ``Transform`` maps points of a child
frame into its parent frame, as a tf2 transform from ``frame_id`` to
``child_frame_id`` does.  Quaternions are (x, y, z, w), as in ROS and
PyBullet; translations are in metres and angles in radians.  Single transforms
are plain tuples of floats: for objects this small, numpy's per-call overhead
would cost more than the arithmetic.

``LinkTransforms`` reads a URDF once and then gives, for joint positions, the
parent link -> child link transform of every joint, which is what
robot_state_publisher puts on /tf (moving joints) and /tf_static (fixed ones).
"""

import math
from typing import NamedTuple, Optional, Sequence
import xml.etree.ElementTree as ElementTree

__all__ = [
    'Vector3',
    'Quaternion',
    'Transform',
    'IDENTITY',
    'BaseState',
    'quaternion_multiply',
    'quaternion_from_rpy',
    'quaternion_from_axis_angle',
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
    'JointModel',
    'JointTransform',
    'parse_joints',
    'root_link',
    'joint_transform',
    'LinkTransforms',
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


def _unit_vector(vector: Sequence[float], what: str) -> Vector3:
    """Return ``vector`` scaled to length 1; ValueError naming ``what`` if that is impossible."""
    x, y, z = (float(c) for c in vector)
    norm = math.sqrt(x * x + y * y + z * z)
    if not (norm > 0.0 and math.isfinite(norm)):
        raise ValueError(f'{what} must be a finite non-zero vector, got {tuple(vector)!r}')
    return (x / norm, y / norm, z / norm)


def quaternion_from_axis_angle(axis: Sequence[float], angle_rad: float) -> Quaternion:
    """Return the rotation of ``angle_rad`` about ``axis`` (normalised here; zero refused)."""
    x, y, z = _unit_vector(axis, 'axis')
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


class JointModel(NamedTuple):
    """A URDF joint: its type, the links it connects, and its frame and axis."""

    name: str
    type: str  # 'revolute', 'continuous', 'prismatic', 'fixed', 'planar', 'floating'
    parent_link: str
    child_link: str
    origin: Transform  # child link frame at position 0, in the parent link frame
    axis: Vector3  # unit vector in the child link frame (joint frame)


class JointTransform(NamedTuple):
    """One edge of the link tree at given joint positions, as a TF message carries it."""

    parent_link: str
    child_link: str
    transform: Transform


_ROTATING = ('revolute', 'continuous')
_MOVING = _ROTATING + ('prismatic',)
_DEFAULT_AXIS = (1.0, 0.0, 0.0)
# How LinkTransforms.moving computes a joint.
_REVOLUTE, _PRISMATIC, _CONSTANT = range(3)


def _parse_triple(element: Optional[ElementTree.Element], attribute: str, default: Vector3,
                  where: str) -> Vector3:
    """Read three finite numbers from an attribute; ValueError naming ``where`` if malformed."""
    text = None if element is None else element.get(attribute)
    if text is None:
        return default
    try:
        values = tuple(float(part) for part in text.split())
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ValueError(f'{where}: {attribute}="{text}" must be three finite numbers')
    return values


def _required_link(joint: ElementTree.Element, tag: str, where: str) -> str:
    """Return the ``link`` attribute of the joint's <parent> or <child>."""
    element = joint.find(tag)
    link = None if element is None else element.get('link')
    if not link:
        raise ValueError(f'{where}: missing <{tag} link="..."/>')
    return link


def parse_joints(urdf_xml: str) -> list[JointModel]:
    """
    Return the joints of a URDF in document order.

    Only the <robot>'s own <joint> children count (a <transmission>'s <joint>
    is a reference, not a joint).  The axis is read only for joint types that
    have one (not fixed or floating), as urdfdom does, and normalised, as KDL
    (robot_state_publisher) does; PyBullet does not normalise a prismatic axis,
    so there a non-unit one moves the link |axis| times further.
    Malformed XML, numbers or links raise ValueError naming the joint.
    """
    try:
        robot = ElementTree.fromstring(urdf_xml)
    except ElementTree.ParseError as error:
        raise ValueError(f'URDF is not well-formed XML: {error}') from None
    joints = []
    for element in robot.findall('joint'):
        name = element.get('name')
        if not name:
            raise ValueError('URDF has a <joint> without a name')
        where = f'URDF joint {name!r}'
        joint_type = element.get('type')
        if not joint_type:
            raise ValueError(f'{where}: missing type')
        origin = element.find('origin')
        xyz_m = _parse_triple(origin, 'xyz', (0.0, 0.0, 0.0), where + ' <origin>')
        rpy_rad = _parse_triple(origin, 'rpy', (0.0, 0.0, 0.0), where + ' <origin>')
        axis = _DEFAULT_AXIS
        if joint_type not in ('fixed', 'floating'):
            raw_axis = _parse_triple(element.find('axis'), 'xyz', _DEFAULT_AXIS, where + ' <axis>')
            axis = _unit_vector(raw_axis, where + ' <axis xyz>')
        joints.append(JointModel(
            name=name, type=joint_type,
            parent_link=_required_link(element, 'parent', where),
            child_link=_required_link(element, 'child', where),
            origin=Transform(xyz_m, quaternion_from_rpy(*rpy_rad)),
            axis=axis))
    return joints


def root_link(joints: Sequence[JointModel]) -> str:
    """
    Return the one link that is no joint's child, checking that the joints form a tree.

    ValueError if there are no joints, two joints share a name or a child
    link, or the links do not hang from a single root.
    """
    if not joints:
        raise ValueError('no joints: the root link cannot be found from joints alone')
    children = {}
    names = set()
    for joint in joints:
        if joint.name in names:
            raise ValueError(f'two joints are named {joint.name!r}')
        names.add(joint.name)
        if joint.child_link in children:
            raise ValueError(f'link {joint.child_link!r} is the child of two joints: '
                             f'{children[joint.child_link]!r} and {joint.name!r}')
        children[joint.child_link] = joint.name
    roots = sorted({j.parent_link for j in joints} - children.keys())
    if len(roots) != 1:
        raise ValueError(f'the joints must hang from one root link, found roots {roots!r}')
    # With one parent per link, a link not reachable from the root sits on a cycle.
    reached = set(roots)
    frontier = list(roots)
    while frontier:
        parent = frontier.pop()
        for joint in joints:
            if joint.parent_link == parent and joint.child_link not in reached:
                reached.add(joint.child_link)
                frontier.append(joint.child_link)
    unreached = sorted(children.keys() - reached)
    if unreached:
        raise ValueError(f'links {unreached!r} are on a cycle, not below {roots[0]!r}')
    return roots[0]


def joint_transform(joint: JointModel, position: float) -> Transform:
    """
    Return the child link's pose in the parent link at ``position``: origin * motion.

    The motion is a rotation of ``position`` rad about the axis (revolute,
    continuous) or a translation of ``position`` m along it (prismatic).  Other
    types, planar and floating included, give the origin: their state is not
    one number.
    """
    if joint.type in _ROTATING:
        motion = Transform((0.0, 0.0, 0.0), quaternion_from_axis_angle(joint.axis, position))
    elif joint.type == 'prismatic':
        motion = Transform(tuple(position * a for a in joint.axis), (0.0, 0.0, 0.0, 1.0))
    else:
        return joint.origin
    return compose(joint.origin, motion)


# Builds a NamedTuple without its Python-level __new__: 160 ns instead of 280 ns per
# object, which made moving() 25 % faster for R2D2.
_tuple_new = tuple.__new__


class LinkTransforms:
    """
    Parent -> child link transforms of a URDF, split as TF publishes them.

    ``moving(positions)`` gives one ``JointTransform`` per name of
    ``moving_joint_names``, in that order, for positions in the same order;
    ``fixed()`` gives every other joint, once, for /tf_static.  Together they
    cover each joint exactly once.  Planar and floating joints (and a fixed
    joint listed as moving) stay at their origin, whatever their position.
    By default the moving joints are the revolute, continuous and prismatic
    ones in URDF order.
    """

    def __init__(self, urdf_xml: str, moving_joint_names: Optional[Sequence[str]] = None):
        """Parse the URDF and fold each joint's constants; ValueError if anything is invalid."""
        joints = parse_joints(urdf_xml)
        by_name = {joint.name: joint for joint in joints}
        # None only for a URDF without joints (a single link, whose name we do not read).
        self.root_link: Optional[str] = root_link(joints) if joints else None
        if moving_joint_names is None:
            moving_joint_names = [j.name for j in joints if j.type in _MOVING]
        self.moving_joint_names: tuple[str, ...] = tuple(moving_joint_names)
        unknown = [name for name in self.moving_joint_names if name not in by_name]
        if unknown:
            raise ValueError(f'moving joints {unknown!r} are not in the URDF '
                             f'(its joints: {sorted(by_name)!r})')
        listed = set(self.moving_joint_names)
        if len(listed) != len(self.moving_joint_names):
            raise ValueError(f'moving joint names repeat: {list(self.moving_joint_names)!r}')
        self._moving = [self._fold(by_name[name]) for name in self.moving_joint_names]
        self._fixed = [JointTransform(j.parent_link, j.child_link, j.origin)
                       for j in joints if j.name not in listed]
        # Child links, each after its parent, so that link_poses composes in one pass.
        self._tree_order: list[str] = []
        by_parent: dict[str, list[str]] = {}
        for joint in joints:
            by_parent.setdefault(joint.parent_link, []).append(joint.child_link)
        frontier = [self.root_link] if joints else []
        while frontier:
            children = by_parent.get(frontier.pop(), [])
            self._tree_order.extend(children)
            frontier.extend(children)

    @staticmethod
    def _fold(joint: JointModel) -> tuple:
        """Fold a joint's origin and axis into the few numbers ``moving`` needs per call."""
        translation, rotation = joint.origin
        if joint.type in _ROTATING:
            # origin.q * (axis sin(p/2), cos(p/2))
            #     = cos(p/2) origin.q + sin(p/2) (origin.q * (axis, 0))
            return (_REVOLUTE, joint.parent_link, joint.child_link, translation, rotation,
                    quaternion_multiply(rotation, joint.axis + (0.0,)))
        if joint.type == 'prismatic':
            # origin.t + p (origin.q applied to axis); the rotation stays origin.q.
            return (_PRISMATIC, joint.parent_link, joint.child_link, translation, rotation,
                    rotate(rotation, joint.axis))
        return (_CONSTANT, joint.parent_link, joint.child_link, translation, rotation, None)

    def moving(self, positions: Sequence[float]) -> list[JointTransform]:
        """Return the moving joints' transforms for positions (rad or m) in the names' order."""
        if len(positions) != len(self._moving):
            raise ValueError(f'expected {len(self._moving)} joint positions '
                             f'{list(self.moving_joint_names)!r}, got {len(positions)}')
        result = []
        append = result.append
        sin, cos = math.sin, math.cos
        for (kind, parent, child, translation, rotation, extra), position in zip(
                self._moving, positions):
            if kind == _REVOLUTE:
                s, c = sin(0.5 * position), cos(0.5 * position)
                qx, qy, qz, qw = rotation
                px, py, pz, pw = extra
                transform = _tuple_new(Transform, (translation, (
                    c * qx + s * px, c * qy + s * py, c * qz + s * pz, c * qw + s * pw)))
            elif kind == _PRISMATIC:
                tx, ty, tz = translation
                dx, dy, dz = extra
                transform = _tuple_new(Transform, (
                    (tx + position * dx, ty + position * dy, tz + position * dz), rotation))
            else:
                transform = _tuple_new(Transform, (translation, rotation))
            append(_tuple_new(JointTransform, (parent, child, transform)))
        return result

    def fixed(self) -> list[JointTransform]:
        """Return the transforms of the joints not listed as moving (for /tf_static)."""
        return list(self._fixed)

    def link_poses(self, positions: Sequence[float]) -> dict[str, Transform]:
        """Return every link's pose in the root link's frame, the root's being IDENTITY."""
        edges = {edge.child_link: edge for edge in self.moving(positions)}
        edges.update((edge.child_link, edge) for edge in self._fixed)
        poses = {self.root_link: IDENTITY} if self.root_link is not None else {}
        for child in self._tree_order:
            edge = edges[child]
            poses[child] = compose(poses[edge.parent_link], edge.transform)
        return poses
