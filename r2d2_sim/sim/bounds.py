"""
The standard's bounds: a region (box, convex hull, sphere) and an entity's collision shape.

No ROS here. A :class:`Region` is ``simulation_interfaces/Bounds`` as plain
data, checked by :func:`check_region`. An entity's shape is its collision
geometry, link by link, as exact convex shapes (:mod:`r2d2_sim.model.convex`):
boxes, spheres, cylinders and capsules as they are, a mesh as the convex hull
of its vertices, anything else (a plane, a height field) as its link's
bounding box. :func:`body_meets` tells whether a body's shape overlaps a
region (the bounds filter of GetEntities), :func:`body_box` gives the box
around its shape in its base link's frame (GetEntityBounds), :func:`link_box`
the box around one link in its own frame (the head camera's mount).
"""

import math
from typing import Iterable, List, NamedTuple, Optional, Sequence, Tuple, TYPE_CHECKING

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.convex import (
    Ball, box_corners, Capsule, collinear, Convex, Cylinder, extent, overlap, Points)
from r2d2_sim.model.transforms import apply, compose, IDENTITY, inverse, rotate, Transform

if TYPE_CHECKING:  # typing only
    from r2d2_sim.physics.body import Body

__all__ = ['Region', 'EMPTY', 'REGION_KINDS', 'MAX_HULL_POINTS', 'check_region',
           'region_shape', 'region_box', 'body_shapes', 'body_meets', 'body_box', 'link_box']

Vec3 = Tuple[float, float, float]

# simulation_interfaces/Bounds' types, by their number: TYPE_EMPTY ... TYPE_SPHERE.
REGION_KINDS = ('empty', 'box', 'convex_hull', 'sphere')
# What a region a peer sends may hold.
MAX_HULL_POINTS = 1000
# A region further out than the blow-up bound (10 km) meets nothing anyway.
MAX_COORDINATE_M = 1.0e6


def _vec3(values: Iterable[float]) -> Vec3:
    """Return three numbers (a point, a corner) as a tuple of three floats."""
    x, y, z = values
    return float(x), float(y), float(z)


class Region(NamedTuple):
    """
    A region as the standard's Bounds gives it: ``kind`` and its ``points``.

    ``box``: two opposite corners (the standard lists the upper one first);
    ``convex_hull``: three or more points, not all on a line; ``sphere``: the
    centre, then a point whose x is the radius; ``empty``: no bounds at all.
    """

    kind: str = 'empty'
    points: Tuple[Vec3, ...] = ()

    @staticmethod
    def box(low: Sequence[float], high: Sequence[float]) -> 'Region':
        """Return the box between two corners, listed as the standard does: upper, then lower."""
        upper = _vec3(max(a, b) for a, b in zip(low, high))
        lower = _vec3(min(a, b) for a, b in zip(low, high))
        return Region('box', (upper, lower))

    @staticmethod
    def sphere(centre: Sequence[float], radius_m: float) -> 'Region':
        """Return the ball of ``radius_m`` around ``centre``."""
        return Region('sphere', (_vec3(centre), (float(radius_m), 0.0, 0.0)))


EMPTY = Region()


def check_region(region: Region, what: str = 'bounds', code: str = 'OPERATION_FAILED') -> Region:
    """
    Return ``region`` if it defines a volume as the standard says; RefusedError ``code`` if not.

    A box has two corners; a sphere a centre and a radius >= 0; a convex hull
    3 to MAX_HULL_POINTS points that are not all on one line; every number
    finite. An empty region's points are dropped.
    """
    if region.kind not in REGION_KINDS:
        raise RefusedError(code, f'{what}: unknown bounds type {region.kind!r}')
    if region.kind == 'empty':
        return EMPTY
    points = region.points
    if len(points) > MAX_HULL_POINTS:
        raise RefusedError(code, f'{what}: {len(points)} points, more than {MAX_HULL_POINTS}')
    if not all(len(p) == 3 and all(math.isfinite(v) and abs(v) <= MAX_COORDINATE_M for v in p)
               for p in points):
        raise RefusedError(code, f'{what}: every point needs three finite numbers within '
                                 f'{MAX_COORDINATE_M:g} m')
    points = tuple(_vec3(p) for p in points)
    if region.kind == 'box':
        if len(points) != 2:
            raise RefusedError(code, f'{what}: a box has two corner points, not {len(points)}')
        return Region.box(points[1], points[0])
    if region.kind == 'sphere':
        if len(points) != 2:
            raise RefusedError(code, f'{what}: a sphere has two points (the centre, then the '
                                     f'radius in x), not {len(points)}')
        if points[1][0] < 0.0:
            raise RefusedError(code, f'{what}: a sphere\'s radius is >= 0, not {points[1][0]}')
        return Region.sphere(points[0], points[1][0])
    if len(points) < 3 or collinear(points):
        raise RefusedError(code, f'{what}: a convex hull needs at least 3 points not on one '
                                 'line')
    return Region('convex_hull', points)


def region_shape(region: Region) -> Convex:
    """Return a checked, non-empty region as a convex shape."""
    if region.kind == 'sphere':
        return Ball(region.points[0], region.points[1][0])
    if region.kind == 'box':
        return Points(box_corners(region.points[1], region.points[0]))
    return Points(region.points)


def region_box(region: Region) -> Tuple[Vec3, Vec3]:
    """Return the axis-aligned box around a checked, non-empty region: (low, high)."""
    shape = region_shape(region)
    spans = [extent(shape, axis) for axis in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))]
    return _vec3(s[0] for s in spans), _vec3(s[1] for s in spans)


def _shape(kind: str, dimensions: Sequence[float], pose: Transform,
           vertices: Sequence[Vec3]) -> Optional[Convex]:
    """Return one collision shape, placed at ``pose``, as a convex shape (None: unknown)."""
    if kind == 'box':
        half = [d / 2.0 for d in dimensions[:3]]
        corners = box_corners([-h for h in half], half)
        return Points([apply(pose, corner) for corner in corners])
    if kind == 'sphere':
        return Ball(pose.translation, dimensions[0])
    if kind in ('cylinder', 'capsule'):
        length, radius = dimensions[0], dimensions[1]
        axis = rotate(pose.rotation, (0.0, 0.0, 1.0))
        if kind == 'cylinder':
            return Cylinder(pose.translation, axis, length / 2.0, radius)
        ends = [apply(pose, (0.0, 0.0, z)) for z in (-length / 2.0, length / 2.0)]
        return Capsule(ends[0], ends[1], radius)
    if kind == 'mesh' and vertices:
        return Points(vertices)
    return None


def _link_shapes(body: 'Body', link: int, inertial: Transform,
                 to_frame: Transform) -> List[Convex]:
    """
    Return a link's collision shapes in a frame.

    ``inertial`` is the link's inertial frame (where its shapes are given) in
    that frame, ``to_frame`` the world in it (for a shape known only by its box).
    """
    shapes = []
    for index, shape in enumerate(body.collision_shapes(link)):
        vertices: Sequence[Vec3] = ()
        if shape.kind == 'mesh':  # already in the inertial frame, local pose applied
            vertices = [apply(inertial, v) for v in body.mesh_vertices(link, index)]
        pose = compose(inertial, Transform(shape.local_position, shape.local_orientation))
        convex = _shape(shape.kind, shape.dimensions, pose, vertices)
        if convex is None:  # a plane, a height field: its link's box
            low, high = body.aabb(link)
            convex = Points([apply(to_frame, c) for c in box_corners(low, high)])
        shapes.append(convex)
    return shapes


def _box_around(shapes: Sequence[Convex]) -> Tuple[Vec3, Vec3]:
    """Return the box (low, high) around convex shapes, in their frame's axes."""
    spans = []
    for axis in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)):
        ends = [extent(convex, axis) for convex in shapes]
        spans.append((min(e[0] for e in ends), max(e[1] for e in ends)))
    return _vec3(s[0] for s in spans), _vec3(s[1] for s in spans)


def link_box(body: 'Body', link: int) -> Tuple[Vec3, Vec3]:
    """
    Return the box (low, high) around a link's collision shapes, in the link's own frame.

    The same however the body stands: PyBullet's ``getAABB`` is a box in the
    world's axes, which grows as the link turns (a 0.4 x 0.2 m box seen at
    45 degrees is 0.42 m square), so a mount sized by it moved with the
    spawn yaw. A link without collision shapes is a point at its origin.
    """
    dynamics = body.dynamics(link)  # the inertial frame in the link's, where its shapes are
    inertial = Transform(dynamics.inertial_position, dynamics.inertial_orientation)
    shapes = _link_shapes(body, link, inertial, inverse(Transform(*body.link_pose(link))))
    return _box_around(shapes or [Points([(0.0, 0.0, 0.0)])])


def body_shapes(body: 'Body', frame: Optional[Transform] = None) -> List[Tuple[int, Convex]]:
    """
    Return the body's collision shapes as (link, convex shape), in the world or in ``frame``.

    ``frame`` is a pose in the world (the base link's, for GetEntityBounds);
    shapes are then given relative to it. A body without collision shapes
    is a point at its base link's origin.
    """
    to_frame = IDENTITY if frame is None else inverse(frame)
    shapes: List[Tuple[int, Convex]] = []
    for link in body.links():
        inertial = compose(to_frame, Transform(*body.inertial_pose(link)))
        shapes += [(link, convex) for convex in _link_shapes(body, link, inertial, to_frame)]
    if not shapes:
        origin = apply(to_frame, body.link_pose(-1)[0])
        shapes.append((-1, Points([origin])))
    return shapes


def _boxes_meet(a: Tuple[Sequence[float], Sequence[float]],
                b: Tuple[Sequence[float], Sequence[float]]) -> bool:
    return all(a[0][k] <= b[1][k] and b[0][k] <= a[1][k] for k in range(3))


def body_meets(body: 'Body', region: Region) -> bool:
    """
    Return True when the body's collision shape touches or overlaps a checked region.

    Exact for the shapes above; links whose bounding box (PyBullet's, a
    little larger than the shape) misses the region's are not looked at.
    """
    if region.kind == 'empty':
        return True
    shape, box = region_shape(region), region_box(region)
    near = {link for link in body.links() if _boxes_meet(body.aabb(link), box)}
    if not near:
        return False
    return any(overlap(convex, shape) for link, convex in body_shapes(body) if link in near)


def body_box(body: 'Body') -> Tuple[Vec3, Vec3]:
    """
    Return the box (low, high) around the body's collision shape, in its base link's frame.

    The base link is the URDF's root link, the entity's canonical link
    (REP-103 axes); the box follows the joints as they are now.
    """
    frame = Transform(*body.link_pose(-1))
    return _box_around([convex for _, convex in body_shapes(body, frame)])
