"""
Regions on the ground a robot's run can reach: boxes and circles in the world's x-y plane.

Pure math. A scenario's goal, a dock's tolerance, a spawn area: each is a
:class:`Region` that says whether a point (the robot's base) is inside.
"""

import math
from typing import NamedTuple, Sequence

__all__ = ['Region', 'box_region', 'circle_region']


class Region(NamedTuple):
    """A box (``kind`` 'box': x_min, y_min, x_max, y_max) or circle ('circle': x, y, r, 0)."""

    kind: str
    values: Sequence[float]

    def contains(self, x: float, y: float) -> bool:
        """Return True when (x, y) is inside, its edge included."""
        if self.kind == 'box':
            x_min, y_min, x_max, y_max = self.values
            return x_min <= x <= x_max and y_min <= y <= y_max
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
