"""
A body loaded again in a rebuilt world: the same object, a new id, what was set on it kept.

``SimWorld.reset`` empties the physics world (``resetSimulation``) and loads
each body again in its order; what was set on a body at loading (its
starting pose, damping, friction, ray groups) is set again, a teleport is not.
"""

import math
import re

import pytest

from r2d2_sim.physics.body import Body, BodyRemoved, file_stamp, Loading, WorldError
from r2d2_sim.physics.description import default_urdf_path
from r2d2_sim.physics.world import RAY_GROUPS, ray_mask, SimWorld
from r2d2_sim.sim.spawnables import box_urdf


@pytest.fixture
def world():
    """Provide a world with its ground plane; closed after the test."""
    with SimWorld() as built:
        yield built


def speed_after_a_throw(world, body):
    """Throw ``body`` up at 5 m/s, let it fly 0.5 s; return its speed (m/s)."""
    body.set_base_state(position=(0.0, 3.0, 2.0), linear_velocity=(5.0, 0.0, 0.0))
    world.step(120)
    return math.hypot(*body.world_state().linear_velocity[:2])


def test_a_reset_keeps_the_bodies_and_their_undamped_motion(world):
    """A box without damping flies on at 5 m/s after the reset too; a teleport is undone."""
    box = world.load('cube_small.urdf', (0.0, 3.0, 0.5))
    box.drop_damping()
    assert speed_after_a_throw(world, box) == pytest.approx(5.0, abs=1e-6)
    plane = world.bodies['ground_plane']
    world.reset()
    assert world.bodies == {'ground_plane': plane, box.name: box}
    assert box.world_state().position == pytest.approx((0.0, 3.0, 0.5))
    assert speed_after_a_throw(world, box) == pytest.approx(5.0, abs=1e-6)
    damped = world.load('cube_small.urdf', (0.0, 5.0, 0.5))
    assert speed_after_a_throw(world, damped) < 4.8  # Bullet's default damping, for contrast


def test_a_reset_keeps_a_robot_s_ray_group_and_its_starting_pose(world):
    """Rays of the robot's group pass through it after the reset; it stands where it stood."""
    robot = world.load_robot(default_urdf_path(), (0.0, 0.0, 0.0))
    start = robot.world_state()
    robot.exclude_from_rays(group=RAY_GROUPS[0])
    through = ([[-1.0, 0.0, 0.3]], [[1.0, 0.0, 0.3]])
    assert world.cast_rays(*through, mask=-1)[0] < 1.0  # a ray of every group hits it
    assert world.cast_rays(*through, mask=ray_mask(RAY_GROUPS[0]))[0] == 1.0
    robot.set_base_state(position=(2.0, 2.0, 0.8))
    world.step(24)
    world.reset()
    assert robot.world_state() == start
    assert world.cast_rays(*through, mask=ray_mask(RAY_GROUPS[0]))[0] == 1.0
    assert world.cast_rays(*through, mask=-1)[0] < 1.0


def test_a_body_in_the_world_cannot_be_loaded_twice_and_a_removed_one_comes_back(world):
    """reload() of a loaded body: one line; of a removed one, it is back, usable."""
    box = world.load('cube_small.urdf', (1.0, 0.0, 0.5))
    with pytest.raises(WorldError, match='in the world already'):
        box.reload()
    world.remove(box)
    with pytest.raises(BodyRemoved):
        box.world_state()
    world.reload(box)
    assert world.bodies[box.name] is box
    assert box.world_state().position == pytest.approx((1.0, 0.0, 0.5))


BALL_PENDULUM = """<robot name="pendulum"><link name="pivot"><inertial><mass value="0"/>
<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
<link name="bob"><inertial><origin xyz="0 1 0"/><mass value="1"/><inertia ixx="0.01" ixy="0"
ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial><collision><origin xyz="0 1 0"/><geometry>
<sphere radius="0.1"/></geometry></collision></link><joint name="ball" type="spherical">
<parent link="pivot"/><child link="bob"/></joint></robot>"""


def swung_ball_pendulum(world, tmp_path):
    """Load a bob 1 m from a ball joint 3 m up, turned 0.3 rad about z and spun: it cones."""
    urdf = tmp_path / 'pendulum.urdf'
    urdf.write_text(BALL_PENDULUM)
    pendulum = world.load(str(urdf), (0.0, 3.0, 3.0))
    pendulum.free_joints()
    pendulum.drop_damping()
    ball = pendulum.joints['ball'].index
    turn = (0.0, 0.0, math.sin(0.15), math.cos(0.15))
    world.client.resetJointStateMultiDof(pendulum.id, ball, turn, (0.5, 0.0, 2.0))
    return pendulum, ball


def swing(world, pendulum, ball, steps=240):
    """Step ``steps`` times; return the ball joint's (rotation, spin) after each."""
    states = []
    for _ in range(steps):
        world.step()
        states.append(world.client.getJointStateMultiDof(pendulum.id, ball)[:2])
    return states


def test_a_ball_pendulum_put_back_swings_again_bit_for_bit(world, tmp_path):
    """Reset in place: its ball joint's rotation and spin too, so the same swing follows."""
    pendulum, ball = swung_ball_pendulum(world, tmp_path)
    pendulum.save_initial_state()
    start = world.client.getJointStateMultiDof(pendulum.id, ball)[:2]
    first = swing(world, pendulum, ball)
    assert abs(first[-1][0][0]) > 0.1 and first[-1][0][2] != start[0][2]  # it fell, turning
    pendulum.reset()
    assert world.client.getJointStateMultiDof(pendulum.id, ball)[:2] == start
    assert swing(world, pendulum, ball) == first


def test_a_swinging_ball_pendulum_swings_on_bit_for_bit_through_a_rebuilt_world(tmp_path):
    """Compaction loads it again and resumes it: the swing of a twin world never rebuilt."""
    swings = []
    for rebuilt in (False, True):
        with SimWorld() as world:
            pendulum, ball = swung_ball_pendulum(world, tmp_path)
            world.step(60)
            before = world.client.getJointStateMultiDof(pendulum.id, ball)[:2]
            if rebuilt:
                assert world.compact()
            assert world.client.getJointStateMultiDof(pendulum.id, ball)[:2] == before
            swings.append(swing(world, pendulum, ball))
    assert swings[1] == swings[0]


def test_a_body_whose_file_was_gone_at_load_says_so_when_its_filters_are_asked(world, tmp_path):
    """Its collision filters unknown: WorldError naming the gone file, not its own groups."""
    path = tmp_path / 'crate.urdf'
    path.write_text(box_urdf((0.2, 0.2, 0.2), mass_kg=1.0, name='crate'))
    loaded = world.load(str(path), (0.0, 0.0, 0.1))
    assert not loaded.sets_own_collision_filters
    loaded.collision_filters()  # read at load: the file may go now
    stamp = file_stamp(str(path))
    path.unlink()
    body = Body(world.client, loaded.id, 'again', str(path),
                loading=Loading(str(path), (0.0, 0.0, 0.1), (0.0, 0.0, 0.0, 1.0), 0, stamp))
    assert body.sets_own_collision_filters  # unknown: as if set
    with pytest.raises(WorldError, match='^' + re.escape(
            f'again: its file {path} is gone, so whether its URDF sets its own collision '
            'groups (which cannot be put back) is unknown') + '$'):
        body.collision_filters()
    assert loaded.collision_filters() == {-1: (1, -1)}
