"""
Regions on the ground a robot's run can reach: boxes, circles and convex polygons in x-y.

Pure math. A scenario's goal, a dock's tolerance, a spawn area, a named
pose's bounds seen from above: each is a :class:`Region` that says whether a
point (the robot's base) is inside.
"""

import math
from typing import Iterable, List, NamedTuple, Sequence, Tuple

__all__ = ['Region', 'box_region', 'circle_region', 'polygon_region', 'MIN_WIDTH_M']

# A polygon narrower than this (m) spans no area: seen from above, a flat box on its side.
MIN_WIDTH_M = 1e-9

Point = Tuple[float, float]  # x, y on the ground


class Region(NamedTuple):
    """
    A region on the ground, by ``kind``: its ``values`` in metres, world frame.

    'box': x_min, y_min, x_max, y_max; 'circle': x, y, r, 0; 'polygon': a
    convex polygon's corners x0, y0, x1, y1... counter-clockwise.
    """

    kind: str
    values: Sequence[float]

    def contains(self, x: float, y: float) -> bool:
        """Return True when (x, y) is inside, its edge included."""
        if self.kind == 'box':
            x_min, y_min, x_max, y_max = self.values
            return x_min <= x <= x_max and y_min <= y <= y_max
        if self.kind == 'polygon':
            corners = list(zip(self.values[0::2], self.values[1::2]))
            return all((bx - ax) * (y - ay) - (by - ay) * (x - ax) >= 0.0
                       for (ax, ay), (bx, by) in zip(corners, corners[1:] + corners[:1]))
        cx, cy, radius = self.values[:3]
        return math.hypot(x - cx, y - cy) <= radius


def box_region(x_min: float, y_min: float, x_max: float, y_max: float) -> Region:
    """Return the box between two corners (m, world frame); ValueError if it is empty."""
    values = tuple(float(v) for v in (x_min, y_min, x_max, y_max))
    if not all(map(math.isfinite, values)) or x_min > x_max or y_min > y_max:
        raise ValueError(f'a box needs finite corners low <= high, got {values}')
    return Region('box', values)


def circle_region(x: float, y: float, radius_m: float) -> Region:
    """Return the circle of ``radius_m`` around (x, y) (m, world frame)."""
    values = (float(x), float(y), float(radius_m), 0.0)
    if not all(map(math.isfinite, values)) or radius_m < 0.0:
        raise ValueError(f'a circle needs a finite centre and a radius >= 0, got {values[:3]}')
    return Region('circle', values)


def polygon_region(points: Sequence[Sequence[float]]) -> Region:
    """
    Return the convex hull of ``points`` (x, y; more values are ignored) on the ground.

    ValueError if they are not finite or span no area (all on one line).
    """
    unique = sorted({(float(p[0]), float(p[1])) for p in points})
    if not all(math.isfinite(v) for point in unique for v in point):
        raise ValueError(f'a polygon needs finite corners, got {unique[:8]}')

    def cross(o: Point, a: Point, b: Point) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def chain(ordered: Iterable[Point]) -> List[Point]:  # Andrew's monotone chain: a half
        half: List[Point] = []
        for point in ordered:
            while len(half) >= 2 and cross(half[-2], half[-1], point) <= 0.0:
                half.pop()
            half.append(point)
        return half[:-1]

    hull = chain(unique) + chain(reversed(unique))
    area = sum(ax * by - bx * ay for (ax, ay), (bx, by) in zip(hull, hull[1:] + hull[:1])) / 2
    span = max(max(x for x, _ in unique) - min(x for x, _ in unique),
               max(y for _, y in unique) - min(y for _, y in unique))
    if len(hull) < 3 or area <= MIN_WIDTH_M * span:  # a sliver no base could stand in
        raise ValueError(f'a polygon needs corners that span an area, got {unique[:8]}')
    return Region('polygon', tuple(v for point in hull for v in point))
