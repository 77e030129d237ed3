"""
GJK distances between convex shapes, checked against geometry worked out by hand.

Unit cubes, right angles and a 45-degree square: every expected distance is
a whole number, a square root of one, or a difference of the two, with the
arithmetic in the comments. The shapes' own support functions and extents
are checked the same way.
"""

import math

import pytest

from r2d2_sim.model.convex import (
    Ball, box_corners, Capsule, collinear, Cylinder, distance, extent, overlap, Points)

SQRT2 = math.sqrt(2.0)
SQRT3 = math.sqrt(3.0)


def cube(low=(0.0, 0.0, 0.0), size=1.0):
    """Return the hull of an axis-aligned cube with its lowest corner at ``low``."""
    return Points(box_corners(low, tuple(c + size for c in low)))


def point(*xyz):
    """Return a single point as a shape."""
    return Points([xyz])


@pytest.mark.parametrize('other, expected', [
    (cube((2.0, 0.0, 0.0)), 1.0),            # faces x = 1 and x = 2 face each other
    (cube((2.0, 2.0, 0.0)), SQRT2),          # edges: (1, 1) to (2, 2) in xy, same z span
    (cube((2.0, 2.0, 2.0)), SQRT3),          # corners (1, 1, 1) and (2, 2, 2)
    (cube((1.0, 0.0, 0.0)), 0.0),            # face to face: touching counts
    (cube((0.5, 0.5, 0.5)), 0.0),            # overlapping
    (cube((-3.0, 0.25, 0.25)), 2.0),         # from the other side: x = -2 to x = 0
], ids=['faces', 'edges', 'corners', 'touching', 'overlapping', 'other side'])
def test_distance_between_unit_cubes(other, expected):
    assert distance(cube(), other) == pytest.approx(expected, abs=1e-9)
    assert distance(other, cube()) == pytest.approx(expected, abs=1e-9)  # symmetric
    assert overlap(cube(), other) is (expected == 0.0)


def test_a_point_inside_a_cube_is_at_distance_zero():
    assert distance(cube(), point(0.5, 0.25, 0.75)) == 0.0


@pytest.mark.parametrize('where, expected', [
    ((3.0, 0.0, 0.0), 3.0 - SQRT2),          # the square's corner at (sqrt 2, 0)
    ((0.0, 3.0, 0.0), 3.0 - SQRT2),          # the corner at (0, sqrt 2)
    ((2.0, 2.0, 0.0), 2 * SQRT2 - 1.0),      # off the edge x + y = sqrt2: (4 - sqrt2) / sqrt2
    ((0.0, 0.0, 3.0), 2.0),                  # above the top face z = 1
])
def test_distance_to_a_box_turned_45_degrees(where, expected):
    # A 2 x 2 x 2 box turned 45 degrees about z: a square with corners (+-sqrt2, 0), (0, +-sqrt2).
    corners = [(x * SQRT2, y * SQRT2, z) for x, y in ((1, 0), (-1, 0), (0, 1), (0, -1))
               for z in (-1.0, 1.0)]
    assert distance(Points(corners), point(*where)) == pytest.approx(expected, abs=1e-9)


def test_a_flat_triangle_and_a_point_above_it():
    # The triangle (0,0,0), (2,0,0), (0,2,0): the point (0.5, 0.5, 3) is 3 above its face,
    # the point (2, 2, 0) is sqrt2 from its long edge x + y = 2.
    triangle = Points([(0.0, 0.0, 0.0), (2.0, 0.0, 0.0), (0.0, 2.0, 0.0)])
    assert distance(triangle, point(0.5, 0.5, 3.0)) == pytest.approx(3.0, abs=1e-9)
    assert distance(triangle, point(2.0, 2.0, 0.0)) == pytest.approx(SQRT2, abs=1e-9)
    assert distance(triangle, point(0.5, 0.5, 0.0)) == 0.0


def test_skew_segments():
    # Along x at z = 0 and along y at z = 1: the closest points are (0,0,0) and (0,0,1).
    a = Points([(-1.0, 0.0, 0.0), (1.0, 0.0, 0.0)])
    b = Points([(0.0, -1.0, 1.0), (0.0, 1.0, 1.0)])
    assert distance(a, b) == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize('where, expected', [
    ((5.0, 0.0, 0.0), 4.0), ((0.0, -3.0, 4.0), 4.0), ((0.6, 0.0, 0.0), 0.0)])
def test_ball_and_point(where, expected):
    # |(0, -3, 4)| = 5, less the radius 1.
    assert distance(Ball((0.0, 0.0, 0.0), 1.0), point(*where)) == pytest.approx(
        expected, abs=1e-7)


def test_two_balls_and_a_ball_against_a_cube():
    assert distance(Ball((0, 0, 0), 1.0), Ball((3, 4, 0), 1.5)) == pytest.approx(2.5, abs=1e-7)
    # The cube's corner (1, 1, 1) is sqrt3 from (2, 2, 2): a ball of radius 1 there misses by
    # sqrt3 - 1; one of radius 2 reaches it.
    assert distance(cube(), Ball((2, 2, 2), 1.0)) == pytest.approx(SQRT3 - 1.0, abs=1e-7)
    assert overlap(cube(), Ball((2, 2, 2), 2.0))


@pytest.mark.parametrize('where, expected', [
    ((3.0, 0.0, 0.0), 2.0),                  # beside the side wall: 3 - radius 1
    ((0.0, 0.0, 4.0), 3.0),                  # above the top cap at z = 1
    ((2.0, 0.0, 2.0), SQRT2),                # off the rim (1, 0, 1): (1, 1) away
    ((0.5, 0.5, 0.5), 0.0),                  # inside
])
def test_cylinder_and_point(where, expected):
    # Axis z, radius 1, from z = -1 to 1.
    shape = Cylinder((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 1.0, 1.0)
    assert distance(shape, point(*where)) == pytest.approx(expected, abs=1e-7)


def test_cylinder_along_x_against_a_cube():
    # Axis x, radius 0.5, half length 2, centred at (0, 0, 3): its lowest line is z = 2.5,
    # 1.5 above the cube's top face z = 1, and its x span -2 .. 2 covers the cube's.
    shape = Cylinder((0.0, 0.0, 3.0), (1.0, 0.0, 0.0), 2.0, 0.5)
    assert distance(shape, cube()) == pytest.approx(1.5, abs=1e-7)


def test_capsule_reaches_past_its_segment_ends():
    # From (0,0,0) to (2,0,0), radius 0.5: the point (3.5, 0, 0) is 1.5 from the end, 1 from it.
    shape = Capsule((0.0, 0.0, 0.0), (2.0, 0.0, 0.0), 0.5)
    assert distance(shape, point(3.5, 0.0, 0.0)) == pytest.approx(1.0, abs=1e-7)
    assert distance(shape, point(1.0, 2.0, 0.0)) == pytest.approx(1.5, abs=1e-7)


def test_extent_is_a_bounding_box_along_any_axis():
    shape = Cylinder((1.0, 2.0, 3.0), (0.0, 0.0, 1.0), 0.5, 0.25)
    assert extent(shape, (1.0, 0.0, 0.0)) == pytest.approx((0.75, 1.25))
    assert extent(shape, (0.0, 0.0, 1.0)) == pytest.approx((2.5, 3.5))
    # The unit cube along the diagonal: from 0 to (1 + 1 + 1) / sqrt3 = sqrt3.
    diagonal = (1 / SQRT3, 1 / SQRT3, 1 / SQRT3)
    assert extent(cube(), diagonal) == pytest.approx((0.0, SQRT3))


@pytest.mark.parametrize('points, expected', [
    ([(0, 0, 0), (1, 1, 1), (2, 2, 2)], True),
    ([(0, 0, 0), (0, 0, 0), (0, 0, 0)], True),
    ([(0, 0, 0), (1, 0, 0)], True),
    ([(0, 0, 0), (1, 0, 0), (0, 1, 0)], False),
])
def test_collinear(points, expected):
    assert collinear(points) is expected


def test_a_hull_needs_a_point():
    with pytest.raises(ValueError):
        Points([])
