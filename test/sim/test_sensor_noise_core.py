"""
Each sensor's noise parameters reach its readings, and every stream follows the seed.

No ROS: robots in the core, standing in the room (walls at known distances)
or driving. Each family of noise parameters (laser, IMU per quantity, wheel
encoders, depth) is checked on at least 10,000 readings against the exact
readings of the same world; the streams are each a sensor's own (turning
another sensor's noise on, or listing the robots in another order, leaves a
robot's noise as it was), and a full reset starts all of them again.
"""

import math

import numpy
import pytest

from r2d2_sim.sim.settings.table import ConfigError
from r2d2_sim.sim.settings.config import parse_config
from r2d2_sim.sim.settings.robots import parse_world
from r2d2_sim.sim.simulation import Simulation

ROOM = 'package://r2d2_sim/urdf/room.urdf'
SCANS = 30  # x 360 beams


def laser_errors(make, **noise):
    """Return noisy minus exact ranges over SCANS scans of a robot standing in the room."""
    exact = make(world=ROOM).robot.laser.scan()
    laser = make(world=ROOM, **noise).robot.laser
    assert numpy.isfinite(exact).all()
    return numpy.concatenate([laser.scan().astype(float) - exact for _ in range(SCANS)]), laser


def test_laser_noise_parameters_reach_the_ranges(make):
    errors, laser = laser_errors(make, scan_noise_mean=0.02, scan_noise_std=0.01,
                                 scan_noise_bias_mean=0.05, scan_noise_bias_std=0.001,
                                 noise_seed=3)
    bias = laser._noise.bias[0]
    assert abs(bias) == pytest.approx(0.05, abs=0.004)
    assert errors.mean() == pytest.approx(0.02 + bias, rel=0.02)
    assert errors.std() == pytest.approx(0.01, rel=0.02)


def test_laser_precision_rounds_every_range(make):
    laser = make(world=ROOM, scan_noise_std=0.01, scan_noise_precision=0.01).robot.laser
    ranges = laser.scan().astype(float)
    assert numpy.allclose(ranges, numpy.round(ranges / 0.01) * 0.01, atol=1e-6)  # float32


def test_the_laser_bias_takes_both_signs_over_seeds(make):
    exact = make(world=ROOM).robot.laser.scan()
    signs = set()
    for seed in range(8):
        ranges = make(world=ROOM, scan_noise_bias_mean=0.1, noise_seed=seed).robot.laser.scan()
        error = float(numpy.mean(ranges - exact))
        assert abs(error) == pytest.approx(0.1, abs=1e-5)
        signs.add(error > 0)
    assert signs == {True, False}


def test_laser_drift_moves_between_scans(make):
    laser = make(world=ROOM, scan_noise_dynamic_bias_std=0.05,
                 scan_noise_dynamic_bias_correlation_time=100.0).robot.laser
    exact = make(world=ROOM).robot.laser.scan()
    offsets = [float(numpy.mean(laser.scan() - exact)) for _ in range(50)]
    assert len(set(offsets)) == 50
    assert offsets[0] != 0.0


def imu_readings(robot, count):
    """Return (orientations, angular, linear) of ``count`` readings of a robot at rest."""
    robot.imu.reset()  # its own times from here on
    readings = [robot.imu.read(0.01 * (k + 1)) for k in range(count)]
    return tuple(numpy.array([getattr(r, name) for r in readings]) for name in (
        'orientation_xyzw', 'angular_velocity_rad_s', 'linear_acceleration_m_s2'))


@pytest.mark.parametrize('quantity, index, exact_value', [
    ('imu_angular_velocity', 1, (0.0, 0.0, 0.0)),
    ('imu_linear_acceleration', 2, (0.0, 0.0, 9.8)),
])
def test_imu_noise_parameters_reach_each_axis(make, quantity, index, exact_value):
    """4,000 readings x 3 axes: each axis has its own bias, all the same spread."""
    simulation = make(**{f'{quantity}_noise_std': 0.02, f'{quantity}_noise_bias_mean': 0.3,
                         f'{quantity}_noise_precision': 0.0001, 'noise_seed': 5})
    for _ in range(240):  # settle at rest
        simulation.step()
    values = imu_readings(simulation.robot, 4000)[index]
    model = simulation.robot.imu.model
    bias = {'imu_angular_velocity': model._angular, 'imu_linear_acceleration': model._linear}[
        quantity].bias
    errors = values - numpy.array(exact_value)
    assert numpy.allclose(numpy.abs(bias), 0.3)
    assert errors.mean(axis=0) == pytest.approx(bias, abs=0.02 * 0.3 + 0.002)
    assert errors.std(axis=0) == pytest.approx([0.02] * 3, rel=0.02)
    assert numpy.allclose(values, numpy.round(values / 0.0001) * 0.0001, atol=1e-12)


def test_imu_orientation_noise_is_a_rotation_per_axis(make):
    simulation = make(imu_orientation_noise_std=0.01, imu_orientation_noise_bias_mean=0.05)
    for _ in range(240):
        simulation.step()
    orientations = imu_readings(simulation.robot, 4000)[0]
    # Small rotations about the world axes of a level robot: x, y ~ half the angle.
    angles = 2.0 * orientations[:, :3] / orientations[:, 3:4]
    bias = simulation.robot.imu.model._orientation.bias
    assert angles[:, :2].mean(axis=0) == pytest.approx(bias[:2], abs=0.002)
    assert angles[:, :2].std(axis=0) == pytest.approx([0.01, 0.01], rel=0.03)


def test_imu_orientation_precision_rounds_the_heading_it_reports(make):
    """A robot turning: each reading's yaw is a multiple of the precision, the true one rounded."""
    from r2d2_sim.model.transforms import yaw_of
    simulation = make(cmd_vel_timeout=0.0, imu_orientation_noise_precision=0.1)
    simulation.robot.command(0.0, 0.5)
    headings = set()
    for _ in range(480):
        simulation.step()
        simulation.robot.imu.reset()  # read again at a time it may have read at
        reading = simulation.robot.imu.read(simulation.time_ns / 1e9)
        yaw = yaw_of(reading.orientation_xyzw)
        true_yaw = yaw_of(simulation.robot.body.world_state().orientation)
        assert yaw / 0.1 == pytest.approx(round(yaw / 0.1), abs=1e-9)
        assert abs(yaw - true_yaw) <= 0.05 + 1e-9
        headings.add(round(yaw, 6))
    assert len(headings) > 3  # it turned through several steps


def drive_straight(simulation, steps=720):
    simulation.robot.command(0.4, 0.0)
    for _ in range(steps):
        simulation.step()
    return simulation.robot.read_frame(simulation.step_count, simulation.time_ns).odometry


def test_encoder_bias_scales_the_odometry_the_physics_left_alone(make):
    """The same drive (bit for bit) with biased encoders: odometry travels (1 + bias) as far."""
    exact = make(cmd_vel_timeout=0.0)
    noisy = make(cmd_vel_timeout=0.0, encoder_noise_bias_mean=0.02, noise_seed=1)
    left_bias, right_bias = noisy.robot.controller.encoders.bias
    odometry = [drive_straight(simulation) for simulation in (exact, noisy)]
    assert exact.robot.body.world_state() == noisy.robot.body.world_state()
    assert abs(left_bias) == abs(right_bias) == pytest.approx(0.02)
    travelled = [math.hypot(o.x_m, o.y_m) for o in odometry]
    assert travelled[1] / travelled[0] == pytest.approx(1.0 + (left_bias + right_bias) / 2,
                                                        abs=2e-3)
    assert odometry[0].pose_covariance is None
    assert odometry[1].pose_covariance[0] > 0.0 and odometry[1].twist_covariance[0] > 0.0


def test_encoder_ticks_make_the_odometry_move_in_steps(make):
    tick = 2.0 * math.pi / 64
    simulation = make(cmd_vel_timeout=0.0, encoder_noise_precision=tick)
    radius = simulation.robot.drive.geometry.wheel_radius_m
    simulation.robot.command(0.05, 0.0)
    seen = set()
    for _ in range(240):
        simulation.step()
        seen.add(round(simulation.robot.controller.odometry.distance_m / (radius * tick), 6))
    assert all(value == int(value) for value in seen) and len(seen) > 2


def depth_errors(make, images=4, **noise):
    parameters = dict(world=ROOM, camera_rate=10.0, camera_depth=True, camera_width=80,
                      camera_height=60)
    exact = make(**parameters).robot.camera.render(depth=True).depth
    camera = make(**parameters, **noise).robot.camera
    seen = numpy.isfinite(exact)  # the room has walls, no ceiling
    assert seen.sum() > 1000
    images = [camera.render(depth=True).depth for _ in range(images)]
    assert all(numpy.array_equal(numpy.isfinite(image), seen) for image in images)
    return numpy.concatenate([image[seen].astype(float) - exact[seen] for image in images]), camera


def test_depth_noise_parameters_reach_every_pixel(make):
    """4 images of 80 x 60, the pixels that see a wall: over 10,000; +inf stays +inf."""
    errors, camera = depth_errors(make, depth_noise_std=0.01, depth_noise_bias_mean=0.04,
                                  noise_seed=2)
    assert len(errors) > 10_000
    bias = camera._depth_noise.bias[0]
    assert abs(bias) == pytest.approx(0.04)
    assert errors.mean() == pytest.approx(bias, rel=0.02)
    assert errors.std() == pytest.approx(0.01, rel=0.02)


def test_each_sensor_has_a_stream_of_its_own(make):
    """The laser's noise is the same with and without IMU and depth noise on."""
    alone = make(world=ROOM, scan_noise_std=0.01).robot.laser.scan()
    crowded = make(world=ROOM, scan_noise_std=0.01, imu_angular_velocity_noise_std=0.1,
                   encoder_noise_std=0.01, camera_rate=10.0, camera_depth=True,
                   depth_noise_std=0.1, camera_width=16, camera_height=12).robot
    crowded.camera.render(depth=True)
    crowded.imu.read(0.01)
    assert numpy.array_equal(crowded.laser.scan(), alone)


def test_a_robots_noise_does_not_depend_on_the_order_robots_are_listed_in(make):
    """Robots a and b listed either way: each reads the same noisy scan, by its name."""
    poses = {'a.initial_pose': [0.0, -0.8, 0.0], 'b.initial_pose': [0.0, 0.8, 0.0]}
    scans = []
    for order in (['a', 'b'], ['b', 'a']):
        simulation = make(world=ROOM, robots=order, scan_noise_std=0.01, **poses)
        scans.append({robot.name: robot.laser.scan() for robot in simulation.robots})
    assert numpy.array_equal(scans[0]['a'], scans[1]['a'])
    assert numpy.array_equal(scans[0]['b'], scans[1]['b'])
    assert not numpy.array_equal(scans[0]['a'] - scans[0]['b'], 0.0)


ALL_NOISE = {'scan_noise_std': 0.01, 'scan_noise_bias_mean': 0.01,
             'scan_noise_dynamic_bias_std': 0.01, 'scan_noise_dynamic_bias_correlation_time': 10.0,
             'imu_angular_velocity_noise_std': 0.01, 'imu_angular_velocity_noise_bias_std': 0.01,
             'imu_linear_acceleration_noise_std': 0.1, 'imu_orientation_noise_std': 0.01,
             'imu_linear_acceleration_noise_dynamic_bias_std': 0.01,
             'imu_linear_acceleration_noise_dynamic_bias_correlation_time': 100.0,
             'encoder_noise_std': 0.02, 'encoder_noise_bias_std': 0.01,
             'encoder_noise_dynamic_bias_std': 0.01,
             'encoder_noise_dynamic_bias_correlation_time': 60.0,
             'encoder_noise_precision': 0.001,
             'camera_rate': 24.0, 'camera_depth': True, 'camera_width': 16, 'camera_height': 12,
             'depth_noise_std': 0.01, 'depth_noise_bias_mean': 0.01,
             'depth_noise_precision': 0.001,
             'world': ROOM, 'cmd_vel_timeout': 0.0, 'noise_seed': 7}


def noisy_run(simulation, steps=240):
    """Drive 1 s and record every noisy reading: scans, IMU, depth, odometry."""
    simulation.robot.command(0.3, 0.4)
    seen = []
    for _ in range(steps):
        result = simulation.step()
        if result is None:
            continue
        m = result.measurements[0]
        seen.append((result.step, None if m.scan is None else m.scan.tobytes(), m.imu,
                     None if m.image is None else m.image.depth.tobytes(),
                     None if m.frame is None else m.frame.odometry))
    return seen


def test_a_full_reset_repeats_every_noisy_reading(make):
    simulation = make(**ALL_NOISE)
    first = noisy_run(simulation)
    assert all(any(entry[i] is not None for entry in first) for i in range(1, 5))
    simulation.reset(time=True, state=True, spawned=True)
    assert noisy_run(simulation) == first


def test_a_full_reset_repeats_the_run_of_a_fresh_start_that_published_at_time_0(make):
    """The node publishes the state at start-up (a read at t = 0), not after a reset: alike."""
    simulation = make(**ALL_NOISE)
    simulation.read_states()  # as SimNode does once built
    first = noisy_run(simulation)
    simulation.reset(time=True, state=True, spawned=True)
    assert noisy_run(simulation) == first


def test_a_state_reset_goes_on_with_the_streams(make):
    simulation = make(**ALL_NOISE)
    first = noisy_run(simulation)
    simulation.reset(time=True, state=True)  # not as launched: the noise goes on
    assert noisy_run(simulation) != first


@pytest.mark.parametrize('parameters, message', [
    ({'scan_noise_bias_std': -0.1}, r'parameter scan_noise_bias_std must be in \[0, 10\] m'),
    ({'imu_angular_velocity_noise_mean': 11.0},
     r'parameter imu_angular_velocity_noise_mean must be in \[-10, 10\] rad/s'),
    ({'encoder_noise_dynamic_bias_std': 0.1},
     'encoder_noise_dynamic_bias_std needs encoder_noise_dynamic_bias_correlation_time > 0'),
    ({'depth_noise_precision': 'fine'}, 'parameter depth_noise_precision must be a number'),
    ({'encoder_noise_precision': 7.0}, r'must be in \[0, 6.28318\] rad'),
])
def test_bad_noise_parameters_are_refused_in_one_line(parameters, message):
    with pytest.raises(ConfigError, match=message) as info:
        parse_config(parameters)
    assert '\n' not in str(info.value)


def test_noise_is_set_per_robot():
    config, robots = parse_world({'robots': ['a', 'b'], 'b.initial_pose': [2.0, 0.0, 0.0],
                                  'a.scan_noise_bias_mean': 0.2, 'scan_noise_std': 0.01})
    a, b = (robot.config.noise('scan') for robot in robots)
    assert (a.bias_mean, a.stddev) == (0.2, 0.01) and (b.bias_mean, b.stddev) == (0.0, 0.01)
    with pytest.raises(ConfigError,
                       match='robot b: parameter encoder_noise_dynamic_bias_std needs'):
        parse_world({'robots': ['b'], 'b.encoder_noise_dynamic_bias_std': 0.1})


def test_the_imu_reads_the_same_with_or_without_a_frame_read_that_step(make):
    # With the state published every step the IMU takes the frame's own read of the
    # base (one query pair fewer); published once a second, it reads the body itself.
    # Bit for bit the same readings, noise and all.
    noise = dict(imu_rate=120.0, noise_seed=5, cmd_vel_timeout=0.0,
                 imu_angular_velocity_noise_std=0.01, imu_linear_acceleration_noise_std=0.05,
                 imu_orientation_noise_std=0.01)
    readings = []
    for publish_rate in (0.0, 1.0):
        simulation = make(publish_rate=publish_rate, **noise)
        simulation.robot.command(0.4, 0.6)
        seen = []
        for _ in range(240):
            result = simulation.step()
            if result is not None and result.measurements[0].imu is not None:
                seen.append((result.step, result.measurements[0].frame is not None,
                             result.measurements[0].imu))
        readings.append(seen)
    every_step, rarely = readings
    assert len(every_step) == len(rarely) == 120
    assert all(framed for _, framed, _ in every_step)
    assert sum(framed for _, framed, _ in rarely) <= 2
    assert [(step, imu) for step, _, imu in every_step] == [(step, imu) for step, _, imu in rarely]


def _odometry_run(simulation, steps=100):
    """Drive a curve; return each state publication's odometry (x, y, yaw)."""
    out = []
    for step in range(steps):
        if step % 50 == 0:
            simulation.robot.command(0.3, 0.4)
        result = simulation.step()
        if result is not None and result.state_due:
            out.append(result.measurements[0].frame.odometry[:3])
    return out


def test_encoder_noise_after_load_world_repeats_a_launch():
    """The encoders' first interval after load_world errs as after start-up (it read exact)."""
    values = dict(encoder_noise_std=0.05, noise_seed=7, world='room.world.yaml',
                  publish_rate=50.0)
    config, robots = parse_world(values)
    launched = Simulation(config, robots)
    try:
        expected = _odometry_run(launched)
    finally:
        launched.close()
    exact_config, _ = parse_world(dict(values, encoder_noise_std=0.0))
    exact = Simulation(exact_config, robots)
    try:
        assert _odometry_run(exact)[0] != expected[0]  # the noise shows from the first
    finally:
        exact.close()
    loaded = Simulation(config, robots)
    try:
        for _ in range(100):
            loaded.step()
        loaded.load_world('room.world.yaml')
        assert _odometry_run(loaded) == expected
    finally:
        loaded.close()


def _frames(simulation, steps):
    """Step ``steps`` times; return each step's odometry (a state is published every step)."""
    return [simulation.step().measurements[0].frame.odometry for _ in range(steps)]


BIASED = {'encoder_noise_bias_mean': 0.05}


@pytest.mark.parametrize('before, restart', [
    (BIASED, {}),                                       # the same noise, its streams again
    (BIASED, {'encoder_noise_std': 0.01}),              # more noise
    (BIASED, {'encoder_noise_bias_mean': 0.0}),         # exact from now on
    ({}, BIASED),                                       # erring from now on
], ids=['same', 'more', 'off', 'on'])
def test_odometry_goes_on_without_a_jump_when_the_noise_restarts(make, before, restart):
    """
    4 s at 0.5 m/s, restart_noise: the next step moves odometry by one step's travel.

    Fresh encoders counted from the true wheel angle while odometry's baseline
    was the old encoders' count: odom x went back by their whole error so far
    (1.97 -> 1.88 m in one step, -22 m/s).
    """
    simulation = make(cmd_vel_timeout=0.0, noise_seed=1, **before)
    simulation.robot.command(0.5, 0.0)
    last = _frames(simulation, 960)[-1]
    assert last.linear_m_s == pytest.approx(0.5, rel=0.1)
    simulation.restart_noise(1, **restart)
    for odometry in _frames(simulation, 24):
        assert odometry.linear_m_s == pytest.approx(0.5, rel=0.1)
        assert math.hypot(odometry.x_m - last.x_m, odometry.y_m - last.y_m) < 0.5 / 240 * 1.1
        if last.pose_covariance is not None and odometry.pose_covariance is not None:
            # The pose's covariance so far stays (a new config built it again from 0).
            assert odometry.pose_covariance[0] >= last.pose_covariance[0] > 0.0
        last = odometry


def test_restarting_the_same_noise_leaves_the_odometry_as_it_was(make):
    """The same seed and noise draw the same bias: odometry as in a run never restarted."""
    runs = [make(cmd_vel_timeout=0.0, noise_seed=1, **BIASED) for _ in range(2)]
    for simulation in runs:
        simulation.robot.command(0.5, 0.3)
        _frames(simulation, 480)
    runs[1].restart_noise(1)
    kept, restarted = (_frames(simulation, 240) for simulation in runs)
    for a, b in zip(kept, restarted):
        assert b[:5] == pytest.approx(a[:5], abs=1e-12)


def test_the_imu_reads_the_motion_on_across_a_noise_restart(make):
    """
    An exact IMU reads the same with or without restart_noise mid-ramp (bit for bit).

    A fresh IMU model forgot its last sample: its next reading showed no
    acceleration while the robot sped up.
    """
    runs = [make(cmd_vel_timeout=0.0, imu_rate=240.0) for _ in range(2)]
    readings = []
    for index, simulation in enumerate(runs):
        simulation.robot.command(0.5, 0.0)  # 0.5 s of ramp at 1 m/s^2
        for step in range(120):
            if step == 60 and index == 1:
                simulation.restart_noise(3, encoder_noise_std=0.01)
            readings.append((index, step, simulation.step().measurements[0].imu))
    kept, restarted = ([imu for i, _, imu in readings if i == index] for index in (0, 1))
    assert kept[61].linear_acceleration_m_s2[0] > 0.5
    assert restarted == kept
