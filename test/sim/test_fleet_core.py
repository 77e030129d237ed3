"""
Several robots in one world, without ROS: they see and touch each other, and stay their own.

Robot a stands at the origin facing +x, robot b 2 m ahead facing it. R2D2's
gripper sticks out 0.515 m ahead of base_link, so the two touch when their
base links are about 1.03 m apart; the laser plane (0.25 m up) crosses the
legs and body.
"""

import math

import pytest

from r2d2_sim.sim.settings.table import ConfigError
from r2d2_sim.sim.settings.robots import parse_world
from r2d2_sim.sim.simulation import Simulation, SpawnRequest
from r2d2_sim.physics.world import RAY_GROUPS, SimWorld

FACING = {'robots': ['a', 'b'], 'b.initial_pose': [2.0, 0.0, math.pi],
          'cmd_vel_timeout': 0.0, 'imu_rate': 0.0}
FORWARD_BEAM = 180  # of 360 from -pi: angle 0, straight ahead


def spawn_c(simulation, z):
    """Spawn our R2D2 as robot c in namespace c at (0, 2, z) through the core; return it."""
    name = simulation.spawn(SpawnRequest('c', uri='package://r2d2_sim/urdf/r2d2.urdf',
                                         namespace='c', position=(0.0, 2.0, z)))
    return next(robot for robot in simulation.robots if robot.name == name)


def x_of(robot):
    """Return the robot's true x (m)."""
    return robot.body.world_state().position[0]


def test_robots_are_entities_named_in_the_list_with_their_own_settings(make):
    """Each robot: its name, its pose, its frame prefix, its own ray group and controller."""
    simulation = make(**FACING, **{'b.max_linear_velocity': 0.2})
    a, b = simulation.robots
    assert (a.name, b.name) == ('a', 'b')
    assert simulation.entities.names() == ['ground_plane', 'a', 'b']
    assert x_of(a) == pytest.approx(0.0, abs=1e-9) and x_of(b) == pytest.approx(2.0, abs=1e-9)
    assert (a.config.frame_prefix, b.config.frame_prefix) == ('a/', 'b/')
    assert a.laser._group == RAY_GROUPS[0] and b.laser._group == RAY_GROUPS[1]
    assert a.controller is not b.controller
    assert b.controller.command(1.0, 0.0).accepted.linear_m_s == pytest.approx(0.2)
    assert a.controller.command(1.0, 0.0).accepted.linear_m_s == pytest.approx(1.0)


def test_each_laser_sees_the_other_robot_approach_and_not_itself(make):
    """The forward beam of b shortens by what a drives (each laser passes through its body)."""
    simulation = make(**FACING)
    a, b = simulation.robots
    scans = []
    a.command(0.3, 0.0)
    for _ in range(240 * 3):
        result = simulation.step()
        if result.measurements[1].scan is not None:
            scans.append((x_of(a), result.measurements[1].scan[FORWARD_BEAM],
                          result.measurements[0].scan[FORWARD_BEAM]))
    first, last = scans[0], scans[-1]
    assert first[1] < 2.0 and math.isfinite(first[1])  # b's legs, not nothing
    assert last[0] - first[0] > 0.5
    # a's leg (the near side) moves with a: b's range shrinks as much as a moves.
    assert first[1] - last[1] == pytest.approx(last[0] - first[0], abs=0.01)
    assert first[2] == pytest.approx(first[1], abs=0.01)  # symmetric: a sees b's near leg


def test_a_command_to_one_robot_never_moves_the_other(make):
    """Before contact, b's state is bit for bit what it is when a stands still."""
    def run(command_a):
        simulation = make(**FACING)
        a, b = simulation.robots
        if command_a:
            a.command(0.3, 0.0)
        for _ in range(240 * 2):  # a drives 0.5 m: still 0.45 m short of the gripper's touch
            simulation.step()
        return x_of(a), b.body.world_state(), b.read_frame(0, 0).odometry
    driven_x, driven_b, driven_odometry = run(True)
    still_x, still_b, still_odometry = run(False)
    assert driven_x > 0.45 and abs(still_x) < 0.01
    assert driven_b == still_b and driven_odometry == still_odometry
    assert driven_b.position[0] == pytest.approx(2.0, abs=0.001)


def test_the_bodies_collide_and_the_driven_one_stops_short(make):
    """Robot a pushes into b: b is shoved back, a never nearer than the grippers allow."""
    simulation = make(**FACING)
    a, b = simulation.robots
    a.command(0.3, 0.0)
    closest = math.inf
    for _ in range(240 * 6):
        simulation.step()
        closest = min(closest, x_of(b) - x_of(a))
        if x_of(b) > 2.02:  # shoved 2 cm: contact
            break
    else:
        pytest.fail(f'b never moved: a at {x_of(a):.3f} m')
    a.command(0.0, 0.0)
    for _ in range(240):
        simulation.step()
        closest = min(closest, x_of(b) - x_of(a))
    assert closest > 0.95  # gripper to gripper: 2 x 0.515 m, give or take the push
    for robot in (a, b):  # both still standing
        assert robot.body.world_state().position[2] == pytest.approx(0.47, abs=0.03)


def test_a_blown_up_robot_is_reset_alone(make):
    """Robot b flung at 1e5 m/s is put back where it started; a drives on undisturbed."""
    errors = []
    config, robots = parse_world(FACING)
    simulation = Simulation(config, robots, error=errors.append)
    try:
        a, b = simulation.robots
        a.command(0.3, 0.0)
        for _ in range(120):
            simulation.step()
        a_before = x_of(a)
        b.body.set_base_state(linear_velocity=(1e5, 0.0, 0.0))
        simulation.step()
        assert (a.blow_ups, b.blow_ups) == (0, 1)
        assert len(errors) == 1 and 'robot b ' in errors[0]
        assert x_of(b) == pytest.approx(2.0, abs=1e-6)
        assert x_of(a) > a_before
    finally:
        simulation.close()


def test_a_nan_in_one_robot_leaves_the_other_standing(make):
    """The NaN broke the ground under both: b, 2 m away, fell through it once a was put back."""
    simulation = make(**FACING)
    a, b = simulation.robots
    for _ in range(120):
        simulation.step()
    b_before = b.body.world_state()
    a.body.set_base_state(linear_velocity=(math.nan, 0.0, 0.0))
    simulation.step()
    assert (a.blow_ups, b.blow_ups) == (1, 0)
    for _ in range(240 * 3 // 2):
        simulation.step()
    for robot in (a, b):
        assert robot.body.world_state().position[2] == pytest.approx(0.47, abs=0.002)
    assert x_of(b) == pytest.approx(b_before.position[0], abs=1e-4)  # b was not put back
    assert (a.blow_ups, b.blow_ups) == (1, 0)


def test_a_robot_that_blows_up_again_and_again_is_taken_out_and_the_other_runs_on(make):
    """
    Robot a, blown up 10 times in a row, is deleted in one line; b drives on; a full reset.

    A URDF that passes every check can still blow up soon after each
    put-back (inertias of 1e-9 on a 1 kg box: every 0.7 s). It was put back
    for ever, loaded again each time, an error line each. A NaN at every step
    stands for it here; blow-ups 5 s apart are not in a row.
    """
    from r2d2_sim.sim.robots.robot import CALM_S, MAX_BLOW_UPS_IN_A_ROW
    errors = []
    simulation = make(errors, **FACING)
    a, b = simulation.robots

    def blow_up(times):
        for _ in range(times):
            a.body.set_base_state(linear_velocity=(math.nan, 0.0, 0.0))
            simulation.step()
    blow_up(MAX_BLOW_UPS_IN_A_ROW - 1)
    for _ in range(round(CALM_S * 240)):  # a stands calmly: the next blow-up is a first
        simulation.step()
    blow_up(MAX_BLOW_UPS_IN_A_ROW - 1)
    assert simulation.robots == [a, b] and a.blow_ups == 2 * MAX_BLOW_UPS_IN_A_ROW - 2
    b.command(0.3, 0.0)
    blow_up(1)
    assert simulation.robots == [b] and simulation.entities.names() == ['ground_plane', 'b']
    assert (a.blow_ups, b.blow_ups) == (2 * MAX_BLOW_UPS_IN_A_ROW - 1, 0)
    taken_out = [line for line in errors if 'taken out' in line]
    assert len(taken_out) == 1 and taken_out[0].startswith('physics blew up at t=')
    assert taken_out[0].endswith(
        f'), {MAX_BLOW_UPS_IN_A_ROW} times in a row within {CALM_S:g} s of being put back: '
        'the robot a is taken out of the world (deleted; a full reset brings it back)')
    assert len([line for line in errors if 'resetting the robot a' in line]) == \
        2 * MAX_BLOW_UPS_IN_A_ROW - 2
    b_x = x_of(b)
    for _ in range(240):
        result = simulation.step()
    assert len(result.measurements) == 1 and result.measurements[0].frame is not None
    assert x_of(b) < b_x - 0.2 and b.body.world_state().position[2] == pytest.approx(
        0.47, abs=0.01)  # facing -x, it drove 0.3 m: standing, no more blow-ups
    assert b.blow_ups == 0
    simulation.reset(time=True, state=True, spawned=True)
    assert [robot.name for robot in simulation.robots] == ['a', 'b']


def test_a_robot_spawned_at_run_time_drives_and_leaves_nothing_behind(make):
    """Spawned: at its pose exactly, driven, falls to its feet; delete frees its ray group."""
    simulation = make(**FACING)
    robot = spawn_c(simulation, 0.6)
    assert robot.name == 'c' and robot.body.spawned and robot.config.frame_prefix == 'c/'
    assert robot.laser._group == RAY_GROUPS[2]
    assert robot.footprint_height_m == pytest.approx(0.47, abs=0.005)  # from its lowest point
    robot.command(0.3, 0.0)
    for _ in range(240 * 2):
        simulation.step()
    position = robot.body.world_state().position
    assert position[0] > 0.4 and position[2] == pytest.approx(0.47, abs=0.01)
    odometry = robot.read_frame(0, 0).odometry
    assert odometry.x_m == pytest.approx(position[0], abs=0.02)  # starts at its spawn pose
    assert odometry.y_m == pytest.approx(2.0, abs=0.02)
    simulation.delete_entity('c')
    assert [r.name for r in simulation.robots] == ['a', 'b']
    assert 'c' not in simulation.entities.names() and not robot.body.alive
    assert simulation.world.take_ray_group() == RAY_GROUPS[2]  # given back


def test_allow_renaming_renames_a_robot_until_its_frames_are_free(make):
    """
    Robot a publishes its frames as c/...: a spawned robot c with allow_renaming is c_1.

    No entity is named c, so the name was kept, and the frames' clash refused the
    spawn (NAME_NOT_UNIQUE), although the standard's renaming lets it succeed.
    """
    from r2d2_sim.errors import RefusedError
    simulation = make(**{**FACING, 'a.frame_prefix': 'c/'})
    uri = 'package://r2d2_sim/urdf/r2d2.urdf'
    with pytest.raises(RefusedError, match="^NAME_NOT_UNIQUE: robot a .* prefix 'c/'"):
        simulation.spawn(SpawnRequest('c', uri=uri, namespace='c', position=(0.0, 2.0, 0.48)))
    name = simulation.spawn(SpawnRequest('c', allow_renaming=True, uri=uri, namespace='c',
                                         position=(0.0, 2.0, 0.48)))
    robot = next(robot for robot in simulation.robots if robot.name == name)
    assert name == 'c_1' and robot.config.frame_prefix == 'c_1/'
    assert simulation.entities.names() == ['ground_plane', 'a', 'b', 'c_1']


def test_a_state_reset_puts_every_robot_home_and_a_spawned_one_at_its_spawn_pose(make):
    """reset(state) keeps spawned robots; reset(spawned) deletes them, start-up ones stay."""
    simulation = make(**FACING)
    c = spawn_c(simulation, 0.48)
    for robot in simulation.robots:
        robot.command(0.3, 0.0)
    for _ in range(240):
        simulation.step()
    simulation.reset(state=True)
    assert [x_of(r) for r in simulation.robots] == pytest.approx([0.0, 2.0, 0.0], abs=1e-9)
    assert c.body.world_state().position[1] == pytest.approx(2.0, abs=1e-9)
    simulation.reset(time=True, state=True, spawned=True)
    assert [r.name for r in simulation.robots] == ['a', 'b']


def test_start_up_robots_can_be_deleted(make):
    """Any entity can be deleted, a listed robot too (more in test/sim/)."""
    simulation = make(**FACING)
    simulation.delete_entity('b')
    assert [r.name for r in simulation.robots] == ['a']


def test_a_robot_that_cannot_be_driven_is_refused_and_leaves_nothing(make):
    """A spawned robot whose wheels the settings name but its URDF lacks: OPERATION_FAILED."""
    from r2d2_sim.errors import RefusedError
    simulation = make(robots=['a'], left_wheel_names=['l'], right_wheel_names=['r'],
                      **{'a.left_wheel_names': ['left_front_wheel_joint'],
                         'a.right_wheel_names': ['right_front_wheel_joint']})
    with pytest.raises(RefusedError) as raised:
        spawn_c(simulation, 0.48)
    assert raised.value.code == 'OPERATION_FAILED' and 'c cannot be driven' in str(raised.value)
    assert simulation.entities.names() == ['ground_plane', 'a']
    assert [r.name for r in simulation.robots] == ['a']


def test_a_bad_robot_at_start_up_is_one_line_naming_it(make):
    """A robot's own bad value names the robot; the world is closed again."""
    with pytest.raises(ConfigError) as raised:
        make(robots=['a', 'b'], **{'b.urdf': 'cube.urdf', 'b.left_wheel_names': ['x'],
                                   'b.right_wheel_names': ['y']})
    assert '\n' not in str(raised.value) and 'x' in str(raised.value)


def test_the_ray_groups_run_out_after_29_robots_with_a_laser():
    """Bullet's group is a C int: bits 2-30 tell 29 robots' rays apart; then one line."""
    with SimWorld(ground_plane=False) as world:
        taken = [world.take_ray_group() for _ in range(29)]
        assert taken == list(RAY_GROUPS) and taken[-1] == 2**30
        with pytest.raises(Exception) as raised:
            world.take_ray_group()
        assert '29 robots with a laser' in str(raised.value)
        world.release_ray_group(taken[3])
        assert world.take_ray_group() == taken[3]
