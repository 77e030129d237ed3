"""
The ground plane ends 100 m from the origin: a robot past its edge would fall for ever.

No ROS. pybullet_data's plane.urdf collides as a box 200 x 200 x 10 m; it is
kept as it is (every contact and pinned recording depends on it). A robot
whose start or spawn pose is off it, and a spawned body that can fall, are
refused in one line; a robot that gets there all the same (a teleport, a
drive off the edge) is said to be falling, once, in one error line, its
physics left as it is.
"""

import math

import pytest

from r2d2_sim.errors import RefusedError, WorldError
from r2d2_sim.sim.simulation import SpawnRequest
from r2d2_sim.sim.spawnables import box_urdf

R2D2 = 'package://r2d2_sim/urdf/r2d2.urdf'
SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'scan_rate': 0.0, 'imu_rate': 0.0}
OFF = 'off the ground plane (x and y from -100 to 100 m)'
UPRIGHT = (0.0, 0.0, 0.0, 1.0)
ZERO = (0.0, 0.0, 0.0)


def test_the_ground_plane_is_200_m_wide(make):
    """What the refusals say: plane.urdf's box, 10 m deep, its top at z 0."""
    from r2d2_sim.sim.robots.robot import FALLEN_DEPTH_M
    low, high = make().world.bodies['ground_plane'].bounds()
    assert low == pytest.approx((-100.0, -100.0, -10.0), abs=2e-3)
    assert high == pytest.approx((100.0, 100.0, 0.0), abs=2e-3)
    assert FALLEN_DEPTH_M == 10.0


@pytest.mark.parametrize('parameters, message', [
    ({'initial_pose': [150.0, 0.0, 0.0]},
     f'initial_pose puts the robot at x 150, y 0, {OFF}: it would fall for ever'),
    ({'robots': ['a', 'b'], 'b.initial_pose': [3.0, -100.5, 1.0]},
     f'robot b: initial_pose puts the robot at x 3, y -100.5, {OFF}: it would fall for ever'),
])
def test_a_start_off_the_ground_is_refused_in_one_line(make, parameters, message):
    with pytest.raises(WorldError) as refused:
        make(**parameters)
    assert str(refused.value) == message


def test_without_the_ground_plane_a_start_anywhere_is_taken(make):
    """No ground plane: the user's world brings its own floor, which may reach anywhere."""
    simulation = make(ground_plane=False, gravity=[0.0, 0.0, 0.0], initial_pose=[150.0, 0.0, 0.0])
    assert simulation.robot.body.world_pose()[0][0] == pytest.approx(150.0)
    make(initial_pose=[99.0, -100.0, 0.0])  # on the ground, at its edge


def test_a_world_whose_start_pose_is_off_the_ground_is_refused(make, tmp_path):
    """The robots would stand 150 m out: refused before anything is built, the world as it was."""
    (tmp_path / 'far.world.yaml').write_text(
        'r2d2_sim_world: 1\nname: far\nstart_pose: out\n'
        'named_poses:\n  - {name: out, position: [150.0, 2.0, 0.0], yaw: 0.0}\n')
    simulation = make(world_paths=[str(tmp_path)])
    before = simulation.entities.names()
    with pytest.raises(RefusedError) as refused:
        simulation.load_world(str(tmp_path / 'far.world.yaml'))
    assert refused.value.code == 'OPERATION_FAILED'
    assert refused.value.message == (
        f"the world's start pose: initial_pose puts the robot at x 150, y 2, {OFF}: it would "
        'fall for ever')
    assert simulation.entities.names() == before and simulation.robot.body.alive


@pytest.mark.parametrize('request_, falls', [
    (SpawnRequest('c', uri=R2D2, namespace='c', position=(150.0, 0.0, 0.48)), True),
    (SpawnRequest('box', resource_string=box_urdf(mass_kg=1.0), position=(0.0, 120.0, 0.1)),
     True),
    (SpawnRequest('wall', resource_string=box_urdf(), position=(0.0, 120.0, 0.1)), False),
])
def test_a_spawn_off_the_ground_that_would_fall_is_refused(make, request_, falls):
    """A robot and a loose box are refused; a fixed wall out there stays where it is put."""
    simulation = make()
    before = list(simulation.world.bodies)
    if not falls:
        simulation.spawn(request_)
        assert list(simulation.world.bodies) == before + [request_.name]
        return
    with pytest.raises(RefusedError) as refused:
        simulation.spawn(request_)
    x, y, _ = request_.position
    assert refused.value.code == 'INVALID_POSE'
    assert refused.value.message == (f'{request_.name} at x {x:g}, y {y:g} would be {OFF} and '
                                     'fall for ever')
    assert list(simulation.world.bodies) == before and len(simulation.robots) == 1


def test_a_robot_falling_off_the_edge_is_said_to_once_a_fall(make):
    """
    Teleported 150 m out: one error line within 3 s, none after; the physics as it was.

    Put back on the ground and out again, it falls again: said again.
    """
    errors = []
    simulation = make(errors=errors)
    body = simulation.robot.body

    def fall_for(seconds):
        simulation.set_entity_state('r2d2', '', (150.0, 0.0, 0.5), UPRIGHT, ZERO, ZERO)
        for _ in range(240 * seconds):
            simulation.step()
    fall_for(3)
    assert len(errors) == 1 and errors[0].startswith(
        'robot r2d2 is falling with nothing under it: at t=2.000 s its base is at z -15.')
    assert errors[0].endswith(f'below z 0, at x 150.0, y 0.0, {OFF}; it falls on until it is '
                              'reset or moved')
    for _ in range(240 * 5):
        simulation.step()
    assert len(errors) == 1 and body.world_pose()[0][2] < -60.0 and simulation.blow_ups == 0
    simulation.set_entity_state('r2d2', '', (0.0, 0.0, 0.5), UPRIGHT, ZERO, ZERO)
    fall_for(3)
    assert len(errors) == 2 and math.isclose(body.world_pose()[0][0], 150.0, abs_tol=1e-3)


def test_the_edge_moves_with_the_ground_plane(make):
    """
    Move the plane with SetEntityState, as any static body: the edge is measured from there.

    Moved to x 300, a loose box spawned at (0, 2) was taken and fell for ever,
    and one at (300, 0), on the plane, was refused as off it.
    """
    simulation = make()
    simulation.set_entity_state('ground_plane', '', (300.0, 0.0, 0.0), UPRIGHT, ZERO, ZERO)
    loose = box_urdf(mass_kg=1.0)
    with pytest.raises(RefusedError) as refused:
        simulation.spawn(SpawnRequest('off', resource_string=loose, position=(0.0, 2.0, 0.1)))
    assert (refused.value.code, refused.value.message) == (
        'INVALID_POSE', 'off at x 0, y 2 would be off the ground plane (x from 200 to 400 m, '
                        'y from -100 to 100 m) and fall for ever')
    simulation.spawn(SpawnRequest('on', resource_string=loose, position=(300.0, 0.0, 0.1)))
    # Turned 45 degrees about its centre at the origin: its corners reach 141 m along x.
    turned = (0.0, 0.0, math.sin(math.pi / 8), math.cos(math.pi / 8))
    simulation.set_entity_state('ground_plane', '', ZERO, turned, ZERO, ZERO)
    simulation.spawn(SpawnRequest('corner', resource_string=loose, position=(130.0, 0.0, 0.1)))
    with pytest.raises(RefusedError) as refused:
        simulation.spawn(SpawnRequest('side', resource_string=loose, position=(95.0, 95.0, 0.1)))
    assert refused.value.message == ('side at x 95, y 95 would be off the ground plane (turned, '
                                     '100 m to each side of its centre at x 0, y 0) and fall '
                                     'for ever')
    for _ in range(240):
        simulation.step()
    assert simulation.world.bodies['corner'].world_pose()[0][2] > 0.0  # it stands on it
