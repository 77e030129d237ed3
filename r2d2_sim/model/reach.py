"""
How far a jointed body can reach from its base, in any joint state: pure math.

A run's watch asks the physics about contacts and closest points only for
bodies that can be near the robot (:class:`~r2d2_sim.sim.oracles.RunWatch`).
That needs a bound that holds in any joint configuration: :func:`reach_radius`
takes the body as it stands now and returns the radius of a sphere around
its base point that holds every collision shape whatever the joints do
within their limits. A revolute, continuous or ball joint turns its subtree
about the joint's origin, which stays where it is in its parent's frame: the
subtree stays within the sphere about that origin that holds it now. A
prismatic joint slides its subtree along its axis, between the places its
limits put it. A fixed joint moves nothing: its link counts as its parent's.
A planar or a free joint has no such bound (None). Spheres about the joints
are nested from the tips to the base.
"""

import math
from typing import List, NamedTuple, Optional, Sequence, Tuple

__all__ = ['LinkReach', 'reach_radius', 'TURNS', 'SLIDES', 'FIXED', 'FREE']

Vec3 = Tuple[float, float, float]

# How a joint moves its child link (PyBullet's joint type codes map onto these).
FIXED, TURNS, SLIDES, FREE = 'fixed', 'turns', 'slides', 'free'


class LinkReach(NamedTuple):
    """One link as it stands now, world frame: its joint's origin, its shapes' box, its parent."""

    parent: int                     # the parent's index; -1: the base
    motion: str                     # FIXED, TURNS, SLIDES or FREE
    origin: Vec3                    # the joint's origin (the link's frame)
    ends: Sequence[Vec3]            # SLIDES: where the origin is at the joint's two limits
    low: Optional[Vec3]             # the link's collision box (None: no shape)
    high: Optional[Vec3]


def _farthest_corner(point: Vec3, low: Optional[Vec3], high: Optional[Vec3]) -> float:
    if low is None or high is None:
        return 0.0
    return math.sqrt(sum(max(abs(lo - p), abs(hi - p)) ** 2
                         for p, lo, hi in zip(point, low, high)))


def reach_radius(base_point: Vec3, base_low: Optional[Vec3], base_high: Optional[Vec3],
                 links: Sequence[LinkReach]) -> Optional[float]:
    """
    Return the radius about ``base_point`` that holds the body in every joint configuration.

    ``base_low``/``base_high``: the base's collision box (None: no shape);
    ``links``: every other link, in index order (each parent before its
    children, as PyBullet numbers them). A link on a FIXED joint is part of
    its parent: measured from the point its parent turns or slides about. A
    slide's subtree moves with its origin, whose farthest place from the
    parent's point is at one of its ``ends``. None when a joint is FREE, a
    slide has not two ends, or a value is not finite.
    """
    anchors: List[Vec3] = []  # the point each link's shapes and children are measured from
    for index, link in enumerate(links):
        if link.parent >= index:
            raise ValueError(f'link {index} has parent {link.parent}: parents come first')
        inherited = base_point if link.parent < 0 else anchors[link.parent]
        anchors.append(inherited if link.motion == FIXED else link.origin)
    radii = [_farthest_corner(anchor, link.low, link.high)
             for anchor, link in zip(anchors, links)]
    base_reach = _farthest_corner(base_point, base_low, base_high)
    for index in range(len(links) - 1, -1, -1):
        link = links[index]
        anchor = base_point if link.parent < 0 else anchors[link.parent]
        if link.motion == FIXED:
            within = radii[index]  # measured from the parent's point already
        elif link.motion == TURNS:
            within = math.dist(anchor, link.origin) + radii[index]
        elif link.motion == SLIDES and len(link.ends) == 2:
            within = max(math.dist(anchor, end) for end in link.ends) + radii[index]
        else:
            return None
        if link.parent < 0:
            base_reach = max(base_reach, within)
        else:
            radii[link.parent] = max(radii[link.parent], within)
    return base_reach if math.isfinite(base_reach) else None
