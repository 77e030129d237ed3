"""
What PyBullet returns, named once: the one place that knows its tuple layouts.

No ROS here. PyBullet answers with positional tuples (``getJointInfo``'s 17
fields, ``getLinkState``'s 8, ``getDynamicsInfo``'s 12...). Each is turned
into a named record here, by a reader that takes the client, the body id and
the link, so nothing else in the package indexes ``[4]`` or ``[12]``.
"""

import operator
from dataclasses import dataclass
from typing import List, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.physics.stdio import silenced_output

with silenced_output():  # PyBullet prints its build time on import
    import pybullet
from pybullet_utils.bullet_client import BulletClient  # noqa: I100 (after the quiet import)

__all__ = ['Vec3', 'Quat', 'JOINT_TYPE_NAMES', 'GEOMETRY_KINDS', 'JointRecord', 'JointStates',
           'Pose', 'LinkState', 'Aabb', 'Dynamics', 'CollisionShape', 'joint_records',
           'link_state', 'aabb', 'dynamics', 'collision_shapes', 'mesh_vertices', 'BodyInfo',
           'body_info', 'ContactPoint', 'contact_records', 'ClosestPoints', 'nearest_points']

Vec3 = Tuple[float, float, float]
Quat = Tuple[float, float, float, float]

GEOMETRY_CYLINDER = pybullet.GEOM_CYLINDER
GEOMETRY_SPHERE = pybullet.GEOM_SPHERE
# A collision shape's kind, as a word: what r2d2_sim.sim.bounds builds shapes from.
GEOMETRY_KINDS = {
    pybullet.GEOM_SPHERE: 'sphere',
    pybullet.GEOM_BOX: 'box',
    pybullet.GEOM_CYLINDER: 'cylinder',
    pybullet.GEOM_MESH: 'mesh',
    pybullet.GEOM_PLANE: 'plane',
    pybullet.GEOM_CAPSULE: 'capsule',
}
JOINT_TYPE_NAMES = {
    pybullet.JOINT_REVOLUTE: 'revolute',
    pybullet.JOINT_PRISMATIC: 'prismatic',
    pybullet.JOINT_SPHERICAL: 'spherical',
    pybullet.JOINT_PLANAR: 'planar',
    pybullet.JOINT_FIXED: 'fixed',
    pybullet.JOINT_POINT2POINT: 'point2point',
    pybullet.JOINT_GEAR: 'gear',
}


@dataclass(frozen=True)
class JointRecord:
    """The 17 attributes PyBullet's ``getJointInfo`` reports for a joint."""

    index: int
    name: str
    type_code: int
    q_index: int
    u_index: int
    flags: int
    damping: float
    friction: float
    lower_limit: float
    upper_limit: float
    max_force: float
    max_velocity: float
    link_name: str
    axis: Vec3
    parent_frame_position: Vec3
    parent_frame_orientation: Quat
    parent_index: int

    @classmethod
    def from_info(cls, info: Sequence) -> 'JointRecord':
        """Build a record from the tuple ``getJointInfo`` returns."""
        (index, name, type_code, q_index, u_index, flags, damping, friction,
         lower, upper, max_force, max_velocity, link_name, axis, parent_pos,
         parent_orn, parent_index) = info
        return cls(
            index=index, name=name.decode('utf-8'), type_code=type_code,
            q_index=q_index, u_index=u_index, flags=flags, damping=damping,
            friction=friction, lower_limit=lower, upper_limit=upper,
            max_force=max_force, max_velocity=max_velocity,
            link_name=link_name.decode('utf-8'), axis=tuple(axis),
            parent_frame_position=tuple(parent_pos),
            parent_frame_orientation=tuple(parent_orn),
            parent_index=parent_index)

    @property
    def type_name(self) -> str:
        """Return the joint type as a word (``revolute``, ``fixed``, ...)."""
        return JOINT_TYPE_NAMES.get(self.type_code, 'unknown')

    @property
    def movable(self) -> bool:
        """Return True for joints with one degree of freedom (not fixed)."""
        return self.type_code in (pybullet.JOINT_REVOLUTE, pybullet.JOINT_PRISMATIC)


class JointStates(NamedTuple):
    """Positions, velocities and applied efforts of a list of joints (read every step)."""

    positions: Sequence[float]
    velocities: Sequence[float]
    efforts: Sequence[float]


class Pose(NamedTuple):
    """A position and an (x, y, z, w) orientation in the world."""

    position: Vec3
    orientation: Quat


class LinkState(NamedTuple):
    """``getLinkState``: the link's centre of mass and its URDF link frame, in the world."""

    com_position: Vec3
    com_orientation: Quat
    frame_position: Vec3
    frame_orientation: Quat


class Aabb(NamedTuple):
    """A world-axis-aligned bounding box: lowest and highest corner."""

    low: Vec3
    high: Vec3


class Dynamics(NamedTuple):
    """``getDynamicsInfo``: mass, lateral friction and the inertial frame in the link frame."""

    mass_kg: float
    lateral_friction: float
    inertial_position: Vec3
    inertial_orientation: Quat


class CollisionShape(NamedTuple):
    """
    One collision shape of a link: PyBullet's geometry type, its dimensions, where it sits.

    ``dimensions`` are a box's full sizes, a sphere's radius first, a
    cylinder's or capsule's length then radius, a mesh's scale. The local
    frame is relative to the link's centre of mass (its inertial frame), not
    to its URDF link frame: measured, a box at xyz 0 0.2 0 of a link whose
    inertial origin is 0.1 0 0 reports about (-0.1, 0.2, 0).
    """

    geometry: int
    dimensions: Vec3
    local_position: Vec3 = (0.0, 0.0, 0.0)
    local_orientation: Quat = (0.0, 0.0, 0.0, 1.0)

    @property
    def kind(self) -> str:
        """Return the geometry as a word: box, sphere, cylinder, capsule, mesh, plane, other."""
        return GEOMETRY_KINDS.get(self.geometry, 'other')


class BodyInfo(NamedTuple):
    """``getBodyInfo``: the base link's name and the URDF's ``<robot name>``."""

    base_link_name: str
    name: str


class ContactPoint(NamedTuple):
    """Where two bodies touch: the links, the point on A (world), and the normal force (N)."""

    body_a: int
    body_b: int
    link_a: int
    link_b: int
    position_on_a: Vec3
    normal_force_n: float


class ClosestPoints(NamedTuple):
    """The nearest points of two bodies within a range: their links and the distance (m)."""

    link_a: int
    link_b: int
    position_on_a: Vec3
    position_on_b: Vec3
    distance_m: float     # negative: they overlap by that much


def joint_records(client: BulletClient, body_id: int) -> List[JointRecord]:
    """Return every joint of a body, in index order."""
    return [JointRecord.from_info(client.getJointInfo(body_id, index))
            for index in range(client.getNumJoints(body_id))]


def link_state(client: BulletClient, body_id: int, link: int) -> LinkState:
    """Return a link's world centre of mass and frame, its forward kinematics computed now."""
    state = client.getLinkState(body_id, link, computeForwardKinematics=True)
    return LinkState(tuple(state[0]), tuple(state[1]), tuple(state[4]), tuple(state[5]))


def aabb(client: BulletClient, body_id: int, link: int) -> Aabb:
    """Return the world bounding box of a link (-1: the base)."""
    low, high = client.getAABB(body_id, link)
    return Aabb(tuple(low), tuple(high))


def dynamics(client: BulletClient, body_id: int, link: int) -> Dynamics:
    """Return a link's mass, lateral friction and inertial frame (-1: the base)."""
    info = client.getDynamicsInfo(body_id, link)
    return Dynamics(info[0], info[1], tuple(info[3]), tuple(info[4]))


def collision_shapes(client: BulletClient, body_id: int, link: int) -> List[CollisionShape]:
    """Return a link's collision shapes, each in its link's inertial frame."""
    return [CollisionShape(shape[2], tuple(shape[3]), tuple(shape[5]), tuple(shape[6]))
            for shape in client.getCollisionShapeData(body_id, link)]


def mesh_vertices(client: BulletClient, body_id: int, link: int, shape_index: int) -> List[Vec3]:
    """
    Return the vertices of a link's collision mesh, in the link's inertial frame, scaled.

    ``getMeshData`` gives them with the shape's local frame already applied
    (measured against the link's bounding box); empty when PyBullet has none.
    """
    try:
        count, vertices = client.getMeshData(body_id, link, collisionShapeIndex=shape_index)
    except client.error:
        return []
    return [tuple(v) for v in vertices[:count]]


def body_info(client: BulletClient, body_id: int) -> BodyInfo:
    """Return the names of a body's base link and of the body, as its URDF gives them."""
    base, name = client.getBodyInfo(body_id)[:2]
    return BodyInfo(base.decode('utf-8'), name.decode('utf-8'))


def contact_records(points: Sequence, ignoring: Sequence[int] = ()) -> List[ContactPoint]:
    """
    Name what ``getContactPoints`` returned that touches; those with ``ignoring`` are dropped.

    Dropped before they are made records: a robot's wheels touch the ground at every step.
    Only points at a distance <= 0 touch: Bullet keeps a manifold's points while the
    shapes are within its contact margin, so it also returns points of bodies still
    apart (up to about a centimetre, with no normal force), which touch nothing.
    """
    return [ContactPoint(p[1], p[2], p[3], p[4], tuple(p[5]), p[9]) for p in points
            if p[8] <= 0.0 and p[2] not in ignoring]


_DISTANCE = operator.itemgetter(8)  # a closest point's distance


def nearest_points(points: Sequence) -> Optional[ClosestPoints]:
    """Return the nearest of what ``getClosestPoints`` returned; None if it returned none."""
    if not points:
        return None
    nearest = min(points, key=_DISTANCE)
    return ClosestPoints(nearest[3], nearest[4], tuple(nearest[5]), tuple(nearest[6]),
                         nearest[8])
