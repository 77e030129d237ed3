"""Regions on the ground: the convex polygon against points worked out by hand."""

import math

import pytest

from r2d2_sim.model.regions import box_region, circle_region, polygon_region


def test_a_polygon_is_the_hull_of_its_points_edges_included():
    """A unit square's corners and its centre: the square, counter-clockwise; edges inside."""
    square = polygon_region([(1, 1), (0, 0), (0.5, 0.5), (1, 0), (0, 1), (1, 0)])
    assert square.values == (0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0)
    assert square.contains(0.5, 0.5) and square.contains(1.0, 0.25) and square.contains(0, 0)
    assert not square.contains(1.001, 0.5) and not square.contains(0.5, -0.001)


def test_a_turned_square_is_a_diamond():
    """A 2 m square turned 45 degrees about the origin: corners at sqrt(2) on the axes."""
    half = math.sqrt(2.0)
    diamond = polygon_region([(half, 0.0), (0.0, half), (-half, 0.0), (0.0, -half)])
    assert diamond.contains(1.41, 0.0) and diamond.contains(0.7, 0.7)
    assert not diamond.contains(0.9, 0.9)  # inside the unturned square, outside the diamond
    assert box_region(-1, -1, 1, 1).contains(0.9, 0.9)
    assert circle_region(0, 0, half).contains(1.0, 1.0)


@pytest.mark.parametrize('points', [[(0, 0), (1, 1), (2, 2)], [(0, 0)],
                                    [(0, 0), (math.nan, 1), (1, 0)],
                                    [(0, 0), (1, 0), (1, 2e-16), (0, 2e-16)]])
def test_points_that_span_no_area_are_no_polygon(points):
    """Points on a line, a single point, a NaN, a sliver (a flat box on its side): ValueError."""
    with pytest.raises(ValueError, match='polygon'):
        polygon_region(points)
