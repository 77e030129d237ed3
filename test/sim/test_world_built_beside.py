"""
A LoadWorld builds the new world beside the old one, which steps on until the swap.

``Simulation.loading_world`` is a generator: each ``next`` loads a body into
a PyBullet client of its own, the old world may step between, and the last
``next`` swaps the new world in. What comes out is what a launch with that
world gives, bit for bit, however many steps the old world took meanwhile;
if the old world changed under the build (a start-up robot deleted, a reset),
the swap builds the world in place instead, the same way.
"""

import shutil

from common import connected_clients, drive_and_read, PACKAGE_URDF
import pytest

from r2d2_sim.errors import RefusedError, WorldError
from r2d2_sim.sim.simulation import SpawnRequest
from r2d2_sim.sim.worlds import EMPTY_WORLD_URI

SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'imu_rate': 0.0}
ROBOTS = {'robots': ['a', 'b'], 'b.initial_pose': [1.0, 0.0, 0.0]}

# Its start pose moves robot a (built anew) and b (its start moves with it).
SHELVES = '''
r2d2_sim_world: 1
name: shelves
start_pose: entry
models:
  - {uri: cube_small.urdf, name: shelf, position: [3.0, 0.0, 0.025]}
  - {uri: cube_small.urdf, name: crate, position: [3.0, 1.0, 0.025]}
  - {uri: cube_small.urdf, name: box, position: [3.0, -1.0, 0.025]}
named_poses:
  - {name: entry, position: [1.0, 2.0, 0.0], yaw: 1.5707963267948966}
'''


BOX = '''<robot name="crate"><link name="base"><inertial><mass value="1"/>
<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
<collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision></link></robot>'''


@pytest.fixture
def world_path(tmp_path):
    path = tmp_path / 'shelves.world.yaml'
    path.write_text(SHELVES)
    return path


def test_the_old_world_steps_between_the_bodies_and_the_new_one_is_a_launch(make, world_path):
    started = make(world=str(world_path), **ROBOTS)
    loaded = make(world_paths=[str(world_path.parent)], **ROBOTS)
    drive_and_read(loaded, 24)
    robot = loaded.robot
    clients = connected_clients()
    steps = loaded.loading_world(str(world_path))
    poses, chunks = [], 0
    with pytest.raises(StopIteration) as done:
        while True:
            next(steps)
            chunks += 1
            assert loaded.entities.names() == ['ground_plane', 'a', 'b']  # the old world
            loaded.step()
            poses.append(robot.body.world_pose())
    assert done.value.value.name == 'shelves'
    assert len(connected_clients()) == len(clients)  # the old client went with the old world
    assert chunks >= 5  # the ground, two robots, three models: one body each
    assert len(set(poses)) == len(poses)  # the old robot drove on all along
    assert loaded.step_count == 0 and loaded.unrun_since_launch
    assert loaded.entities.names() == started.entities.names() == [
        'ground_plane', 'a', 'shelf', 'crate', 'box', 'b']
    assert drive_and_read(loaded, 120) == drive_and_read(started, 120)  # bit for bit


def test_a_world_changed_during_the_build_is_built_in_place_as_a_launch(make, world_path):
    started = make(world=str(world_path), **ROBOTS)
    loaded = make(world_paths=[str(world_path.parent)], **ROBOTS)
    clients = connected_clients()
    steps = loaded.loading_world(str(world_path))
    next(steps)
    next(steps)
    loaded.delete_entity('b')  # built beside with b kept: the swap must not take it
    loaded.spawn(SpawnRequest('cube', uri='cube_small.urdf', position=(0.5, 0.5, 0.025)))
    for _ in steps:
        loaded.step()
    assert connected_clients() == clients  # the build beside was dropped, not leaked
    assert loaded.entities.names() == started.entities.names()  # b back, the cube gone
    assert drive_and_read(loaded, 120) == drive_and_read(started, 120)


def test_a_spawn_during_the_build_leaves_with_the_old_world(make, world_path):
    loaded = make(world_paths=[str(world_path.parent)], **ROBOTS)
    steps = loaded.loading_world(str(world_path))
    next(steps)
    loaded.spawn(SpawnRequest('cube', uri='cube_small.urdf', position=(0.5, 0.5, 0.025)))
    for _ in steps:
        loaded.step()
    assert 'cube' not in loaded.entities.names() and 'cube' not in loaded.world.bodies
    assert loaded.entities.names() == ['ground_plane', 'a', 'shelf', 'crate', 'box', 'b']


def test_a_build_that_fails_drops_its_client_and_builds_the_old_world_as_launched(
        make, world_path, tmp_path):
    model = tmp_path / 'crate.urdf'
    model.write_text(BOX)
    world_path.write_text(SHELVES.replace('uri: cube_small.urdf, name: crate',
                                          f'uri: {model}, name: crate'))
    errors = []
    loaded = make(errors=errors, world_paths=[str(world_path.parent)], **ROBOTS)
    clients = connected_clients()
    steps = loaded.loading_world(str(world_path))
    next(steps)
    model.write_text('<robot name="broken">')  # changed between the check and the build
    with pytest.raises(RefusedError, match='could not be built'):
        for _ in steps:
            loaded.step()
    assert connected_clients() == clients
    assert loaded.entities.names() == ['ground_plane', 'a', 'b'] and loaded.step_count == 0
    assert any('could not be built' in line for line in errors)


def test_fifteen_robots_with_lasers_all_move_to_the_new_start(make, world_path):
    """Ray groups are per client: the robots built beside take the new world's, not 29 more."""
    names = [f'r{i}' for i in range(15)]
    poses = {f'{name}.initial_pose': [1.5 * (i % 6), 1.5 * (i // 6), 0.0]
             for i, name in enumerate(names)}
    errors = []
    started = make(world=str(world_path), robots=names, **poses)
    loaded = make(errors=errors, world_paths=[str(world_path.parent)], robots=names, **poses)
    assert all(robot.laser is not None for robot in loaded.robots)
    loaded.load_world(str(world_path))  # its start pose moves every robot: built anew
    assert errors == []
    assert [r.name for r in loaded.robots] == [r.name for r in started.robots] == names
    assert [r.ray_group for r in loaded.robots] == [r.ray_group for r in started.robots]
    spare = loaded.world.take_ray_group()  # the next group free is a launch's next one
    assert spare == started.world.take_ray_group()
    assert spare not in [r.ray_group for r in loaded.robots]


def test_a_world_closed_during_the_build_is_not_brought_back(make, world_path):
    loaded = make(world_paths=[str(world_path.parent)], **ROBOTS)
    clients = connected_clients()
    steps = loaded.loading_world(str(world_path))
    next(steps)
    next(steps)
    loaded.close()  # what destroying the node does between two chunks
    with pytest.raises(WorldError, match='closed'):
        for _ in steps:
            pass
    assert not loaded.world.connected
    assert len(connected_clients()) == len(clients) - 1  # its own client gone, the build's too


def bin_with_its_centre_of_mass_at(x_m):
    """Return BOX named bin, its inertial origin at ``x_m`` along x: its shape stays put."""
    return BOX.replace('"crate"', '"bin"').replace('<inertial>',
                                                   f'<inertial><origin xyz="{x_m:g} 0 0"/>')


def test_an_extra_model_whose_file_changed_leaves_in_one_line_not_misplaced(
        make, world_path, tmp_path):
    """
    Its inertial origin moved 0.3 m in its file while running: LoadWorld reads the file anew.

    A reset loads the bin as it was (PyBullet's copy). The world built beside read
    the new file into the old records: the bin said it stood at x 1.30, its box
    where a launch with that file puts it (1.00).
    """
    model = tmp_path / 'bin.urdf'
    model.write_text(bin_with_its_centre_of_mass_at(0.0))
    errors = []
    simulation = make(errors=errors, world_paths=[str(world_path.parent)],
                      extra_models=[f'{model} 1.0 1.0 0.1'], gravity=[0.0, 0.0, 0.0])
    extra = simulation.world.bodies['bin']
    launched = (extra.world_pose(), extra.bounds())
    model.write_text(bin_with_its_centre_of_mass_at(0.3))
    simulation.reset(state=True)
    assert (extra.world_pose(), extra.bounds()) == launched and errors == []
    simulation.load_world(str(world_path))
    assert errors == [f'bin left the world: {model} changed since bin was loaded from it']
    assert 'bin' not in simulation.world.bodies and not extra.alive
    assert simulation.entities.names() == ['ground_plane', 'r2d2', 'shelf', 'crate', 'box']


def test_a_robot_that_left_takes_its_start_with_it_and_the_others_keep_theirs(make, tmp_path):
    """
    Robot b's URDF was edited: b leaves at the first LoadWorld, and c stays c at every next one.

    The empty world moves no start: each robot is loaded again from its file.
    Each robot's start was paired with the robots left by position: once b left,
    the second LoadWorld built b's start in c's place, and c was gone for good.
    """
    urdfs = {name: tmp_path / f'{name}.urdf' for name in 'abc'}
    for path in urdfs.values():
        shutil.copy(PACKAGE_URDF, path)
    errors = []
    simulation = make(errors=errors, robots=['a', 'b', 'c'],
                      **{f'{name}.urdf': str(path) for name, path in urdfs.items()},
                      **{'b.initial_pose': [1.0, 0.0, 0.0], 'c.initial_pose': [2.0, 0.0, 0.0]})
    with open(urdfs['b'], 'a') as edited:
        edited.write('<!-- edited -->\n')

    def robots():
        return [(robot.name, robot.namespace, robot.body.source, robot.config.initial_pose)
                for robot in simulation.robots]
    simulation.load_world(EMPTY_WORLD_URI)
    assert errors == [f'b left the world: {urdfs["b"]} changed since b was loaded from it']
    once = robots()
    assert [name for name, *_ in once] == ['a', 'c']
    assert once[1][1:3] == ('/c', str(urdfs['c']))
    simulation.load_world(EMPTY_WORLD_URI)
    assert robots() == once and len(errors) == 1
    simulation.reset(time=True, state=True, spawned=True)  # as launched with the world
    assert robots() == once and len(errors) == 1
