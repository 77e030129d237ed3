"""
Coplanar triangles merged: a finely tessellated flat face becomes a few, the same surface.

No ROS, no PyBullet; numpy only. Exported walls and floors come tessellated
far beyond their shape (bench/sdf_world.py's warehouse walls: 73,728
triangles for six boxes), and Bullet's time to build a concave mesh grows
with its triangles (about 1 ms per thousand; a single PyBullet call, which
holds the interpreter, so nothing else of the simulator runs meanwhile). A
*facet* here is a connected set of triangles on one plane (normals and
offsets equal within :data:`PLANE_TOLERANCE`, every corner on the plane) of
one colour. A facet whose outline is one simple loop is triangulated again
from that loop's corners alone (ear clipping; the points along a straight
stretch are left out, where the neighbouring facet's triangles still end: a
T-junction, the same surface), and the new triangles cover exactly the
facet's area (checked, else the facet is kept as it was). Facets with holes,
and anything curved, are kept as they are.
"""

import math
from typing import Dict, List, Optional, Sequence, Tuple

import numpy

from r2d2_sim.sim.sdf.components import lowest_labels

__all__ = ['merge_coplanar', 'PLANE_TOLERANCE', 'MAX_CORNERS']

# Normals (unit) and plane offsets (m) within this are one plane; a corner
# farther than this from its facet's plane keeps the facet as it was.
PLANE_TOLERANCE = 1e-7
# An outline of more corners is kept as it was: ear clipping here is quadratic in
# them (a comb of 2,000 teeth took 7.8 s), and so jagged a face gains little.
MAX_CORNERS = 256
Point2 = Tuple[float, float]  # a corner in its facet's plane


def merge_coplanar(vertices: numpy.ndarray, faces: numpy.ndarray, groups: numpy.ndarray
                   ) -> Tuple[numpy.ndarray, numpy.ndarray]:
    """
    Return ``faces`` and their ``groups`` with each simple facet triangulated from its outline.

    ``vertices`` (V x 3), ``faces`` (F x 3 indices, counter-clockwise seen
    from outside) and ``groups`` (F, a colour each) as the mesh cache keeps
    them, vertices merged. The vertices are not changed (some may be left
    unused); the faces kept come first, in their order, then the new ones.
    """
    vertices = numpy.asarray(vertices, dtype=numpy.float64)
    faces = numpy.asarray(faces, dtype=numpy.int64)
    groups = numpy.asarray(groups)
    if len(faces) < 4:
        return faces, groups
    corners = vertices[faces]
    normals = numpy.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    doubled_areas = numpy.linalg.norm(normals, axis=1)
    usable = doubled_areas > 0.0
    normals[usable] /= doubled_areas[usable, None]
    offsets = numpy.einsum('ij,ij->i', normals, corners[:, 0])
    labels = _facets(faces, normals, offsets, groups, usable)
    order = numpy.argsort(labels, kind='stable')
    bounds = numpy.flatnonzero(numpy.diff(labels[order])) + 1
    starts = numpy.concatenate([[0], bounds])
    ends = numpy.concatenate([bounds, [len(order)]])
    kept = numpy.ones(len(faces), dtype=bool)
    new_faces: List[Tuple[int, int, int]] = []
    new_groups: List[int] = []
    # Only facets of three triangles or more can come out smaller (a terrain has none).
    large = ends - starts >= 3
    for start, end in zip(starts[large].tolist(), ends[large].tolist()):
        members = order[start:end]
        if not usable[members[0]]:
            continue
        triangles = _retriangulated(vertices, faces[members], normals[members[0]],
                                    offsets[members[0]], doubled_areas[members].sum())
        if triangles is not None and len(triangles) < len(members):
            kept[members] = False
            new_faces.extend(triangles)
            new_groups.extend([int(groups[members[0]])] * len(triangles))
    if not new_faces:
        return faces, groups
    return (numpy.concatenate([faces[kept], numpy.asarray(new_faces, dtype=numpy.int64)]),
            numpy.concatenate([groups[kept], numpy.asarray(new_groups, dtype=groups.dtype)]))


def _facets(faces: numpy.ndarray, normals: numpy.ndarray, offsets: numpy.ndarray,
            groups: numpy.ndarray, usable: numpy.ndarray) -> numpy.ndarray:
    """Label each face with its facet: the lowest face index of its connected coplanar set."""
    count = len(faces)
    edges = numpy.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    owners = numpy.repeat(numpy.arange(count), 3)
    order = numpy.lexsort((edges[:, 1], edges[:, 0]))
    edges, owners = edges[order], owners[order]
    same = numpy.all(edges[1:] == edges[:-1], axis=1)
    first, second = owners[:-1][same], owners[1:][same]
    joined = (usable[first] & usable[second] & (groups[first] == groups[second])
              & (numpy.abs(offsets[first] - offsets[second]) <= PLANE_TOLERANCE)
              & numpy.all(numpy.abs(normals[first] - normals[second]) <= PLANE_TOLERANCE,
                          axis=1))
    return lowest_labels(count, first[joined], second[joined])


def _retriangulated(vertices: numpy.ndarray, faces: numpy.ndarray, normal: numpy.ndarray,
                    offset: float, doubled_area: float) -> Optional[List[Tuple[int, int, int]]]:
    """Return a facet's triangles from its outline; None unless it is one simple loop."""
    used = numpy.unique(faces)
    if numpy.abs(vertices[used] @ normal - offset).max() > PLANE_TOLERANCE:
        return None
    loop = _outline(faces)
    if loop is None:
        return None
    # Coordinates in the plane, counter-clockwise seen along the normal.
    u = numpy.cross(normal, (1.0, 0.0, 0.0) if abs(normal[0]) < 0.9 else (0.0, 1.0, 0.0))
    u /= numpy.linalg.norm(u)
    v = numpy.cross(normal, u)
    points = vertices[loop] - vertices[loop[0]]  # small numbers: exact turns stay exact
    flat = [(float(p @ u), float(p @ v)) for p in points]
    triangles = _ear_clipped(flat)
    if triangles is None:
        return None
    area = sum(_cross(flat[a], flat[b], flat[c]) for a, b, c in triangles)
    if abs(area - doubled_area) > 1e-9 * max(1.0, doubled_area):
        return None
    return [(int(loop[a]), int(loop[b]), int(loop[c])) for a, b, c in triangles]


def _outline(faces: numpy.ndarray) -> Optional[List[int]]:
    """Return the facet's boundary as one loop of vertices in the faces' winding; else None."""
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    base = int(directed.max()) + 1
    codes = directed[:, 0] * base + directed[:, 1]
    if len(numpy.unique(codes)) != len(codes):
        return None  # an edge twice the same way: not a surface
    outer = directed[~numpy.isin(directed[:, 1] * base + directed[:, 0], codes)]
    if len(outer) < 3 or len(numpy.unique(outer[:, 0])) != len(outer):
        return None  # the outline touches itself
    following: Dict[int, int] = dict(zip(outer[:, 0].tolist(), outer[:, 1].tolist()))
    start = min(following)
    loop = [start]
    while True:
        nxt = following.get(loop[-1])
        if nxt is None:
            return None
        if nxt == start:
            break
        loop.append(nxt)
        if len(loop) > len(following):
            return None
    return loop if len(loop) == len(following) else None  # else holes or islands


def _cross(o: Sequence[float], a: Sequence[float], b: Sequence[float]) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def _inside(p: Point2, a: Point2, b: Point2, c: Point2, eps: float = 0.0) -> bool:
    """
    Return True when ``p`` lies in the triangle abc (counter-clockwise), edges included.

    ``eps`` (a cross product: length squared) widens the edges: a point that
    rounding put just outside one still counts.
    """
    return _cross(a, b, p) >= -eps and _cross(b, c, p) >= -eps and _cross(c, a, p) >= -eps


def _corners(points: List[Tuple[float, float]]) -> List[int]:
    """Return the indices of the outline's corners: the points where it turns, in order."""
    ring = list(range(len(points)))
    changed = True
    while changed and len(ring) > 3:
        changed = False
        for k in range(len(ring) - 1, -1, -1):
            o, a, b = (points[ring[k - 1]], points[ring[k]], points[ring[(k + 1) % len(ring)]])
            first = math.hypot(a[0] - o[0], a[1] - o[1])
            second = math.hypot(b[0] - a[0], b[1] - a[1])
            if abs(_cross(o, a, b)) <= 1e-9 * first * second and _ahead(o, a, b):
                del ring[k]
                changed = True
                if len(ring) <= 3:
                    break
    return ring


def _ahead(o: Point2, a: Point2, b: Point2) -> bool:
    """Return True when ``b`` goes on from ``a`` the way ``a`` came from ``o`` (no turn back)."""
    return (a[0] - o[0]) * (b[0] - a[0]) + (a[1] - o[1]) * (b[1] - a[1]) > 0.0


def _ear_clipped(points: List[Tuple[float, float]]) -> Optional[List[Tuple[int, int, int]]]:
    """
    Return a counter-clockwise simple polygon cut into triangles (by index); None if it cannot be.

    The points along a straight stretch of the outline are left out (the
    neighbouring facets still end there: the same surface, a T-junction);
    then ear clipping: a convex corner whose triangle holds no corner that
    turns the other way (a reflex one) is cut off, until three remain.
    """
    ring = _corners(points)
    if not 3 <= len(ring) <= MAX_CORNERS:
        return None
    triangles: List[Tuple[int, int, int]] = []
    # A turn within this of straight is no corner to cut, and may be in the way of one.
    span = max(max(abs(x), abs(y)) for x, y in points) or 1.0
    eps = 1e-9 * span * span

    def turn(k: int) -> float:
        return _cross(points[ring[k - 1]], points[ring[k]], points[ring[(k + 1) % len(ring)]])
    reflex = {ring[k] for k in range(len(ring)) if turn(k) <= eps}  # not clearly convex
    k = 0
    misses = 0
    while len(ring) > 3:
        m = len(ring)
        k %= m
        a, b, c = ring[k - 1], ring[k], ring[(k + 1) % m]
        ear = turn(k) > eps and not any(
            _inside(points[r], points[a], points[b], points[c], eps)
            for r in reflex if r not in (a, b, c))
        if not ear:
            k += 1
            misses += 1
            if misses > m:
                return None  # no ear: the outline is not simple
            continue
        triangles.append((a, b, c))
        del ring[k]
        misses = 0
        m -= 1
        for j in (k - 1, k % m):  # the neighbours may have stopped turning the other way
            if ring[j] in reflex and turn(j) > eps:
                reflex.discard(ring[j])
        k = max(k - 1, 0)
    if _cross(*(points[i] for i in ring)) <= eps:
        return None
    triangles.append((ring[0], ring[1], ring[2]))
    return triangles
