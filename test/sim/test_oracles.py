"""
The run oracles against cases worked out by hand: a gap, a wall, a region, a fall.

Boxes are 0.2 m cubes (half 0.1 m), R2D2's gripper reaches 0.515 m ahead of
its base link (its front), and commands take effect at once here (no
acceleration limit), so a robot at 0.3 m/s meets a wall whose face is d
metres ahead of its base link at about (d - 0.515) / 0.3 s.
"""

import math

import pytest

from r2d2_sim.model.regions import box_region, circle_region
from r2d2_sim.sim.oracles import RunWatch
from r2d2_sim.sim.simulation import SpawnRequest
from r2d2_sim.sim.spawnables import box_urdf

SIMULATION_DEFAULTS = {'scan_rate': 0.0, 'imu_rate': 0.0, 'cmd_vel_timeout': 0.0,
                       'max_linear_acceleration': 0.0, 'max_angular_acceleration': 0.0}
GRIPPER_REACH_M = 0.515


def place_box(simulation, name, x, y=0.0, size=0.2, mass_kg=0.0, sizes=None):
    """Spawn a box (a cube of ``size`` m) standing at (x, y): fixed unless it has a mass."""
    sizes = sizes or (size, size, size)
    return simulation.spawn(SpawnRequest(
        name, resource_string=box_urdf(sizes, mass_kg=mass_kg, name=name),
        position=(x, y, sizes[2] / 2)))


def run(simulation, seconds):
    for _ in range(round(seconds * 240)):
        simulation.step()


def test_two_boxes_at_a_known_gap_have_that_clearance(make):
    """Faces 0.30 m apart: the clearance is 0.30 m, to that box, from the first step."""
    simulation = make(ground_plane=True)
    simulation.set_entity_state('r2d2', '', (0.0, 5.0, 0.47), (0.0, 0.0, 0.0, 1.0),
                                (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))  # out of the way
    place_box(simulation, 'a', 0.0)
    place_box(simulation, 'b', 0.5)  # centres 0.5 apart: faces 0.3 apart
    with RunWatch(simulation, 'a', clearance_range_m=1.0) as watch:
        run(simulation, 0.1)
    assert watch.clearance.other == 'b'
    assert watch.clearance.distance_m == pytest.approx(0.30, abs=0.005)
    assert watch.clearance.time_ns == simulation.clock.time_ns(1)
    assert watch.contacts == [] and watch.touched() == []


def test_nothing_within_range_is_the_range(make):
    """A box 3 m away with a 1 m range: clearance 1 m, to nothing."""
    simulation = make()
    place_box(simulation, 'far', 3.5)
    with RunWatch(simulation, clearance_range_m=1.0) as watch:
        run(simulation, 0.1)
    assert watch.clearance == (1.0, None, None)


def test_a_robot_driven_into_a_wall_touches_it_when_geometry_says(make):
    """The wall's face 1.115 m ahead at 0.3 m/s: contact after about 2 s, with the gripper."""
    simulation = make()
    place_box(simulation, 'wall', 1.115 + 0.1, sizes=(0.2, 2.0, 1.0))  # face at x = 1.115
    expected_s = (1.115 - GRIPPER_REACH_M) / 0.3  # 2.0 s
    with RunWatch(simulation) as watch:
        simulation.robot.command(0.3, 0.0)
        run(simulation, 3.0)
    assert watch.touched() == ['wall']
    contact = watch.contacts[0]
    assert contact.start_ns / 1e9 == pytest.approx(expected_s, abs=0.1)
    assert contact.robot_link in ('left_tip', 'right_tip'), contact  # the gripper's tips
    assert contact.position[0] == pytest.approx(1.115, abs=0.005)  # on the wall's face
    assert contact.max_normal_force_n > 0.0
    assert watch.clearance.distance_m <= 0.0 and watch.clearance.other == 'wall'
    assert watch.tipped_ns is None


def test_without_clearance_the_contacts_are_the_same_and_the_clearance_the_range(make):
    """clearance=False asks no closest points: the same contact, the clearance left at 2 m."""
    simulation = make()
    place_box(simulation, 'wall', 1.115 + 0.1, sizes=(0.2, 2.0, 1.0))
    with RunWatch(simulation, clearance=False) as watch:
        simulation.robot.command(0.3, 0.0)
        run(simulation, 3.0)
    assert watch.touched() == ['wall']
    assert watch.clearance == (2.0, None, None)


def test_the_ground_and_the_robot_itself_are_no_contacts(make):
    """Driving on the plane, alone: no contact, clearance the range."""
    simulation = make()
    with RunWatch(simulation) as watch:
        simulation.robot.command(0.3, 0.5)
        run(simulation, 1.0)
    assert watch.contacts == [] and watch.clearance.other is None


def test_a_contact_ends_when_the_bodies_part(make):
    """A box dropped on the robot from above touches it and rolls off: start and end."""
    simulation = make()
    place_box(simulation, 'dropped', 0.0, size=0.1, mass_kg=0.5)
    simulation.set_entity_state('dropped', '', (0.25, 0.0, 1.2), (0.0, 0.0, 0.0, 1.0),
                                (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    with RunWatch(simulation) as watch:
        run(simulation, 3.0)
    assert watch.touched() == ['dropped']
    first = watch.contacts[0]
    assert first.end_ns is not None and first.end_ns > first.start_ns


def test_regions_reached_at_the_time_distance_over_speed_gives(make):
    """0.3 m/s along +x: x = 0.6 is reached after about 2 s; a region behind, never."""
    simulation = make()
    regions = {'ahead': box_region(0.6, -0.5, 2.0, 0.5), 'behind': circle_region(-1.0, 0.0, 0.3)}
    with RunWatch(simulation, regions=regions) as watch:
        simulation.robot.command(0.3, 0.0)
        run(simulation, 3.0)
    assert set(watch.reached) == {'ahead'}
    assert watch.reached['ahead'] / 1e9 == pytest.approx(2.0, abs=0.1)


def test_tipping_is_when_the_base_leans_past_the_angle(make):
    """Put down on its side: tipped at the first step; upright: never."""
    simulation = make()
    with RunWatch(simulation) as upright:
        run(simulation, 0.5)
    assert upright.tipped_ns is None
    roll = (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))  # 90 degrees
    simulation.set_entity_state('r2d2', '', (0.0, 0.0, 0.5), roll, (0.0, 0.0, 0.0),
                                (0.0, 0.0, 0.0))
    with RunWatch(simulation) as fallen:
        run(simulation, 0.1)
    assert fallen.tipped_ns == fallen.start_ns + simulation.clock.time_ns(1)


@pytest.mark.parametrize('degrees, tipped', [(30.0, False), (44.0, False), (46.0, True),
                                             (60.0, True)])
def test_the_default_tip_angle_is_45_degrees(make, degrees, tipped):
    """Leaning 44 degrees is standing, 46 is tipped (docs/testing.md: 45 degrees by default)."""
    simulation = make()
    # Held in the air for the one step watched: the lean is what was set, untouched by the
    # ground; rolled and pitched alike, as a robot falls over a corner.
    half = math.radians(degrees) / 2.0
    axis = (math.sqrt(0.5), math.sqrt(0.5))
    lean = (axis[0] * math.sin(half), axis[1] * math.sin(half), 0.0, math.cos(half))
    simulation.set_entity_state('r2d2', '', (0.0, 0.0, 2.0), lean, (0.0, 0.0, 0.0),
                                (0.0, 0.0, 0.0))
    with RunWatch(simulation) as watch:
        simulation.step()
    assert (watch.tipped_ns is not None) == tipped


def test_a_closed_watch_sees_nothing_more_and_bad_arguments_are_refused(make):
    """close() stops it; an unknown entity, a range of 0 and an angle of 0 are ValueErrors."""
    simulation = make()
    watch = RunWatch(simulation)
    run(simulation, 0.1)
    watch.close()
    watch.close()
    run(simulation, 0.1)
    assert watch.steps == 24
    for kwargs, fragment in (({'entity': 'nobody'}, 'no entity named'),
                             ({'clearance_range_m': 0.0}, 'clearance_range_m'),
                             ({'tip_angle_rad': 0.0}, 'tip_angle_rad')):
        with pytest.raises(ValueError, match=fragment):
            RunWatch(simulation, **kwargs)


NAMED_POSES_WORLD = """\
r2d2_sim_world: 1
name: marks
models: []
named_poses:
  - name: diamond
    position: [1.0, 0.0, 0.0]
    yaw: 0.7853981633974483
    bounds:
      box: [[0.3, 0.3, 1.0], [-0.3, -0.3, 0.0]]
  - name: behind
    position: [-1.0, 0.0, 0.0]
    bounds:
      sphere: {centre: [0.0, 0.0, 0.0], radius: 0.3}
  - name: bare
    position: [2.0, 0.0, 0.0]
"""


def test_a_named_pose_is_reached_where_its_turned_bounds_begin(make, tmp_path):
    """A 0.6 m square turned 45 degrees at x = 1: its corner at 1 - 0.3 * sqrt(2), at 1.92 s."""
    world = tmp_path / 'marks.world.yaml'
    world.write_text(NAMED_POSES_WORLD)
    simulation = make(world=str(world))
    corner_x = 1.0 - 0.3 * math.sqrt(2.0)  # 0.576 m; the square unturned would begin at 0.7
    with RunWatch(simulation, regions={'diamond': 'diamond', 'behind': 'behind'}) as watch:
        simulation.robot.command(0.3, 0.0)
        run(simulation, 3.0)
    assert set(watch.reached) == {'diamond'}
    assert watch.reached['diamond'] / 1e9 == pytest.approx(corner_x / 0.3, abs=0.05)
    for name, fragment in (('bare', 'has no bounds'), ('kitchen', "no named pose 'kitchen'")):
        with pytest.raises(ValueError, match=fragment):
            RunWatch(simulation, regions={name: name})
