"""
Entity bounds and the bounds filters in the core, against geometry worked out by hand.

GetEntityBounds is a box "relative to entity's canonical link transform":
in the base link's frame, so a box turned 45 degrees keeps its own sizes.
The filters (box, convex hull, sphere) test the entities' collision shapes
exactly, not their world bounding boxes: a query in the corner of a turned
box's bounding box, outside the box itself, does not pick it.
"""

import math

import pytest

from r2d2_sim.errors import RefusedError
from r2d2_sim.sim.bounds import Region
from r2d2_sim.sim.simulation import SpawnRequest

SIMULATION_DEFAULTS = {'scan_rate': 0.0, 'imu_rate': 0.0}
# 0.4 x 0.2 x 0.1 m, mass 0: it stays where it is put.
SLAB = ('<robot name="slab"><link name="slab"><collision><geometry><box size="0.4 0.2 0.1"/>'
        '</geometry></collision></link></robot>')
CRATE = ('<robot name="crate"><link name="crate"><collision><geometry><box size="0.2 0.2 0.2"/>'
         '</geometry></collision></link></robot>')
TURN_45 = (0.0, 0.0, math.sin(math.pi / 8), math.cos(math.pi / 8))


def spawn(simulation, name, text, position, orientation=(0.0, 0.0, 0.0, 1.0)):
    """Spawn ``text`` as ``name`` at a pose (its base link's)."""
    return simulation.spawn(SpawnRequest(name, resource_string=text, position=position,
                                         orientation=orientation))


def test_the_room_and_the_robot_are_boxes_in_their_base_link_frame(make):
    simulation = make(world='package://r2d2_sim/urdf/room.urdf')
    # The room's walls: x -3.1 .. 2.1, y -2.6 .. 2.6, 1 m high (urdf/room.urdf's comment).
    upper, lower = simulation.entities.bounds('room').points
    assert upper == pytest.approx((2.1, 2.6, 1.0)) and lower == pytest.approx((-3.1, -2.6, 0.0))
    # R2D2: legs and wheels at y +-0.22, 0.1 wide: +-0.27. Wheel centres at 0.25 - 0.6 - 0.085
    # = -0.435 under the base link, radius 0.035: its floor at -0.47. Its foot bars are 0.4
    # long: its back at x -0.2.
    upper, lower = simulation.entities.bounds('r2d2').points
    assert (lower[0], lower[1], lower[2], upper[1]) == pytest.approx((-0.2, -0.27, -0.47, 0.27))


def test_a_turned_box_keeps_its_own_sizes(make):
    simulation = make()
    spawn(simulation, 'slab', SLAB, (1.0, 1.0, 0.05), TURN_45)
    upper, lower = simulation.entities.bounds('slab').points
    assert upper == pytest.approx((0.2, 0.1, 0.05)) and lower == pytest.approx((-0.2, -0.1, -0.05))


def test_bounds_of_no_such_entity_are_not_found(make):
    with pytest.raises(RefusedError, match='^NOT_FOUND'):
        make().entities.bounds('kitchen_table')


def crates(simulation, region):
    """Return the names of the crates and slabs that a region picks, sorted."""
    return sorted(n for n in simulation.entities.overlapping(region) if n != 'ground_plane'
                  and n != 'r2d2')


@pytest.fixture
def yard(make):
    """Return a world of a crate at (2, 0) (faces x 1.9 .. 2.1) and one at (0, 2) turned 45 deg."""
    simulation = make()
    spawn(simulation, 'square', CRATE, (2.0, 0.0, 0.1))
    spawn(simulation, 'diamond', CRATE, (0.0, 2.0, 0.1), TURN_45)
    return simulation


def test_a_box_filter_meets_the_shapes_exactly(yard):
    assert crates(yard, Region.box((1.85, -0.05, 0.0), (1.95, 0.05, 0.2))) == ['square']
    assert crates(yard, Region.box((1.8, -0.05, 0.0), (1.89, 0.05, 0.2))) == []
    # The diamond's corners are 0.1 * sqrt2 = 0.1414 from its centre along x and y, so its
    # bounding box reaches (0.13, 2.13); the point (0.12, 2.12) is |x| + |y - 2| = 0.24 > 0.1414
    # from it in the diamond's own metric: outside the diamond, inside its bounding box.
    assert crates(yard, Region.box((0.11, 2.11, 0.0), (0.13, 2.13, 0.2))) == []
    assert crates(yard, Region.box((0.1, 1.9, 0.0), (0.2, 2.1, 0.2))) == ['diamond']
    # Corners in either order, as the standard lists them (upper first) or not.
    assert crates(yard, Region('box', ((1.95, 0.05, 0.2), (1.85, -0.05, 0.0)))) == ['square']


def test_a_convex_hull_filter_meets_the_shapes_exactly(yard):
    # A flat triangle at z 0.1 whose tip reaches x 1.95 (into the square), or 1.85 (short of it).
    for tip, picked in ((1.95, ['square']), (1.85, [])):
        hull = Region('convex_hull', ((1.5, -0.5, 0.1), (1.5, 0.5, 0.1), (tip, 0.0, 0.1)))
        assert crates(yard, hull) == picked
    # A tetrahedron around both crates' centres.
    around = Region('convex_hull', ((-1.0, -1.0, 0.05), (4.0, -1.0, 0.05), (-1.0, 4.0, 0.05),
                                    (0.5, 0.5, 3.0)))
    assert crates(yard, around) == ['diamond', 'square']


def test_a_sphere_filter_meets_the_shapes_exactly(yard):
    # From (2.3, 0, 0.1) the square's face x = 2.1 is 0.2 away.
    assert crates(yard, Region.sphere((2.3, 0.0, 0.1), 0.19)) == []
    assert crates(yard, Region.sphere((2.3, 0.0, 0.1), 0.21)) == ['square']


def test_the_filters_follow_an_entity_that_moves(yard):
    region = Region.box((4.9, -0.1, 0.0), (5.1, 0.1, 0.2))
    assert crates(yard, region) == []
    yard.set_entity_state('square', '', (5.0, 0.0, 0.1), (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0),
                          (0.0, 0.0, 0.0))
    assert crates(yard, region) == ['square']


@pytest.mark.parametrize('region', [
    Region('box', ((1.0, 1.0, 1.0),)),
    Region('sphere', ((0.0, 0.0, 0.0), (-1.0, 0.0, 0.0))),
    Region('convex_hull', ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (2.0, 2.0, 2.0))),
    Region('convex_hull', ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))),
    Region('box', ((0.0, 0.0, math.nan), (1.0, 1.0, 1.0))),
], ids=['box of one point', 'negative radius', 'collinear hull', 'hull of two', 'NaN'])
def test_a_malformed_region_is_refused(yard, region):
    with pytest.raises(RefusedError, match='^OPERATION_FAILED: bounds: '):
        yard.entities.overlapping(region)


def test_an_empty_region_picks_every_entity(yard):
    assert yard.entities.overlapping(Region()) == yard.entities.names()
