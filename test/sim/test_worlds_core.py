"""
Worlds in the core, without ROS: loaded at start-up or while running, unloaded, reset, listed.

The standard's LoadWorld clears the scene, loads the new world and leaves
the simulation stopped; a full reset is "as if it was closed and launched
again", so it builds the world loaded last. The robots are the simulator's
own (its parameters), not the world's: they stay, standing at the world's
start pose. Named poses are frames a spawn or a teleport can be given in.
"""

import math
import os

from common import drive_and_read
import pytest

from r2d2_sim.errors import RefusedError, WorldError
from r2d2_sim.sim.entities import Category
from r2d2_sim.sim.settings.table import ConfigError
from r2d2_sim.sim.names import is_name
from r2d2_sim.sim.simulation import SpawnRequest
from r2d2_sim.sim.spawnables import box_urdf
from r2d2_sim.sim.tags import FILTER_MODE_ALL, TagsFilter
from r2d2_sim.sim.worlds import EMPTY_WORLD_URI, LoadOptions

ROOM = 'package://r2d2_sim/urdf/room.world.yaml'
SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'scan_rate': 0.0, 'imu_rate': 0.0}

# A world whose start pose is 1 m along x, 2 m along y, turned 90 degrees, and a shelf.
TURNED = '''
r2d2_sim_world: 1
name: turned
tags: [test, turned]
start_pose: entry
models:
  - {uri: cube_small.urdf, name: shelf, position: [3.0, 0.0, 0.025], tags: [shelf, small]}
named_poses:
  - {name: entry, position: [1.0, 2.0, 0.0], yaw: 1.5707963267948966, tags: [start]}
  - {name: far, description: somewhere, position: [-4.0, 0.0, 0.0], tags: [goal, far]}
'''


def test_the_world_parameter_takes_a_manifest_with_models_named_poses_and_tags(make):
    simulation = make(world=ROOM, tags=['astromech', 'test'])
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'room']
    world = simulation.worlds.current
    assert (world.name, world.uri, world.start_pose.name) == ('room', ROOM, 'start')
    assert 'indoor' in world.tags
    assert [pose.name for pose in simulation.worlds.named_poses(TagsFilter(('corner',)))] == \
        ['corner_ne', 'corner_nw', 'corner_sw', 'corner_se']
    room = simulation.entities.info('room')
    assert (room.category, room.tags) == (Category.STATIC_OBJECT, ('walls', 'static'))
    assert room.description.startswith('The walls')
    assert simulation.entities.info('r2d2').tags == ('astromech', 'test')
    assert simulation.entities.state('r2d2').position[:2] == pytest.approx((0.0, 0.0), abs=1e-9)


def test_an_empty_world_parameter_is_the_empty_world(make):
    simulation = make()
    world = simulation.worlds.current
    assert world.name == 'empty' and world.uri == EMPTY_WORLD_URI
    assert simulation.worlds.named_poses() == [] and simulation.worlds.is_loaded


def test_a_world_urdf_is_one_model_as_before(make):
    simulation = make(world='package://r2d2_sim/urdf/room.urdf')
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'room']
    assert simulation.worlds.current.name == 'room' and simulation.worlds.named_poses() == []


def test_a_bad_world_parameter_is_one_line(make):
    with pytest.raises(WorldError, match=r'^world /no/such\.world\.yaml: .*no such world file'):
        make(world='/no/such.world.yaml')


def test_the_start_pose_places_the_start_up_robots(make):
    """initial_pose is relative to the start pose: (1, 2) turned 90 degrees."""
    simulation = make(world_paths=[], robots=['a', 'b'],
                      **{'b.initial_pose': [1.0, 0.0, 0.0], 'b.tags': ['second']})
    a, b = simulation.robots
    simulation.load_world('', TURNED)
    entities = simulation.entities
    assert entities.info('b').tags == ('second',) and entities.tags('a') == ()
    # a at the pose itself; b 1 m along the pose's x, which is world +y: (1, 3), facing +y.
    assert simulation.entities.state('a').position[:2] == pytest.approx((1.0, 2.0), abs=1e-6)
    state = simulation.entities.state('b')
    assert state.position[:2] == pytest.approx((1.0, 3.0), abs=1e-6)
    assert 2 * math.atan2(state.orientation[2], state.orientation[3]) == pytest.approx(
        math.pi / 2, abs=1e-6)
    assert simulation.robots[0] is not a  # moved: built anew at the new start
    assert simulation.robots[0].config.initial_pose == pytest.approx((1.0, 2.0, math.pi / 2))


def test_a_loaded_world_runs_as_one_started_with_it(make, tmp_path):
    """Loading a world builds what sim_node would start with world:= that world: the same run."""
    path = tmp_path / 'turned.world.yaml'
    path.write_text(TURNED)
    robots = {'robots': ['a', 'b'], 'b.initial_pose': [1.0, 0.0, 0.0]}
    started = make(world=str(path), **robots)
    loaded = make(world_paths=[str(tmp_path)], **robots)
    drive_and_read(loaded, 50)
    loaded.load_world(str(path))
    assert loaded.entities.names() == started.entities.names() == [
        'ground_plane', 'a', 'shelf', 'b']
    assert drive_and_read(loaded) == drive_and_read(started)  # bit for bit


def test_load_world_replaces_the_world_and_stops_at_time_zero(make):
    """Old models and spawned entities leave; robots stay, a deleted one comes back; time 0."""
    simulation = make(world=ROOM)
    robot = simulation.robot
    simulation.spawn(SpawnRequest('box', uri='cube_small.urdf', position=(0.5, 0.5, 0.025)))
    drive_and_read(simulation, 48)
    world = simulation.load_world('', TURNED)
    assert world.name == 'turned' and simulation.worlds.current is world
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'shelf']
    assert [pose.name for pose in simulation.worlds.named_poses()] == ['entry', 'far']
    assert simulation.step_count == 0 and simulation.unrun_since_launch
    assert simulation.entities.info('shelf').tags == ('shelf', 'small')
    simulation.delete_entity('r2d2')
    simulation.load_world(ROOM)  # the room's start is the origin, as at start-up
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'room']
    assert simulation.robot is not robot  # deleted, so built again
    simulation.load_world(ROOM)
    assert simulation.robots  # the same robot now: its start did not move


def test_a_full_reset_builds_the_world_loaded_last_as_it_was_loaded(make):
    """Moved, relabelled or deleted: a full reset restores the loaded world; the run repeats."""
    other = make(world=ROOM)
    other.load_world('', TURNED)
    fresh = drive_and_read(other)
    simulation = make(world=ROOM)
    simulation.load_world('', TURNED)
    drive_and_read(simulation, 100)
    simulation.reset(time=True, state=True, spawned=True)
    assert drive_and_read(simulation) == fresh  # bit for bit, as loaded
    simulation.set_entity_state('shelf', '', (9.0, 9.0, 0.025), (0.0, 0.0, 0.0, 1.0),
                                (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    simulation.set_entity_info('shelf', Category.HUMAN, 'a person now', ['person'])
    simulation.reset(time=False, state=True, spawned=False)
    assert simulation.entities.info('shelf').tags == ('person',)  # a state reset keeps the info
    simulation.delete_entity('shelf')
    simulation.reset(time=True, state=True, spawned=True)
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'shelf']
    info = simulation.entities.info('shelf')
    assert (info.category, info.tags) == (Category.DYNAMIC_OBJECT, ('shelf', 'small'))
    assert simulation.entities.state('shelf').position[0] == pytest.approx(3.0, abs=1e-6)
    assert drive_and_read(simulation) == fresh


def test_unload_world_leaves_the_robots_and_no_world(make):
    simulation = make(world=ROOM)
    simulation.spawn(SpawnRequest('box', uri='cube_small.urdf', position=(0.5, 0.5, 0.025)))
    simulation.unload_world()
    assert not simulation.worlds.is_loaded and simulation.worlds.current is None
    assert simulation.entities.names() == ['ground_plane', 'r2d2']
    assert simulation.worlds.named_poses() == [] and simulation.step_count == 0
    with pytest.raises(RefusedError, match='^NO_WORLD_LOADED'):
        simulation.unload_world()
    with pytest.raises(RefusedError, match='^NOT_FOUND'):
        simulation.worlds.named_pose('start')
    simulation.load_world(ROOM)
    assert simulation.worlds.is_loaded and simulation.entities.names()[-1] == 'room'


def test_named_poses_are_frames_for_spawns_and_teleports(make):
    simulation = make(world='', world_paths=[])
    simulation.load_world('', TURNED)
    # 0.5 m along the entry's x (world +y), 0.1 m up: (1, 2.5, 0.1).
    box = simulation.spawn(SpawnRequest('crate', uri='cube_small.urdf', frame_id='entry',
                                        position=(0.5, 0.0, 0.1)))
    assert simulation.entities.state(box).position == pytest.approx((1.0, 2.5, 0.1), abs=1e-6)
    simulation.set_entity_state('r2d2', 'far', (0.0, 0.0, 0.471), (0.0, 0.0, 0.0, 1.0),
                                (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    placed = simulation.entities.state('r2d2').position
    assert placed == pytest.approx((-4.0, 0.0, 0.471), abs=1e-6)
    with pytest.raises(RefusedError, match='^INVALID_POSE'):
        simulation.spawn(SpawnRequest('x', uri='cube_small.urdf', frame_id='kitchen_door'))


def test_named_poses_filter_by_tags_any_or_all(make):
    simulation = make(world=ROOM)
    names = [p.name for p in simulation.worlds.named_poses(TagsFilter(('spawn', 'goal')))]
    assert names == ['start', 'goal', 'spawn_area']
    both = TagsFilter(('spawn', 'area'), FILTER_MODE_ALL)
    assert [p.name for p in simulation.worlds.named_poses(both)] == ['spawn_area']
    area = simulation.worlds.named_pose('spawn_area')
    # The bounds, relative to the pose, listed as the standard does: upper corner, then lower.
    assert area.bounds.kind == 'box'
    assert area.bounds.points == ((0.7, 0.6, 1.0), (-0.7, -0.6, 0.0))


def test_worlds_are_listed_from_the_package_and_world_paths(make, tmp_path):
    (tmp_path / 'lab.world.yaml').write_text(
        'r2d2_sim_world: 1\nname: lab\ntags: [indoor, lab]\n'
        'models:\n  - {uri: crate.urdf, name: crate, position: [2, 0, 0.1]}\n')
    (tmp_path / 'crate.urdf').write_text(
        '<robot name="crate"><link name="c"><collision><geometry><box size="0.2 0.2 0.2"/>'
        '</geometry></collision></link></robot>')
    (tmp_path / 'notes.txt').write_text('not a world')
    simulation = make(world_paths=[str(tmp_path)])
    worlds, note = simulation.worlds.available()
    assert note == ''
    assert [w.name for w in worlds] == ['empty', 'room', 'samurai', 'lab']
    lab = worlds[-1]
    assert lab.uri == 'file://' + str(tmp_path / 'lab.world.yaml')
    assert [w.name for w in simulation.worlds.available(tags=TagsFilter(('indoor',)))[0]] == \
        ['room', 'lab']
    both = TagsFilter(('indoor', 'lab'), FILTER_MODE_ALL)
    assert [w.name for w in simulation.worlds.available(tags=both)[0]] == ['lab']
    simulation.load_world(lab.uri)  # a listed world loads
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'crate']
    simulation.load_world('lab.world.yaml')  # a name is looked for in world_paths too
    assert simulation.worlds.current.name == 'lab'


@pytest.mark.parametrize('name, value, line', [
    ('world_paths', ['/nonexistent/worlds'],
     'parameter world_paths: /nonexistent/worlds is not a directory'),
    ('world_paths', ['package://no_such_package/worlds'],
     "parameter world_paths: package://no_such_package/worlds: no ROS package "
     "'no_such_package'"),
    ('model_paths', ['/etc/passwd'], 'parameter model_paths: /etc/passwd is not a directory'),
])
def test_paths_that_name_no_directory_stop_the_start(make, name, value, line):
    """A world path that is none failed every GetAvailableWorlds later; now it is said first."""
    with pytest.raises(ConfigError) as raised:
        make(**{name: value})
    assert str(raised.value) == line


def test_available_worlds_sources_fail_as_the_standard_says(make, tmp_path):
    broken = tmp_path / 'broken'
    broken.mkdir()
    (broken / 'bad.world.yaml').write_text('r2d2_sim_world: 1\nname: [unclosed\n')
    simulation = make(world_paths=[str(broken)])
    with pytest.raises(RefusedError, match='^DEFAULT_SOURCES_FAILED: .*bad.world.yaml'):
        simulation.worlds.available()
    worlds, note = simulation.worlds.available(continue_on_error=True)
    assert [w.name for w in worlds] == ['empty', 'room', 'samurai']
    assert 'bad.world.yaml' in note and '[unclosed' not in note  # no file contents
    with pytest.raises(RefusedError, match='^NOT_FOUND: /etc lies outside'):
        make().worlds.available(['/etc'])
    with pytest.raises(RefusedError, match='^FEATURE_UNSUPPORTED: https://'):
        make().worlds.available(['https://fuel.gazebosim.org/worlds'])
    worlds, note = make().worlds.available(['https://fuel.gazebosim.org/worlds'],
                                           offline_only=True)
    assert len(worlds) == 3 and 'offline_only' in note
    package = make().worlds.available(['package://r2d2_sim/urdf'])[0]  # listed twice: fine
    assert [w.name for w in package] == ['empty', 'room', 'samurai'] * 2


def test_load_options_of_the_standard(make, tmp_path):
    """fail_on_unsupported_element refuses what is ignored; missing assets can be left out."""
    text = ('r2d2_sim_world: 1\nname: odd\nweather: rain\nmodels:\n'
            '  - {uri: missing.urdf}\n  - {uri: cube_small.urdf, name: cube}\n')
    simulation = make(world_paths=[str(tmp_path)])
    (tmp_path / 'odd.world.yaml').write_text(text)
    before = simulation.entities.names()
    with pytest.raises(RefusedError, match='^MISSING_ASSETS: odd.world.yaml: model missing'):
        simulation.load_world('odd.world.yaml')
    with pytest.raises(RefusedError, match='^UNSUPPORTED_ELEMENTS: odd.world.yaml: unknown keys'):
        simulation.load_world('odd.world.yaml', options=LoadOptions(True, True))
    assert simulation.entities.names() == before
    world = simulation.load_world('odd.world.yaml', options=LoadOptions(False, True))
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'cube']
    assert any('unknown keys' in n and 'weather' not in n for n in world.notes)
    assert any('left out' in n and 'missing.urdf' in n for n in world.notes)


def test_a_model_named_like_a_robot_is_refused_and_nothing_changes(make):
    simulation = make()
    text = 'r2d2_sim_world: 1\nname: x\nmodels:\n  - {uri: cube_small.urdf, name: r2d2}\n'
    with pytest.raises(RefusedError, match='^OPERATION_FAILED: .*r2d2'):
        simulation.load_world('', text)
    assert simulation.worlds.current.name == 'empty'


def test_a_model_with_no_name_is_checked_under_the_name_the_build_gives_it(make, tmp_path):
    """
    A model without a name takes its URDF's robot name: one that is a later robot's is refused.

    The world's models load before the second robot. A model whose URDF is
    ``<robot name="b">`` took b's name, robot b could not be loaded again (one
    error line), LoadWorld answered OK, and b was gone for good.
    """
    errors = []
    simulation = make(errors=errors, world_paths=[str(tmp_path)], robots=['a', 'b'],
                      **{'b.initial_pose': [2.0, 0.0, 0.0]})
    (tmp_path / 'b_box.urdf').write_text(box_urdf(name='b'))
    (tmp_path / 'shelf.world.yaml').write_text(
        'r2d2_sim_world: 1\nname: shelf\nmodels:\n  - {uri: b_box.urdf, position: [5, 5, 0.1]}\n')
    robots = simulation.robots
    for world, text in (('shelf.world.yaml', ''), ('', box_urdf(name='b'))):
        with pytest.raises(RefusedError, match="^OPERATION_FAILED: the world's model .*named 'b'"):
            simulation.load_world(world, text)
        assert simulation.entities.names() == ['ground_plane', 'a', 'b']
        assert simulation.robots == robots and simulation.worlds.current.name == 'empty'
    # Named after the ground plane or the first robot, loaded before it: made unique, as before.
    (tmp_path / 'a_box.urdf').write_text(box_urdf(name='a'))
    simulation.load_world('', 'r2d2_sim_world: 1\nname: two\nmodels:\n'
                          f'  - {{uri: {tmp_path / "a_box.urdf"}, position: [5, 5, 0.1]}}\n'
                          f'  - {{uri: {tmp_path / "a_box.urdf"}, position: [5, 6, 0.1]}}\n')
    assert simulation.entities.names() == ['ground_plane', 'a', 'a_1', 'a_2', 'b']
    simulation.reset(time=True, state=True, spawned=True)
    assert [robot.name for robot in simulation.robots] == ['a', 'b'] and errors == []


def test_start_up_and_world_entities_get_names_the_entity_rule_takes(make):
    """
    Named after a URDF's robot name that is no valid name, they take it made valid.

    ``cube_small.urdf`` is ``<robot name="cube.urdf">``: listed as ``cube.urdf``,
    deleted, it could not be spawned again under that name (NAME_INVALID).
    """
    simulation = make(extra_models=['cube_small.urdf 1 1 0.025'])
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'cube_urdf']
    simulation.delete_entity('cube_urdf')
    simulation.spawn(SpawnRequest('cube_urdf', uri='cube_small.urdf', position=(1.0, 1.0, 0.025)))
    simulation.load_world('', box_urdf(name='my room/\u03b1'))
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'cube_urdf', 'my_room__']
    assert all(is_name(name) for name in simulation.entities.names())


def test_a_link_out_of_the_allowed_places_is_refused(make, tmp_path):
    inside = tmp_path / 'worlds'
    inside.mkdir()
    outside = tmp_path / 'elsewhere'
    outside.mkdir()
    (outside / 'secret.world.yaml').write_text('r2d2_sim_world: 1\nname: secret\n')
    os.symlink(outside / 'secret.world.yaml', inside / 'link.world.yaml')
    simulation = make(world_paths=[str(inside)])
    with pytest.raises(RefusedError, match='^NOT_FOUND: .*outside the places'):
        simulation.load_world(str(inside / 'link.world.yaml'))
    with pytest.raises(RefusedError, match='^NOT_FOUND: .*outside the places'):
        simulation.load_world(str(outside / 'secret.world.yaml'))
