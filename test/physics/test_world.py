"""
The PyBullet world headless: joints by name, frames, drive sign, time.

The ``world`` fixture is the top conftest's; the joint info the node serves
from it is checked in ros/test_world_ros.py.
"""

import math
import os
import socket
import sys

import pybullet
import pytest

from r2d2_sim.model.kinematics import quaternion_to_yaw
from r2d2_sim.physics.body import BodyRemoved
from r2d2_sim.physics.records import JointRecord
from r2d2_sim.physics.world import SimWorld, WorldError

from common import load_r2d2

WHEELS = ['left_front_wheel_joint', 'left_back_wheel_joint',
          'right_front_wheel_joint', 'right_back_wheel_joint']


def test_joints_are_looked_up_by_name(world, robot):
    """All 15 joints are known by name; unknown names list the known ones."""
    assert len(robot.joints) == 15
    wheel = robot.joint('left_front_wheel_joint')
    assert isinstance(wheel, JointRecord)
    assert wheel.type_name == 'revolute' and wheel.movable
    assert robot.joint('base_to_left_leg').type_name == 'fixed'
    assert robot.joint('gripper_extension').type_name == 'prismatic'
    with pytest.raises(WorldError, match='head_swivel'):
        robot.joint('no_such_joint')


def test_240_steps_are_one_second(world):
    """The fixed time step is 1/240 s: 240 steps advance simulated time by 1 s."""
    world.step(240)
    assert world.step_count == 240
    assert world.sim_time_s == pytest.approx(1.0)
    assert world.client.getPhysicsEngineParameters()['fixedTimeStep'] == pytest.approx(1 / 240)


def test_robot_rests_on_its_wheels_level(world, robot):
    """After settling the base is level and about 0.47 m up (wheels on the plane)."""
    world.step(240)
    base = robot.base_state()
    roll, pitch, _ = world.client.getEulerFromQuaternion(base.orientation)
    assert abs(roll) < math.radians(1) and abs(pitch) < math.radians(1)
    assert base.position[2] == pytest.approx(0.47, abs=0.01)


def test_positive_wheel_velocity_drives_along_plus_x(world, robot):
    """REP-103: all wheels at +5 rad/s move the base forward along +x."""
    indices = [robot.joint(n).index for n in WHEELS]
    world.step(60)
    robot.set_joint_velocities(indices, [5.0] * 4, [20.0] * 4)
    world.step(480)
    base = robot.base_state()
    assert base.position[0] > 0.25
    assert abs(base.position[1]) < 0.05 * base.position[0]
    assert base.linear_velocity[0] == pytest.approx(5.0 * 0.035, rel=0.05)  # body frame


def test_left_faster_than_right_turns_clockwise(world, robot):
    """Left wheels forward, right wheels backward: yaw decreases (turning right)."""
    left = [robot.joint(n).index for n in WHEELS[:2]]
    right = [robot.joint(n).index for n in WHEELS[2:]]
    robot.set_joint_velocities(left + right, [5.0, 5.0, -5.0, -5.0], [20.0] * 4)
    world.step(240)
    assert quaternion_to_yaw(*robot.base_state().orientation) < -0.2


def test_base_twist_is_in_the_body_frame():
    """Spawned at yaw 90 degrees, driving forward shows as +x body velocity."""
    with SimWorld() as world:
        robot = load_r2d2(world, (1.0, 2.0, math.pi / 2))
        indices = [robot.joint(n).index for n in WHEELS]
        robot.set_joint_velocities(indices, [5.0] * 4, [20.0] * 4)
        world.step(240)
        base = robot.base_state()
        assert base.position[1] > 2.1  # world +y
        assert base.linear_velocity[0] > 0.1 and abs(base.linear_velocity[1]) < 0.02


def test_reset_restores_spawn_state_and_keeps_time(world, robot):
    """reset() puts the robot back exactly; the step counter keeps counting."""
    start = robot.base_state()
    indices = [robot.joint(n).index for n in WHEELS]
    robot.set_joint_velocities(indices, [5.0] * 4, [20.0] * 4)
    world.step(240)
    assert robot.base_state().position[0] > start.position[0] + 0.1
    world.reset()
    assert robot.base_state() == start
    assert world.step_count == 240


def test_two_worlds_are_independent():
    """Each world has its own client: stepping one leaves the other untouched."""
    with SimWorld() as a, SimWorld() as b:
        robot_a, robot_b = load_r2d2(a), load_r2d2(b)
        assert a.client._client != b.client._client
        indices = [robot_a.joint(n).index for n in WHEELS]
        robot_a.set_joint_velocities(indices, [5.0] * 4, [20.0] * 4)
        a.step(240)
        b.step(240)
        assert robot_a.base_state().position[0] > 0.1
        assert abs(robot_b.base_state().position[0]) < 0.01


def test_close_disconnects(world):
    """close() disconnects the physics client and is idempotent."""
    assert world.connected
    world.close()
    world.close()
    assert not world.connected


def test_sanity_check_detects_non_finite_and_far_states(world, robot):
    """state_problem names the problem when the base is flung away."""
    assert robot.state_problem() is None
    world.client.resetBasePositionAndOrientation(robot.id, (1e5, 0, 0), (0, 0, 0, 1))
    assert 'left the world' in robot.state_problem()


def test_missing_urdf_is_a_world_error():
    """An unknown file gives a WorldError naming it."""
    from r2d2_sim.sim.simulation import Simulation
    from r2d2_sim.sim.settings.config import parse_config
    with pytest.raises(WorldError, match='not found'):
        Simulation(parse_config({'urdf': '/no/such/robot.urdf'}))


def test_malformed_urdf_is_a_world_error(tmp_path):
    """A file PyBullet refuses gives a WorldError, not a crash."""
    bad = tmp_path / 'bad.urdf'
    bad.write_text('<robot name="x"><link name="a"></robot')
    with SimWorld() as world, pytest.raises(WorldError, match='cannot load'):
        load_r2d2(world, urdf=str(bad))


def test_wheel_radius_from_collision_shape(world, robot):
    """The wheel radius is read from the wheel's cylinder: 0.035 m."""
    from r2d2_sim.sim.robots.drive_train import _wheel_radius_m
    wheel = robot.joint('left_front_wheel_joint').index
    assert _wheel_radius_m(robot, wheel) == pytest.approx(0.035)
    assert pybullet.GEOM_CYLINDER != pybullet.GEOM_MESH


def test_bodies_come_and_go_and_reset_each_on_its_own(world, robot):
    """A removed body's id goes to the next one loaded; our Body objects never mix them up."""
    robot_start = robot.world_state()
    cube = world.load('cube_small.urdf', (1.0, 0.0, 0.5))
    old_id = cube.id
    world.remove(cube)
    with pytest.raises(BodyRemoved):
        cube.world_state()
    sphere = world.load('sphere_small.urdf', (0.0, 1.0, 0.5))
    assert sphere.id == old_id and sphere.name not in (cube.name, robot.name)
    for ask in (cube.contacts, lambda: cube.closest_points(robot, 10.0)):  # not the sphere's
        with pytest.raises(BodyRemoved):
            ask()
    world.step(120)  # the sphere falls; restoreState would now refuse the changed world
    robot.set_base_state(position=(0.5, 0.5, 0.8))
    world.reset()
    assert robot.world_state() == robot_start
    assert sphere.world_state().position == pytest.approx((0.0, 1.0, 0.5))
    assert sorted(world.bodies) == sorted(['ground_plane', robot.name, sphere.name])


def test_names_are_unique_with_a_suffix(world):
    """Loading the same URDF twice gives cube, then cube_1."""
    first = world.load('cube_small.urdf', (1.0, 0.0, 0.5))
    second = world.load('cube_small.urdf', (2.0, 0.0, 0.5))
    assert second.name == first.name + '_1'
    with pytest.raises(WorldError, match='already in the world'):
        world.load('cube_small.urdf', name=first.name)


def test_world_state_round_trips_through_set_world_state(world, robot):
    """Place the body frame (not the centre of mass) with a world twist; read the same back."""
    pose = ((0.3, -0.2, 0.9), (0.0, 0.0, math.sin(0.4), math.cos(0.4)))
    robot.set_world_state(*pose, (0.2, 0.1, 0.0), (0.0, 0.0, 0.5))
    state = robot.world_state()
    # PyBullet keeps poses in single precision: 1e-7 relative.
    assert state.position == pytest.approx(pose[0], abs=1e-6)
    assert state.orientation == pytest.approx(pose[1], abs=1e-6)
    assert state.linear_velocity == pytest.approx((0.2, 0.1, 0.0), abs=1e-6)
    assert state.angular_velocity == pytest.approx((0.0, 0.0, 0.5), abs=1e-6)


def test_gui_without_a_display_is_one_line_not_the_end_of_the_process(monkeypatch):
    """Without a display the GUI connect would exit the interpreter: the world refuses first."""
    from r2d2_sim.physics.world import display_problem
    monkeypatch.delenv('DISPLAY', raising=False)
    with pytest.raises(WorldError, match='DISPLAY is not set'):
        SimWorld(gui=True)
    assert 'none answers' in display_problem({'DISPLAY': ':987'})
    assert 'is not one' in display_problem({'DISPLAY': 'nonsense'})


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason="Linux's abstract sockets")
def test_a_display_on_the_abstract_socket_only_answers():
    """An X server without /tmp/.X11-unix (CI's sandbox) listens on the abstract socket only."""
    from r2d2_sim.physics.world import display_problem
    number = 900 + os.getpid() % 90
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        server.bind(f'\0/tmp/.X11-unix/X{number}')
        server.listen(1)
        assert not os.path.exists(f'/tmp/.X11-unix/X{number}')
        assert display_problem({'DISPLAY': f':{number}'}) is None
    finally:
        server.close()
    assert 'none answers' in display_problem({'DISPLAY': f':{number}'})


def test_a_closed_world_refuses_use_in_one_line():
    """After close(): WorldError saying so, not an AttributeError on None; close() twice too."""
    world = SimWorld()
    world.close()
    world.close()
    with pytest.raises(WorldError, match='closed'):
        world.load('plane.urdf')
