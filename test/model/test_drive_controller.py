"""
The drive controller without ROS or PyBullet, with geometry you can check by hand.

Wheel radius 0.5 m and track 1 m (so v = 1 m/s is 2 rad/s on each wheel and
w = 1 rad/s is -/+1 rad/s), physics at 10 Hz (dt = 0.1 s): every expected
number below is a line of arithmetic in its comment.
"""

import math

import pytest

from r2d2_sim.model.drive_controller import (
    DriveController, OVERFLOW, STOP, timeout_steps, Twist2D)
from r2d2_sim.model.kinematics import DiffDriveGeometry, TwistLimits

GEOMETRY = DiffDriveGeometry(wheel_radius_m=0.5, wheel_separation_m=1.0,
                             max_wheel_velocity_rad_s=10.0)
DT_S = 0.1


def controller(limits=TwistLimits(), timeout=0, sign=1, left=1, right=1, pose=(0.0, 0.0, 0.0)):
    """Build a controller on the hand geometry."""
    return DriveController(GEOMETRY, limits, DT_S, timeout, left, right, sign, pose)


def test_a_command_applies_at_the_next_update_as_wheel_speeds():
    """At v = 1 m/s, w = 1 rad/s: left (1 - 1*1/2)/0.5 = 1 rad/s, right (1 + 0.5)/0.5 = 3."""
    c = controller()
    verdict = c.command(1.0, 1.0)
    assert verdict.accepted == Twist2D(1.0, 1.0) and not verdict.clamped
    assert c.target == STOP  # nothing moves until the physics loop updates
    assert c.update(0) == [1.0, 3.0]
    assert c.wheel_targets == (1.0, 3.0)
    assert c.update(1) is None  # nothing changed: the motors keep their targets


def test_targets_fan_out_to_every_wheel_with_the_urdf_sign():
    """Two wheels a side, sign -1 (the classic R2D2): [-1, -1, -3, -3] in joint space."""
    c = controller(sign=-1, left=2, right=2)
    c.command(1.0, 1.0)
    assert c.update(0) == [-1.0, -1.0, -3.0, -3.0]
    assert c.wheel_targets == (1.0, 3.0)  # REP-103 wheel speeds, before the sign


@pytest.mark.parametrize('field', ['linear_y', 'linear_z', 'angular_x', 'angular_y'])
@pytest.mark.parametrize('value, problem', [(math.nan, 'NaN'), (math.inf, 'infinite value'),
                                            (-math.inf, 'infinite value')])
def test_non_finite_commands_are_refused_and_the_last_one_kept(field, value, problem):
    """Refuse NaN or infinity in any of the six fields: nothing pending, target unchanged."""
    c = controller()
    c.command(0.5, 0.0)
    c.update(0)
    verdict = c.command(0.0, 0.0, **{field: value})
    assert verdict.accepted is None and verdict.problem == problem
    assert c.update(1) is None and c.target == Twist2D(0.5, 0.0)
    for args in ((value, 0.0), (0.0, value)):
        assert c.command(*args).problem == problem


@pytest.mark.parametrize('command', [(1e308, 0.0), (0.0, 1e308), (-1e307, 1e307)])
def test_without_a_wheel_limit_a_command_whose_wheel_speeds_overflow_is_refused(command):
    """No wheel speed limit (the geometry's default): 1e308 m/s would be inf rad/s, refused."""
    geometry = DiffDriveGeometry(wheel_radius_m=0.035, wheel_separation_m=0.484)
    c = DriveController(geometry, TwistLimits(), DT_S, 0, 2, 2)
    c.command(0.5, 0.0)
    c.update(0)
    verdict = c.command(*command)
    assert verdict.accepted is None and verdict.problem == OVERFLOW
    assert c.update(1) is None and c.target == Twist2D(0.5, 0.0)
    assert all(map(math.isfinite, c.joint_targets()))
    assert c.command(1e300, 0.0).accepted == Twist2D(1e300, 0.0)  # 2.9e301 rad/s: a number
    assert all(map(math.isfinite, c.update(2)))


def test_axes_a_differential_drive_cannot_follow_are_named():
    """linear.y and angular.x are reported as ignored; the rest of the twist is taken."""
    verdict = controller().command(0.2, 0.1, linear_y=1.0, angular_x=-0.5)
    assert verdict.ignored_axes == ('linear.y', 'angular.x')
    assert verdict.accepted == Twist2D(0.2, 0.1)


def test_too_fast_is_scaled_keeping_the_curvature():
    """At v = 10, w = 10 the right wheel needs (10 + 5)/0.5 = 30 > 10 rad/s: scaled by 1/3."""
    verdict = controller().command(10.0, 10.0)
    assert verdict.clamped
    assert verdict.accepted.linear_m_s == pytest.approx(10.0 / 3.0)
    assert verdict.accepted.angular_rad_s == pytest.approx(10.0 / 3.0)


def test_the_ramp_moves_both_axes_by_the_same_fraction():
    """Limit 1 m/s^2 at dt 0.1 s: 0.1 m/s per step; w follows at the same fraction (0.05)."""
    c = controller(TwistLimits(max_linear_acceleration_m_s2=1.0))
    c.command(1.0, 0.5)
    c.update(0)
    assert c.ramped == pytest.approx((0.1, 0.05))
    for step in range(1, 9):
        c.update(step)
    assert c.ramped == pytest.approx((0.9, 0.45))
    c.update(9)  # 0.9 + 0.1, give or take the rounding of nine additions of 0.1
    c.update(10)
    assert c.ramped == (1.0, 0.5)  # reached exactly, not approached forever
    assert c.update(11) is None


def test_the_timeout_brakes_after_whole_steps():
    """A 0.25 s timeout at 10 Hz is ceil(2.5) = 3 steps: the 3rd update after the command stops."""
    assert timeout_steps(0.25, 10.0) == 3
    c = controller(timeout=3)
    c.command(0.5, 0.0)
    c.update(0)
    assert c.update(1) is None and c.update(2) is None
    assert c.update(3) == [0.0, 0.0] and c.target == STOP


@pytest.mark.parametrize('timeout_s, rate_hz, steps', [
    (0.07, 100.0, 7), (0.14, 50.0, 7), (0.55, 100.0, 55), (1.1, 50.0, 55), (0.5, 240.0, 120),
    (1e-12, 240.0, 1)])
def test_the_timeout_counts_the_steps_as_written_not_as_the_floats_multiply(
        timeout_s, rate_hz, steps):
    """0.07 s at 100 Hz is 7 steps: the floats' product, 7.000000000000001, rounded up to 8."""
    assert timeout_steps(timeout_s, rate_hz) == steps


def test_no_timeout_for_zero_or_beyond_any_run():
    """0 s disables the timeout; 1e308 s would overflow ceil and is as good as none."""
    assert timeout_steps(0.0, 240.0) == 0
    assert timeout_steps(1e308, 240.0) == 0


def test_odometry_integrates_the_encoder_angles():
    """Both wheels turn 2 rad (sign -1: joints read -2): 0.5 m * 2 = 1 m straight ahead."""
    c = controller(sign=-1, left=2, right=2, pose=(1.0, 2.0, math.pi / 2))
    c.update_odometry([0.0, 0.0, 0.0, 0.0], 0)
    c.update_odometry([-2.0, -2.0, -2.0, -2.0], 10)
    odometry = c.odometry
    assert (odometry.x_m, odometry.y_m) == pytest.approx((1.0, 3.0))  # facing +y
    assert odometry.linear_m_s == pytest.approx(1.0)  # 1 m in 10 steps of 0.1 s


def test_reset_drops_the_command_and_restarts_odometry_at_the_initial_pose():
    """After a reset: target and ramp stopped, zero wheel targets, odometry at the spawn pose."""
    c = controller(pose=(0.5, 0.0, 0.0))
    c.command(1.0, 0.0)
    c.update(0)
    c.update_odometry([0.0, 0.0], 0)
    c.update_odometry([4.0, 4.0], 20)
    assert c.odometry.x_m == pytest.approx(2.5)
    c.command(0.3, 0.0)  # pending, never applied
    assert c.reset(21, [4.0, 4.0]) == [0.0, 0.0]
    assert c.target == c.ramped == STOP and c.update(22) is None
    assert (c.odometry.x_m, c.odometry.y_m, c.odometry.yaw_rad) == (0.5, 0.0, 0.0)
    c.update_odometry([6.0, 6.0], 31)  # the baseline is the angle at reset: +2 rad = 1 m
    assert c.odometry.x_m == pytest.approx(1.5)


@pytest.mark.parametrize('left, right, sign', [(0, 2, 1), (2, 0, 1), (1, 1, 0)])
def test_impossible_drive_trains_are_refused(left, right, sign):
    """A side without wheels, or a sign other than +-1, is a ValueError."""
    with pytest.raises(ValueError):
        controller(left=left, right=right, sign=sign)


class RacingController(DriveController):
    """Another thread's command lands right after update() has read the latest one."""

    racing = False

    def __getattribute__(self, name):
        value = super().__getattribute__(name)
        if name == '_latest' and super().__getattribute__('racing'):
            object.__setattr__(self, 'racing', False)
            self.command(0.4, 0.0)  # what the subscription thread does meanwhile
        return value


def test_a_command_written_while_update_reads_is_not_lost():
    """The command written during update() is taken at the next update, not wiped."""
    c = RacingController(GEOMETRY, TwistLimits(), DT_S, 0, 1, 1)
    c.command(0.2, 0.0)
    c.racing = True
    c.update(0)
    assert c.target == Twist2D(0.2, 0.0)
    c.update(1)
    assert c.target == Twist2D(0.4, 0.0)


def test_the_same_command_sent_again_restarts_the_timeout():
    """An equal twist is a new command: the timeout counts from the latest one."""
    c = controller(timeout=3)
    c.command(0.5, 0.0)
    c.update(0)
    c.update(2)
    c.command(0.5, 0.0)
    c.update(3)  # 3 steps after the first command, 1 after the second
    assert c.target == Twist2D(0.5, 0.0)
    assert c.update(6) == [0.0, 0.0]
