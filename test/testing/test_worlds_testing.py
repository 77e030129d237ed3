"""
The testing API's worlds and named poses, in the in-process harness (SimHarness).

A test asks for "the goal" or "the spawn area" instead of coordinates: it
reads a named pose, places a robot or spawns a box at one (``at=``), loads
and unloads worlds, and reads and sets an entity's tags and bounds. The same
verbs through SimProcess (the standard's services, another process) are
system/test_worlds_system.py's.
"""

import math

import pytest
from sensor_msgs.msg import LaserScan

from common import BOX

from r2d2_sim.testing import HarnessError, RefusedError

ROOM = 'package://r2d2_sim/urdf/room.world.yaml'


@pytest.fixture
def r2d2_sim_parameters():
    """Start in the room, commands held."""
    return {'cmd_vel_timeout': 0.0, 'world': ROOM}


def test_at_the_goal_the_wall_is_one_metre_ahead(r2d2_sim):
    scans = []
    r2d2_sim.create_node('listener').create_subscription(LaserScan, 'scan', scans.append, 10)
    goal = r2d2_sim.named_pose('goal')  # x -2, y 1.5, facing -x: the wall x = -3 is 1 m ahead
    r2d2_sim.set_entity_state('r2d2', (0.0, 0.0, 0.471), at='goal')  # on its wheels there
    r2d2_sim.advance(seconds=0.2)
    truth = r2d2_sim.ground_truth().pose.pose
    assert (truth.position.x, truth.position.y) == pytest.approx(goal.position[:2], abs=0.001)
    assert 2 * math.atan2(truth.orientation.z, truth.orientation.w) == pytest.approx(
        math.pi, abs=0.01)
    assert scans[-1].ranges[180] == pytest.approx(1.0, abs=0.01)


def test_a_box_dropped_in_the_spawn_area_stays_in_its_bounds(r2d2_sim):
    area = r2d2_sim.named_pose('spawn_area')
    assert 'spawn' in area.tags and area.bounds.kind == 'box'
    upper, lower = area.bounds.points  # relative to the pose, upper corner first
    box = r2d2_sim.spawn('cube_small.urdf', at='spawn_area', position=(0.5, -0.3, 0.5))
    r2d2_sim.advance(seconds=1.0)  # it falls onto the floor
    x, y, z = r2d2_sim.entity_state(box).position
    x, y = x - area.position[0], y - area.position[1]  # the area is not turned
    assert lower[0] < x < upper[0] and lower[1] < y < upper[1]
    assert (x, y, z) == pytest.approx((0.5, -0.3, 0.025), abs=0.001)


def test_named_poses_by_tags_and_an_unknown_one(r2d2_sim):
    assert [p.name for p in r2d2_sim.named_poses(tags=['corner'])] == [
        'corner_ne', 'corner_nw', 'corner_sw', 'corner_se']
    assert [p.name for p in r2d2_sim.named_poses(tags=['spawn', 'area'], match_all=True)] == \
        ['spawn_area']
    with pytest.raises(RefusedError, match="^NOT_FOUND: no named pose 'kitchen_door'"):
        r2d2_sim.named_pose('kitchen_door')


def test_loading_another_world_keeps_the_robot_and_its_readers(r2d2_sim):
    r2d2_sim.send_cmd_vel(linear=0.3)
    r2d2_sim.advance(seconds=1.0)
    assert r2d2_sim.current_world().name == 'room'
    world = r2d2_sim.load_world('r2d2_sim_world: 1\nname: yard\nstart_pose: gate\n'
                                'named_poses:\n  - {name: gate, position: [5, 5, 0]}\n')
    assert world.name == 'yard' and r2d2_sim.current_world().name == 'yard'
    assert r2d2_sim.entities() == ['ground_plane', 'r2d2']
    truth = r2d2_sim.ground_truth()  # one control period after the load, at the gate
    assert truth.header.stamp.nanosec > 0 and truth.header.stamp.sec == 0
    assert (truth.pose.pose.position.x, truth.pose.pose.position.y) == pytest.approx(
        (5.0, 5.0), abs=0.01)
    r2d2_sim.send_cmd_vel(linear=0.3)  # the robot drives on, in the new world
    r2d2_sim.advance(seconds=1.0)
    assert r2d2_sim.ground_truth().pose.pose.position.x > 5.1
    assert [w.name for w in r2d2_sim.available_worlds(tags=['indoor'])] == ['room']


def test_unloaded_nothing_steps_until_a_world_is_loaded(r2d2_sim):
    r2d2_sim.unload_world()
    assert r2d2_sim.current_world() is None
    with pytest.raises(HarnessError, match='no world is loaded'):
        r2d2_sim.advance(seconds=0.1)
    with pytest.raises(RefusedError, match='^INCORRECT_STATE: no world is loaded'):
        r2d2_sim.reset_world()
    r2d2_sim.load_world(ROOM)
    r2d2_sim.advance(seconds=0.1)
    assert r2d2_sim.entities() == ['ground_plane', 'r2d2', 'room']


def test_entity_info_tags_and_bounds(r2d2_sim):
    r2d2_sim.set_entity_info('room', tags=['walls', 'test'])
    info = r2d2_sim.entity_info('room')
    assert info.tags == ('walls', 'test')
    assert info.description == 'The walls and the three boxes, one static body.'
    upper, lower = r2d2_sim.entity_bounds('room').points
    assert upper == pytest.approx((2.1, 2.6, 1.0)) and lower == pytest.approx((-3.1, -2.6, 0.0))
    r2d2_sim.reset_world()  # a full reset: the room as loaded, its tags too
    assert r2d2_sim.entity_info('room').tags == ('walls', 'static')


def test_available_worlds_can_leave_out_a_directory_with_a_bad_world(r2d2_sim_factory, tmp_path):
    """One bad world file fails the listing (the default); continue_on_error lists the rest."""
    (tmp_path / 'bad.sdf').write_text('<sdf version="1.9"><world name="w"><unclosed')
    sim = r2d2_sim_factory(world_paths=[str(tmp_path)])
    with pytest.raises(RefusedError, match='^DEFAULT_SOURCES_FAILED: .*bad.sdf'):
        sim.available_worlds()
    assert [w.name for w in sim.available_worlds(continue_on_error=True)] == \
        ['empty', 'room', 'samurai']
    assert [w.name for w in sim.available_worlds(tags=['indoor'], continue_on_error=True)] == \
        ['room']


def test_a_reset_with_no_scope_is_refused_in_one_line_and_resets_nothing(r2d2_sim):
    """Every scope False: ValueError, as SimProcess says (the standard's empty scope is all)."""
    box = r2d2_sim.spawn(BOX, position=(1.0, 0.0, 0.1))
    r2d2_sim.advance(seconds=0.5)
    before = r2d2_sim.sim.step_count
    with pytest.raises(ValueError, match='all False, which resets nothing') as raised:
        r2d2_sim.reset_world(time=False, state=False, spawned=False)
    assert '\n' not in str(raised.value)
    assert box in r2d2_sim.entities() and r2d2_sim.sim.step_count == before
