"""A jointed body's reach holds every shape in every configuration: by hand, and sampled."""

import math
import random

import pytest

from r2d2_sim.model.reach import FIXED, LinkReach, reach_radius, SLIDES, TURNS

ORIGIN = (0.0, 0.0, 0.0)


def test_an_arm_reaches_its_joint_then_its_shape_about_the_joint():
    """A link turning at 1 m from the base, its box at 0.4-0.6 m beyond: 1 + |(0.6, 0.1, 0.1)|."""
    arm = LinkReach(-1, TURNS, (1.0, 0.0, 0.0), (), (1.4, -0.1, -0.1), (1.6, 0.1, 0.1))
    base = ((-0.2, -0.2, -0.2), (0.2, 0.2, 0.2))
    assert reach_radius(ORIGIN, *base, [arm]) == pytest.approx(1.0 + math.sqrt(0.38))
    # A base larger than the arm's reach is the reach.
    assert reach_radius(ORIGIN, (-3.0, 0, 0), (0.0, 0, 0), [arm]) == pytest.approx(3.0)


def test_a_slide_reaches_its_farther_end_and_a_fixed_link_is_its_parents():
    """A slide between 0.5 and 2 m: 2 m. A fixed link's box counts from the base, not its joint."""
    slide = LinkReach(-1, SLIDES, (1.0, 0.0, 0.0), ((0.5, 0.0, 0.0), (2.0, 0.0, 0.0)),
                      (1.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    assert reach_radius(ORIGIN, None, None, [slide]) == pytest.approx(2.0)
    assert reach_radius(ORIGIN, None, None, [slide._replace(ends=())]) is None
    assert reach_radius(ORIGIN, None, None, [slide._replace(motion='free')]) is None
    with pytest.raises(ValueError, match='parents come first'):
        reach_radius(ORIGIN, None, None, [slide._replace(parent=0)])
    leg = LinkReach(-1, FIXED, (0.0, 0.0, 1.0), (), (0.0, 0.0, -0.5), (0.0, 0.0, 0.2))
    assert reach_radius(ORIGIN, None, None, [leg]) == pytest.approx(0.5)  # not 1 + 1.5
    # A wheel turning on the leg's foot: from the base to its axle, and its radius.
    wheel = LinkReach(0, TURNS, (0.0, 0.0, -0.5), (), (-0.1, -0.1, -0.6), (0.1, 0.1, -0.4))
    assert reach_radius(ORIGIN, None, None, [leg, wheel]) == pytest.approx(
        0.5 + math.sqrt(0.03))


def _chain_points(lengths, kinds, joints, shapes):
    """Return each link's joint origin and its shape's points, in the world (a planar chain)."""
    x = y = heading = 0.0
    origins, points = [], []
    for length, kind, q, shape in zip(lengths, kinds, joints, shapes):
        x, y = x + length * math.cos(heading), y + length * math.sin(heading)
        if kind == TURNS:
            heading += q
        ox, oy = x, y
        if kind == SLIDES:  # along the link's own x
            ox, oy = x + q * math.cos(heading), y + q * math.sin(heading)
        origins.append((ox, oy, 0.0))
        points.append([(ox + px * math.cos(heading) - py * math.sin(heading),
                        oy + px * math.sin(heading) + py * math.cos(heading), pz)
                       for px, py, pz in shape])
        x, y = ox, oy
    return origins, points


@pytest.mark.parametrize('seed', range(20))
def test_no_configuration_of_a_random_chain_leaves_its_reach(seed):
    """Chains of turning, sliding and fixed joints: 300 configurations each stay inside."""
    rng = random.Random(seed)
    count = rng.randint(1, 5)
    lengths = [rng.uniform(0.0, 1.0) for _ in range(count)]
    kinds = [rng.choice((TURNS, SLIDES, FIXED)) for _ in range(count)]
    limits = [(rng.uniform(-0.5, 0.0), rng.uniform(0.0, 0.5)) for _ in range(count)]
    shapes = [[(rng.uniform(-0.3, 0.6), rng.uniform(-0.2, 0.2), rng.uniform(-0.1, 0.1))
               for _ in range(4)] for _ in range(count)]

    def configuration():
        return [rng.uniform(-math.pi, math.pi) if kind == TURNS
                else rng.uniform(*limit) if kind == SLIDES else 0.0
                for kind, limit in zip(kinds, limits)]

    now = configuration()
    origins, points = _chain_points(lengths, kinds, now, shapes)
    links = []
    for index, (kind, q, limit) in enumerate(zip(kinds, now, limits)):
        xs, ys, zs = zip(*points[index])
        ends = []
        if kind == SLIDES:  # the origin at each limit, everything above it as it is
            for end in limit:
                moved = list(now)
                moved[index] = end
                ends.append(_chain_points(lengths, kinds, moved, shapes)[0][index])
        links.append(LinkReach(index - 1, kind, origins[index], ends,
                               (min(xs), min(ys), min(zs)), (max(xs), max(ys), max(zs))))
    radius = reach_radius(ORIGIN, None, None, links)
    assert radius is not None
    farthest = 0.0
    for _ in range(300):
        _, moved = _chain_points(lengths, kinds, configuration(), shapes)
        farthest = max(farthest, max(math.dist(ORIGIN, p) for link in moved for p in link))
    assert farthest <= radius + 1e-9
    assert radius < 10.0 * (sum(lengths) + 1.0)  # a bound, not infinity
