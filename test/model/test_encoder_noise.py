"""
Wheel encoders that err (r2d2_sim.model.encoders), and the odometry covariance they give.

The encoders' error is relative to each reading's rotation: its statistics
over 10,000 readings, a standing robot that reads no travel, ticks, a bias
that curves a straight drive by the amount geometry says, and the
propagated covariance against a Monte Carlo of the same error model.
"""

import math

import numpy
import pytest

from r2d2_sim.model.drive_controller import DriveController
from r2d2_sim.model.encoders import Encoders, OdometryCovariance
from r2d2_sim.model.kinematics import DiffDriveGeometry, TwistLimits
from r2d2_sim.model.noise import NoiseSpec

READINGS = 10_000
DT_S = 1.0 / 240.0


def encoders(seed=0, **noise):
    return Encoders(NoiseSpec(**noise), numpy.random.default_rng(seed))


def relative_errors(enc, step_rad=0.01, readings=READINGS):
    """Turn both sides by ``step_rad`` per reading; return each reading's (counted/true - 1)."""
    previous = numpy.array(enc.read(0.0, 0.0, DT_S))
    errors = []
    for k in range(1, readings + 1):
        counted = numpy.array(enc.read(k * step_rad, -k * step_rad, DT_S))
        errors.append((counted - previous) / numpy.array([step_rad, -step_rad]) - 1.0)
        previous = counted
    return numpy.array(errors)


def test_exact_encoders_count_the_true_angle():
    enc = Encoders(NoiseSpec(), None)
    assert enc.read(1.25, -3.5, DT_S) == (1.25, -3.5)
    assert enc.read(2.0, -1.0, DT_S) == (2.0, -1.0)


def test_white_relative_error_per_reading_has_its_mean_and_sigma():
    errors = relative_errors(encoders(1, mean=0.05, stddev=0.01))
    for side in (0, 1):
        assert errors[:, side].mean() == pytest.approx(0.05, rel=0.02)
        assert errors[:, side].std() == pytest.approx(0.01, rel=0.02)


def test_a_constant_bias_is_a_wheel_radius_error_of_either_sign():
    signs = set()
    for seed in range(30):
        enc = encoders(seed, bias_mean=0.05)
        errors = relative_errors(enc, readings=10)
        assert numpy.allclose(errors, enc.bias)  # the same fraction every reading
        assert numpy.allclose(numpy.abs(enc.bias), 0.05)
        signs.add(tuple(numpy.sign(enc.bias)))
    assert len(signs) == 4  # each side's sign drawn on its own


def test_a_standing_robot_reads_no_travel_whatever_the_noise():
    enc = encoders(2, mean=0.1, stddev=0.5, bias_mean=0.2, dynamic_bias_stddev=0.1,
                   dynamic_bias_correlation_time_s=10.0)
    readings = {enc.read(0.3, 0.7, DT_S) for _ in range(1000)}
    assert readings == {(0.3, 0.7)}


def test_a_reading_at_no_interval_draws_nothing():
    """The same instant read twice (a start-up publication) leaves the stream where it was."""
    noise = {'stddev': 0.02, 'dynamic_bias_stddev': 0.01, 'dynamic_bias_correlation_time_s': 60.0}
    once, twice = encoders(seed=3, **noise), encoders(seed=3, **noise)
    once.read(0.5, -0.5, 0.0)
    twice.read(0.5, -0.5, 0.0)
    assert twice.read(0.5, -0.5, 0.0) == (0.5, -0.5)
    for k in range(1, 50):
        angles = (0.5 + 0.01 * k, -0.5 + 0.02 * k)
        assert once.read(*angles, DT_S) == twice.read(*angles, DT_S)


def test_counts_are_whole_ticks():
    tick = 2.0 * math.pi / 4096
    enc = encoders(3, stddev=0.01, precision=tick)
    for k in range(READINGS):
        left, right = enc.read(0.0007 * k, 0.0011 * k, DT_S)
        assert left == round(left / tick) * tick and right == round(right / tick) * tick
    # A slow wheel still gets its ticks: sub-tick rotations accumulate, not vanish.
    enc = encoders(precision=tick)
    counts = [enc.read(tick / 10 * k, 0.0, DT_S)[0] for k in range(101)]
    assert counts[-1] == pytest.approx(10 * tick)


def controller(noise, seed=0, separation_m=0.5, radius_m=0.1):
    geometry = DiffDriveGeometry(wheel_radius_m=radius_m, wheel_separation_m=separation_m)
    return DriveController(geometry, TwistLimits(), DT_S, 0, 1, 1,
                           encoders=Encoders(noise, numpy.random.default_rng(seed)),
                           covariance=OdometryCovariance(noise, radius_m, separation_m))


def test_a_bias_curves_a_straight_drive_by_what_geometry_says():
    """Both wheels turn 100 rad: odometry turns by r 100 (b_right - b_left) / separation."""
    drive = controller(NoiseSpec(bias_mean=0.01), seed=4)
    drive.update_odometry([0.0, 0.0], 0)
    for step in range(1, 1001):
        drive.update_odometry([0.1 * step, 0.1 * step], step)
    b_left, b_right = drive.encoders.bias
    assert b_left != b_right
    assert drive.odometry.yaw_rad == pytest.approx(0.1 * 100.0 * (b_right - b_left) / 0.5,
                                                   rel=1e-9)


def simulate(noise, left_m, right_m, runs, seed, radius_m, separation_m, dynamic=None):
    """
    Monte Carlo of the encoders' error model along a path; return final poses (runs x 3).

    ``dynamic``: each run's drifting bias at the start (runs x 2; None: 0).
    """
    generator = numpy.random.default_rng(seed)
    steps = len(left_m)
    constant = generator.normal(noise.bias_mean, noise.bias_stddev, (runs, 2))
    constant *= numpy.where(generator.uniform(size=(runs, 2)) < 0.5, -1.0, 1.0)
    constant += noise.mean
    dynamic = numpy.zeros((runs, 2)) if dynamic is None else dynamic
    tau = noise.dynamic_bias_correlation_time_s
    decay = math.exp(-DT_S / tau) if tau else 1.0
    step_std = (math.sqrt(-noise.dynamic_bias_stddev ** 2 * tau / 2 * math.expm1(-2 * DT_S / tau))
                if tau else 0.0)
    pose = numpy.zeros((runs, 3))
    for k in range(steps):
        dynamic = decay * dynamic + generator.normal(0.0, step_std, (runs, 2))
        error = constant + dynamic + generator.normal(0.0, noise.stddev, (runs, 2))
        integrate(pose, left_m[k] * (1.0 + error[:, 0]), right_m[k] * (1.0 + error[:, 1]),
                  separation_m)
    return pose


def integrate(pose, left, right, separation_m):
    """Move each run's pose by its sides' travel, as odometry's midpoint integration does."""
    ds, dyaw = (left + right) / 2.0, (right - left) / separation_m
    mid = pose[:, 2] + dyaw / 2.0
    pose[:, 0] += ds * numpy.cos(mid)
    pose[:, 1] += ds * numpy.sin(mid)
    pose[:, 2] += dyaw


FULL_NOISE = dict(stddev=0.05, bias_mean=0.01, bias_stddev=0.005,
                  dynamic_bias_stddev=0.02, dynamic_bias_correlation_time_s=5.0)


@pytest.mark.parametrize('noise', [
    NoiseSpec(**FULL_NOISE),
    NoiseSpec(mean=0.01, **FULL_NOISE),
    NoiseSpec(mean=-0.02, stddev=0.05),
    NoiseSpec(mean=0.01),
], ids=['no mean', 'a mean and everything else', 'a mean and white noise', 'a mean alone'])
def test_the_propagated_covariance_matches_a_monte_carlo_of_the_same_errors(noise):
    """
    An arc of 2 s: the covariance of x, y and yaw within 10 % of 4,000 simulated runs.

    The covariance is the error's second moment about the true (noiseless)
    path: the error of a consumer who takes odometry for the truth. A mean
    is one scale error of both wheels: counted as two independent biases,
    it gave a yaw deviation of 0.029 rad where the runs err by 0.010.
    """
    radius_m, separation_m = 0.05, 0.4
    steps = 480
    left_m = numpy.full(steps, 0.3 * DT_S)   # left slower: an arc to the left
    right_m = numpy.full(steps, 0.5 * DT_S)
    covariance = OdometryCovariance(noise, radius_m, separation_m)
    yaw = 0.0
    for k in range(steps):
        covariance.update(yaw, left_m[k], right_m[k], DT_S)
        yaw += (right_m[k] - left_m[k]) / separation_m
    exact = simulate(NoiseSpec(), left_m, right_m, 1, 7, radius_m, separation_m)[0]
    errors = simulate(noise, left_m, right_m, 4000, 7, radius_m, separation_m) - exact
    empirical = errors.T @ errors / len(errors)
    predicted = covariance.pose
    for i in range(3):
        assert predicted[i, i] == pytest.approx(empirical[i, i], rel=0.1)
    correlation = empirical[0, 2] / math.sqrt(empirical[0, 0] * empirical[2, 2])
    assert predicted[0, 2] / math.sqrt(predicted[0, 0] * predicted[2, 2]) == \
        pytest.approx(correlation, abs=0.05)


def simulate_rounded(noise, left_m, right_m, runs, seed, radius_m, separation_m):
    """Monte Carlo of white noise and counts rounded to a tick, from a random start angle."""
    generator = numpy.random.default_rng(seed)
    tick = radius_m * noise.precision
    counted = generator.uniform(0.0, tick, (runs, 2))  # where each wheel stands at the start
    last = numpy.round(counted / tick) * tick
    pose = numpy.zeros((runs, 3))
    for k in range(len(left_m)):
        error = generator.normal(0.0, noise.stddev, (runs, 2))
        counted = counted + numpy.array([left_m[k], right_m[k]]) * (1.0 + error)
        reading = numpy.round(counted / tick) * tick
        left, right = (reading - last).T
        last = reading
        integrate(pose, left, right, separation_m)
    return pose


RADIUS_M, SEPARATION_M = 0.05, 0.4
ROUNDED = NoiseSpec(stddev=0.01, precision=2.0 * math.pi / 256)


def propagated(noise, left_m, right_m):
    """Return the covariance after the odometry steps of these travels."""
    covariance = OdometryCovariance(noise, RADIUS_M, SEPARATION_M)
    yaw = 0.0
    for left, right in zip(left_m, right_m):
        covariance.update(yaw, left, right, DT_S)
        yaw += (right - left) / SEPARATION_M
    return covariance.pose


def test_rounded_counts_give_the_covariance_a_monte_carlo_of_them_gives():
    """An arc of 10 s with counts rounded to 1/256 turn: within 10 % of 4,000 runs."""
    steps = 2400
    left_m, right_m = numpy.full(steps, 0.3 * DT_S), numpy.full(steps, 0.5 * DT_S)
    predicted = propagated(ROUNDED, left_m, right_m)
    poses = simulate_rounded(ROUNDED, left_m, right_m, 4000, 11, RADIUS_M, SEPARATION_M)
    empirical = numpy.cov(poses.T)
    for i in range(3):
        assert predicted[i, i] == pytest.approx(empirical[i, i], rel=0.1)


def test_a_robot_standing_still_keeps_its_rounding_covariance_however_long():
    """Roundings do not add up: standing, the yaw's variance stays r^2 p^2 / (3 s^2)."""
    noise = NoiseSpec(precision=ROUNDED.precision)  # rounding alone
    bound = (RADIUS_M * noise.precision) ** 2 / (3.0 * SEPARATION_M ** 2)
    for steps in (24, 14400):  # 0.1 s, 1 minute at 240 Hz
        standing = numpy.zeros(steps)
        assert propagated(noise, standing, standing)[2, 2] == pytest.approx(bound, rel=1e-9)


def test_the_twist_covariance_is_the_last_steps_error_over_its_time():
    noise = NoiseSpec(stddev=0.02)
    covariance = OdometryCovariance(noise, 0.05, 0.4)
    covariance.update(0.0, 0.002, 0.004, DT_S)
    left_var, right_var = (0.002 * 0.02) ** 2, (0.004 * 0.02) ** 2
    assert covariance.twist[0, 0] == pytest.approx((left_var + right_var) / 4 / DT_S ** 2)
    assert covariance.twist[1, 1] == pytest.approx((left_var + right_var) / 0.16 / DT_S ** 2)
    assert covariance.twist[0, 1] == pytest.approx((right_var - left_var) / 0.8 / DT_S ** 2)


def test_a_mean_is_a_scale_error_that_errs_in_speed_and_not_in_turn():
    """Equal travel on both sides: a mean errs vx by mean * v and wz not at all."""
    covariance = OdometryCovariance(NoiseSpec(mean=0.01), 0.05, 0.4)
    covariance.update(0.0, 0.002, 0.002, DT_S)
    speed_m_s = 0.002 / DT_S
    assert covariance.twist[0, 0] == pytest.approx((0.01 * speed_m_s) ** 2, rel=1e-12)
    assert covariance.twist[1, 1] == pytest.approx(0.0, abs=1e-18)
    assert covariance.pose[2, 2] == pytest.approx(0.0, abs=1e-18)


def test_a_reset_forgets_the_pose_error_but_not_the_bias_prior():
    noise = NoiseSpec(bias_mean=0.1)
    covariance = OdometryCovariance(noise, 0.05, 0.4)
    for _ in range(100):
        covariance.update(0.0, 0.01, 0.01, DT_S)
    assert covariance.pose[0, 0] > 0.0
    covariance.reset()
    assert not covariance.pose.any()
    assert covariance.covariance[3, 3] == pytest.approx(0.01)


def test_a_reset_keeps_the_drifting_bias_the_encoders_keep():
    """
    Ten minutes of drift, a reset, a 2 s arc: its covariance within 10 % of 4,000 runs.

    A state reset puts the robot back but the encoders keep their biases
    (Encoders.restart): the drift so far goes on into the runs after it.
    Set back to its prior (0), the drifting bias went missing from the
    covariance: its yaw variance was 0.5 % of the runs'.
    """
    noise = NoiseSpec(dynamic_bias_stddev=0.001, dynamic_bias_correlation_time_s=300.0)
    covariance = OdometryCovariance(noise, RADIUS_M, SEPARATION_M)
    drift_s, runs = 600, 4000
    for _ in range(drift_s):  # a reading a second, driving straight
        covariance.update(0.0, 0.05, 0.05, 1.0)
    covariance.reset()
    assert not covariance.pose.any()
    steps = 480
    left_m, right_m = numpy.full(steps, 0.3 * DT_S), numpy.full(steps, 0.5 * DT_S)
    yaw = 0.0
    for left, right in zip(left_m, right_m):
        covariance.update(yaw, left, right, DT_S)
        yaw += (right - left) / SEPARATION_M
    # The runs' drifting biases after the same ten minutes, in the same 1 s steps.
    generator = numpy.random.default_rng(12)
    tau = noise.dynamic_bias_correlation_time_s
    step_std = math.sqrt(-noise.dynamic_bias_stddev ** 2 * tau / 2 * math.expm1(-2 / tau))
    dynamic = numpy.zeros((runs, 2))
    for _ in range(drift_s):
        dynamic = math.exp(-1 / tau) * dynamic + generator.normal(0.0, step_std, (runs, 2))
    exact = simulate(NoiseSpec(), left_m, right_m, 1, 13, RADIUS_M, SEPARATION_M)[0]
    errors = simulate(noise, left_m, right_m, runs, 13, RADIUS_M, SEPARATION_M,
                      dynamic=dynamic) - exact
    empirical = errors.T @ errors / runs
    for i in range(3):
        assert covariance.pose[i, i] == pytest.approx(empirical[i, i], rel=0.1)


def test_new_encoders_keep_the_pose_covariance_and_start_their_biases_afresh():
    """carry_on: the pose's covariance and twist are the odometry's; the biases the new prior."""
    old = OdometryCovariance(NoiseSpec(**FULL_NOISE), RADIUS_M, SEPARATION_M)
    for _ in range(240):
        old.update(0.0, 0.002, 0.003, DT_S)
    new = OdometryCovariance(NoiseSpec(bias_mean=0.02), RADIUS_M, SEPARATION_M)
    new.carry_on(old)
    assert (new.pose == old.pose).all() and (new.twist == old.twist).all()
    assert numpy.diag(new.covariance)[3:7] == pytest.approx([0.0004, 0.0004, 0.0, 0.0])
    assert not new.covariance[0:3, 3:7].any() and not new.covariance[3:7, 0:3].any()
