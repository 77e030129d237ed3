"""
The simulation core without ROS: what each step measures, when, and how a blow-up is put right.

:meth:`Simulation.step` returns plain data (None when nothing is due), so
these tests read it directly: no rclpy context, no subscriber.
"""

import math

import pytest


QUIET = {'scan_rate': 0.0, 'imu_rate': 0.0, 'camera_rate': 0.0}


def test_nothing_is_returned_between_publications(make):
    """At 60 Hz of 240, three steps give None and the fourth the state at step 4."""
    simulation = make(publish_rate=60.0, **QUIET)
    results = [simulation.step() for _ in range(8)]
    assert [r is None for r in results] == [True, True, True, False] * 2
    result = results[3]
    assert (result.step, result.time_ns, result.state_due) == (4, 4 * 10**9 // 240, True)
    frame = result.measurements[0].frame
    assert (frame.step, frame.time_ns) == (4, result.time_ns)
    assert len(frame.joints.positions) == len(simulation.robot.movable)


def test_sensors_are_measured_at_their_own_rates(make):
    """Scan at 10 Hz (every 24 steps), IMU at 100 Hz (2.4 steps), camera at 5 Hz; state never."""
    simulation = make(publish_rate=1.0, scan_rate=10.0, imu_rate=100.0, camera_rate=5.0,
                      camera_width=8, camera_height=6)
    seen = {'scan': [], 'imu': [], 'image': []}
    for _ in range(48):
        result = simulation.step()
        if result is None:
            continue
        assert not result.state_due
        measurement = result.measurements[0]
        assert measurement.frame is None and measurement.time_ns == result.time_ns
        for name in seen:
            if getattr(measurement, name) is not None:
                seen[name].append(result.step)
    assert seen['scan'] == [24, 48]
    assert seen['imu'] == [math.ceil(n * 2.4) for n in range(1, 21)]
    assert seen['image'] == [48]
    scan = simulation.step() or None  # step 49: nothing due
    assert scan is None


def test_readings_are_plain_data(make):
    """A scan is an array of REP-117 ranges, an image rgb bytes, an IMU reading a tuple."""
    simulation = make(scan_rate=240.0, imu_rate=240.0, camera_rate=240.0, camera_width=8,
                      camera_height=6, camera_depth=True)
    measurement = simulation.step().measurements[0]
    assert measurement.scan.dtype.name == 'float32' and len(measurement.scan) == 360
    assert len(measurement.image.rgb) == 8 * 6 * 3 and measurement.image.depth.shape == (6, 8)
    assert measurement.imu.linear_acceleration_m_s2[2] == pytest.approx(9.8, abs=0.5)


def test_the_imu_sees_the_robot_land_then_rest_as_limits_md_says(make):
    """Set down 1 mm up: the second 100 Hz sample is the landing; from 0.05 s on, 9.8 +- 0.005."""
    simulation = make(scan_rate=0.0, imu_rate=100.0, camera_rate=0.0)
    samples = []
    for _ in range(240):
        result = simulation.step()
        if result is not None and result.measurements[0].imu is not None:
            samples.append((result.time_ns / 1e9, result.measurements[0].imu))
    z = [(time_s, imu.linear_acceleration_m_s2[2]) for time_s, imu in samples]
    assert z[0][1] == pytest.approx(9.8, abs=1e-9) and z[1][1] == pytest.approx(24.5, abs=0.1)
    assert all(value == pytest.approx(9.8, abs=0.005) for time_s, value in z if time_s >= 0.05)


def test_a_kept_frame_does_not_change_afterwards(make):
    """Frame.odometry is a snapshot, not the live odometry object."""
    simulation = make(cmd_vel_timeout=0.0, **QUIET)
    simulation.robot.command(0.5, 0.0)
    first = simulation.step().measurements[0].frame
    kept = first.odometry
    for _ in range(120):
        last = simulation.step().measurements[0].frame
    assert first.odometry == kept
    assert last.odometry.x_m > kept.x_m + 0.01


def test_a_blow_up_between_publications_resets_the_robot_and_says_why(make):
    """Caught by the every-step check; the next state published is the reset robot."""
    errors = []
    simulation = make(errors, publish_rate=10.0, **QUIET)
    start_z = simulation.robot.body.world_state().position[2]
    simulation.robot.command(0.3, 0.0)
    for _ in range(12):
        simulation.step()
    simulation.robot.body.set_base_state(linear_velocity=(math.nan, 0.0, 0.0))
    assert simulation.step() is None  # step 13: no publication, the check still ran
    assert simulation.blow_ups == 1
    assert 'is not finite' in errors[0] and 'resetting the robot' in errors[0]
    for _ in range(11):
        result = simulation.step()
    frame = result.measurements[0].frame
    assert all(map(math.isfinite, frame.base.linear_velocity))
    assert frame.base.position[0] == pytest.approx(0.0, abs=1e-3)  # back at the start
    assert simulation.robot.controller.target == (0.0, 0.0)        # command dropped
    for _ in range(240 * 3 // 2):  # 1.5 s later it stands there: it fell through the ground
        result = simulation.step()
    assert start_z == pytest.approx(0.47, abs=0.01)
    assert result.measurements[0].frame.base.position[2] == pytest.approx(start_z, abs=0.002)


@pytest.mark.parametrize('nan_steps', [1, 2, 3])
def test_a_nan_breaks_the_ground_too_and_both_are_put_back(make, nan_steps):
    """
    The NaN spreads to the ground plane; both are loaded again, and the robot stands and drives.

    One step with a NaN (the node's check catches it at once) made the
    ground plane's pose NaN: the robot put back fell through it. After more
    such steps (taken here past the check) a robot put back in place sank
    through the ground all the same: it is loaded again.
    """
    errors = []
    simulation = make(errors, cmd_vel_timeout=0.0, **QUIET)
    robot, plane = simulation.robot, simulation.world.bodies['ground_plane']
    start = robot.body.world_state()
    robot.command(0.3, 0.0)
    for _ in range(120):
        simulation.step()
    robot.body.set_base_state(linear_velocity=(math.nan, 0.0, 0.0))
    simulation.world.step(nan_steps - 1)  # the physics alone: no check
    simulation.step()
    assert simulation.blow_ups == 1
    assert robot.body.world_state() == start
    for _ in range(240 * 3 // 2):
        simulation.step()
    assert robot.body.world_state().position[2] == pytest.approx(start.position[2], abs=0.002)
    assert plane.world_state().position == (0.0, 0.0, 0.0)
    assert list(simulation.world.bodies) == ['ground_plane', 'r2d2']  # in their load order
    assert len(errors) == 2 and 'ground_plane was broken with it' in errors[1]
    robot.command(0.3, 0.0)
    for _ in range(240):
        simulation.step()
    position = robot.body.world_state().position
    assert position[0] > 0.2 and position[2] == pytest.approx(start.position[2], abs=0.002)
    assert simulation.blow_ups == 1


def test_a_run_after_a_nan_blow_up_repeats_bit_for_bit(make):
    """The same commands and the same NaN at the same step: the same states to the bit."""
    def run():
        simulation = make(cmd_vel_timeout=0.0, **QUIET)
        simulation.robot.command(0.3, 0.0)
        for _ in range(120):
            simulation.step()
        simulation.robot.body.set_base_state(linear_velocity=(math.nan, 0.0, 0.0))
        states = []
        for step in range(720):
            if step == 240:
                simulation.robot.command(0.3, 0.2)
            simulation.step()
            states.append(simulation.robot.body.world_state())
        assert simulation.blow_ups == 1
        return states
    first, second = run(), run()
    assert first == second
    assert first[-1].position[2] == pytest.approx(0.47, abs=0.01)


def test_a_body_that_cannot_be_loaded_again_is_reset_in_place_and_the_run_goes_on(
        make, monkeypatch):
    """
    A reload that fails leaves the body in the world, reset in place; every other is put back.

    Before, the robot's reload failing escaped the step with the body gone
    from the world (the Robot still in it), the NaN ground never put back,
    and every later step raised BodyRemoved.
    """
    from r2d2_sim.errors import WorldError
    from r2d2_sim.physics.body import Body

    def failing(body, client):
        raise WorldError(f'PyBullet cannot load {body.source} again: (simulated)')
    errors = []
    simulation = make(errors, cmd_vel_timeout=0.0, **QUIET)
    robot, plane = simulation.robot, simulation.world.bodies['ground_plane']
    start = robot.body.world_state()
    for _ in range(20):
        simulation.step()
    monkeypatch.setattr(Body, '_load_into', failing)
    robot.body.set_base_state(linear_velocity=(math.nan, 0.0, 0.0))
    simulation.step()
    assert simulation.blow_ups == 1
    assert list(simulation.world.bodies) == ['ground_plane', 'r2d2']
    assert simulation.robots == [robot] and robot.body.alive
    assert robot.body.world_state() == start and plane.finite()
    assert len(errors) == 3 and all('\n' not in line for line in errors)
    assert 'the robot r2d2 is reset in place, not loaded again' in errors[1]
    assert errors[2].startswith('physics blew up: ground_plane was broken with it and is reset '
                                'in place where it started, not loaded again (PyBullet cannot')
    for _ in range(10):
        simulation.step()
    assert simulation.blow_ups == 1


def test_a_blown_up_robot_is_reset_alone(make):
    """A cube the robot pushed keeps its place when the robot is put back."""
    simulation = make(extra_models=['cube_small.urdf 0.3 0 0.025'], **QUIET)
    cube = simulation.models[0]
    cube.set_base_state(position=(0.3, 0.5, 0.025))
    simulation.robot.body.set_base_state(position=(1e5, 0.0, 0.5))
    simulation.step()
    assert simulation.blow_ups == 1
    assert cube.world_state().position[1] == pytest.approx(0.5, abs=1e-3)
    assert simulation.robot.body.world_state().position[0] == pytest.approx(0.0, abs=1e-3)


def test_reset_puts_every_body_back_and_keeps_time(make):
    """Simulation.reset: robot and extra bodies where they started; the clock goes on."""
    simulation = make(extra_models=['cube_small.urdf 0.8 0 0.025'], cmd_vel_timeout=0.0,
                      **QUIET)
    start = simulation.robot.body.world_state()
    simulation.robot.command(0.5, 0.0)
    for _ in range(240):
        simulation.step()
    simulation.models[0].set_base_state(position=(3.0, 3.0, 0.025))
    simulation.reset()
    assert simulation.robot.body.world_state() == start
    cube = simulation.models[0]
    assert cube.world_state().position == pytest.approx((0.8, 0, 0.025))
    assert simulation.step_count == 240
    frame = simulation.step().measurements[0].frame
    assert frame.odometry.x_m == pytest.approx(0.0, abs=1e-3)
