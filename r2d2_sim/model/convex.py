"""
Convex shapes and how far apart they are: GJK on support functions, numpy at most.

Pure math, free of ROS and PyBullet. A convex shape is known here only by
its support function: the point of the shape farthest along a direction.
That is enough for the Gilbert-Johnson-Keerthi distance algorithm
(:func:`distance`), which works on the Minkowski difference of two shapes
and never builds a hull: the hull of a point set (a box's eight corners, a
mesh's vertices, a region a client gave as points), a ball, a capsule and a
cylinder are all exact, and a shape swept by a ball (a capsule is a segment
swept) is the same shape with a radius. Two shapes overlap when their
distance is 0 (touching counts). :func:`extent` gives a shape's extent
along an axis: a bounding box in any frame, exactly.

The simulation standard's bounds filters (a box, a convex hull, a sphere)
and its entity bounds are computed with these; the entities' shapes come
from their collision geometry (:mod:`r2d2_sim.sim.bounds`).
"""

import math
from typing import List, Sequence, Tuple

import numpy
from numpy.typing import ArrayLike

__all__ = ['Convex', 'Points', 'Ball', 'Capsule', 'Cylinder', 'distance', 'overlap',
           'extent', 'box_corners', 'collinear', 'DISTANCE_TOLERANCE_M']

Vec3 = Tuple[float, float, float]

# Two shapes closer than this (m) touch: floating point makes exact contact fuzzy.
DISTANCE_TOLERANCE_M = 1e-9
# GJK stops when a step gets the distance no closer than this fraction of it.
_RELATIVE_TOLERANCE = 1e-12
_MAX_ITERATIONS = 100


def _dot(a: Sequence[float], b: Sequence[float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _sub(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _add(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def _scale(a: Sequence[float], s: float) -> Vec3:
    return (a[0] * s, a[1] * s, a[2] * s)


def _cross(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _unit(d: Sequence[float]) -> Vec3:
    norm = math.sqrt(_dot(d, d))
    if norm == 0.0:
        return (1.0, 0.0, 0.0)  # any direction: a ball's support is any point of its surface
    return (d[0] / norm, d[1] / norm, d[2] / norm)


class Convex:
    """A convex shape, by its support function: its point farthest along ``direction``."""

    def support(self, direction: Vec3) -> Vec3:
        """Return the shape's point farthest along ``direction`` (any one of them, if several)."""
        raise NotImplementedError


class Points(Convex):
    """The convex hull of points (N x 3, N >= 1): a box's corners, a mesh, a client's region."""

    def __init__(self, points: ArrayLike) -> None:
        self.points = numpy.asarray(points, dtype=float).reshape(-1, 3)
        if len(self.points) == 0:
            raise ValueError('a convex hull needs at least one point')

    def support(self, direction: Vec3) -> Vec3:
        """Return the point with the largest projection on ``direction``."""
        index = int(numpy.argmax(self.points @ numpy.asarray(direction)))
        return tuple(self.points[index].tolist())


class Ball(Convex):
    """A ball: ``centre`` (m) and ``radius_m`` >= 0."""

    def __init__(self, centre: Sequence[float], radius_m: float) -> None:
        self.centre = tuple(float(c) for c in centre)
        self.radius_m = float(radius_m)

    def support(self, direction: Vec3) -> Vec3:
        """Return the centre moved by the radius along ``direction``."""
        return _add(self.centre, _scale(_unit(direction), self.radius_m))


class Capsule(Convex):
    """The segment from ``a`` to ``b`` swept by a ball of ``radius_m``."""

    def __init__(self, a: Sequence[float], b: Sequence[float], radius_m: float) -> None:
        self.a, self.b = tuple(map(float, a)), tuple(map(float, b))
        self.radius_m = float(radius_m)

    def support(self, direction: Vec3) -> Vec3:
        """Return the farther end moved by the radius along ``direction``."""
        end = self.a if _dot(self.a, direction) >= _dot(self.b, direction) else self.b
        return _add(end, _scale(_unit(direction), self.radius_m))


class Cylinder(Convex):
    """A solid cylinder: ``centre``, unit ``axis``, ``half_length_m`` along it, ``radius_m``."""

    def __init__(self, centre: Sequence[float], axis: Sequence[float], half_length_m: float,
                 radius_m: float) -> None:
        self.centre = tuple(map(float, centre))
        self.axis = _unit(axis)
        self.half_length_m = float(half_length_m)
        self.radius_m = float(radius_m)

    def support(self, direction: Vec3) -> Vec3:
        """Return the rim point (or a cap's centre, straight along the axis) farthest along it."""
        along = _dot(direction, self.axis)
        cap = _add(self.centre, _scale(self.axis, math.copysign(self.half_length_m, along)))
        radial = _sub(direction, _scale(self.axis, along))
        if _dot(radial, radial) <= 1e-30:
            return cap
        return _add(cap, _scale(_unit(radial), self.radius_m))


def box_corners(low: Sequence[float], high: Sequence[float]) -> List[Vec3]:
    """Return the eight corners of the axis-aligned box from ``low`` to ``high``."""
    return [(x, y, z) for x in (low[0], high[0]) for y in (low[1], high[1])
            for z in (low[2], high[2])]


def collinear(points: Sequence[Sequence[float]], tolerance_m: float = 1e-9) -> bool:
    """Return True when the points lie on one line (or in one point): they span no area."""
    array = numpy.asarray(points, dtype=float).reshape(-1, 3)
    if len(array) < 3:
        return True
    spread = array - array[0]
    far = spread[int(numpy.argmax(numpy.einsum('ij,ij->i', spread, spread)))]
    length = float(numpy.linalg.norm(far))
    if length <= tolerance_m:
        return True
    off_line = numpy.linalg.norm(numpy.cross(spread, far / length), axis=1)
    return float(off_line.max()) <= tolerance_m


def extent(shape: Convex, axis: Sequence[float]) -> Tuple[float, float]:
    """Return the lowest and highest projection of ``shape`` on the unit ``axis``."""
    x, y, z = axis
    return _dot(shape.support((-x, -y, -z)), axis), _dot(shape.support((x, y, z)), axis)


# -- the closest point of a simplex to the origin (Ericson, Real-Time Collision Detection 5.1)

def _closest_on_segment(a: Vec3, b: Vec3) -> Tuple[Vec3, List[Vec3]]:
    ab = _sub(b, a)
    length2 = _dot(ab, ab)
    if length2 <= 0.0:
        return a, [a]
    t = -_dot(a, ab) / length2
    if t <= 0.0:
        return a, [a]
    if t >= 1.0:
        return b, [b]
    return _add(a, _scale(ab, t)), [a, b]


def _closest_on_triangle(a: Vec3, b: Vec3, c: Vec3) -> Tuple[Vec3, List[Vec3]]:
    ab, ac = _sub(b, a), _sub(c, a)
    ap = _scale(a, -1.0)
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        return a, [a]
    bp = _scale(b, -1.0)
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return b, [b]
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0 and d1 - d3 > 0.0:
        return _add(a, _scale(ab, d1 / (d1 - d3))), [a, b]
    cp = _scale(c, -1.0)
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return c, [c]
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0 and d2 - d6 > 0.0:
        return _add(a, _scale(ac, d2 / (d2 - d6))), [a, c]
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0 and (d4 - d3) + (d5 - d6) > 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return _add(b, _scale(_sub(c, b), w)), [b, c]
    denominator = va + vb + vc
    if denominator <= 0.0:  # a degenerate (flat) triangle: its closest edge
        return min((_closest_on_segment(p, q) for p, q in ((a, b), (b, c), (a, c))),
                   key=lambda found: _dot(found[0], found[0]))
    v, w = vb / denominator, vc / denominator
    return _add(a, _add(_scale(ab, v), _scale(ac, w))), [a, b, c]


def _closest_on_tetrahedron(points: List[Vec3]) -> Tuple[Vec3, List[Vec3]]:
    best = None
    for i in range(4):
        face = [points[j] for j in range(4) if j != i]
        normal = _cross(_sub(face[1], face[0]), _sub(face[2], face[0]))
        side_origin = -_dot(normal, face[0])
        side_opposite = _dot(normal, _sub(points[i], face[0]))
        # The origin is outside this face when it lies across the face's plane from the
        # fourth vertex; a flat tetrahedron (no side at all) has every face looked at.
        if side_origin * side_opposite < 0.0 or side_opposite == 0.0:
            found = _closest_on_triangle(*face)
            if best is None or _dot(found[0], found[0]) < _dot(best[0], best[0]):
                best = found
    if best is None:  # inside every face: the origin is in the tetrahedron
        return (0.0, 0.0, 0.0), points
    return best


def _closest(simplex: List[Vec3]) -> Tuple[Vec3, List[Vec3]]:
    if len(simplex) == 1:
        return simplex[0], simplex
    if len(simplex) == 2:
        return _closest_on_segment(*simplex)
    if len(simplex) == 3:
        return _closest_on_triangle(*simplex)
    return _closest_on_tetrahedron(simplex)


def distance(a: Convex, b: Convex) -> float:
    """
    Return how far apart (m) two convex shapes are: 0 when they touch or overlap.

    GJK: the point of the Minkowski difference a - b nearest the origin,
    approached through simplices of support points; exact for polytopes
    (within floating point), converging for curved shapes.
    """
    def support(direction: Vec3) -> Vec3:
        return _sub(a.support(direction), b.support(_scale(direction, -1.0)))

    v = support((1.0, 0.0, 0.0))
    simplex = [v]
    for _ in range(_MAX_ITERATIONS):
        vv = _dot(v, v)
        if vv <= DISTANCE_TOLERANCE_M ** 2:
            return 0.0
        w = support(_scale(v, -1.0))
        if vv - _dot(v, w) <= _RELATIVE_TOLERANCE * vv or w in simplex:
            return math.sqrt(vv)  # no support point gets closer: v is the nearest
        v, simplex = _closest(simplex + [w])
        if len(simplex) == 4:
            return 0.0  # the origin is inside a tetrahedron of a - b
    return math.sqrt(_dot(v, v))


def overlap(a: Convex, b: Convex, tolerance_m: float = DISTANCE_TOLERANCE_M) -> bool:
    """Return whether two convex shapes touch or overlap, within ``tolerance_m``."""
    return distance(a, b) <= tolerance_m
