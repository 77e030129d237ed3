"""Unit tests for r2d2_sim.model.kinematics (pure kinematics, no ROS or PyBullet)."""

import math

import pytest

from r2d2_sim.model.kinematics import (
    DiffDriveGeometry,
    DiffDriveOdometry,
    DriveConfigError,
    limit_twist,
    quaternion_to_yaw,
    twist_to_wheel_velocities,
    wheel_velocities_to_twist,
    yaw_to_quaternion,
)

HALF_SQRT2 = math.sqrt(0.5)


def angle_error_rad(actual_rad, expected_rad):
    """Return the signed smallest difference between two angles."""
    return math.remainder(actual_rad - expected_rad, 2.0 * math.pi)


# --------------------------------------------------------------------------- geometry


@pytest.mark.parametrize('field', ['wheel_radius_m', 'wheel_separation_m',
                                   'max_wheel_velocity_rad_s'])
@pytest.mark.parametrize('bad_value', [0.0, -1.0, math.nan, 'abc'])
def test_geometry_rejects_bad_values_naming_the_field(field, bad_value):
    kwargs = {'wheel_radius_m': 1.0, 'wheel_separation_m': 1.0,
              'max_wheel_velocity_rad_s': 10.0}
    kwargs[field] = bad_value
    with pytest.raises(DriveConfigError, match=field) as excinfo:
        DiffDriveGeometry(**kwargs)
    message = str(excinfo.value)
    assert '\n' not in message
    assert repr(bad_value) in message


@pytest.mark.parametrize('field', ['wheel_radius_m', 'wheel_separation_m'])
def test_geometry_rejects_infinite_radius_and_separation(field):
    kwargs = {'wheel_radius_m': 1.0, 'wheel_separation_m': 1.0}
    kwargs[field] = math.inf
    with pytest.raises(DriveConfigError, match=field):
        DiffDriveGeometry(**kwargs)


def test_geometry_error_is_a_value_error():
    assert issubclass(DriveConfigError, ValueError)


def test_geometry_default_limit_is_infinite_and_ints_become_floats():
    geometry = DiffDriveGeometry(1, 2)
    assert geometry.max_wheel_velocity_rad_s == math.inf
    assert isinstance(geometry.wheel_radius_m, float)
    assert geometry.wheel_separation_m == 2.0


def test_geometry_is_frozen():
    geometry = DiffDriveGeometry(1.0, 2.0)
    with pytest.raises(AttributeError):
        geometry.wheel_radius_m = 3.0


# --------------------------------------------------------------------------- kinematics


def test_twist_to_wheels_hand_computed():
    # r = 0.5, s = 0.4, v = 1, w = 2:
    # left  = (1 - 2 * 0.4 / 2) / 0.5 = 0.6 / 0.5 = 1.2
    # right = (1 + 2 * 0.4 / 2) / 0.5 = 1.4 / 0.5 = 2.8
    geometry = DiffDriveGeometry(0.5, 0.4)
    left, right = twist_to_wheel_velocities(geometry, 1.0, 2.0)
    assert left == pytest.approx(1.2)
    assert right == pytest.approx(2.8)


def test_wheels_to_twist_hand_computed():
    # r = 0.5, s = 0.4, left 1.2, right 2.8:
    # v = 0.5 * (1.2 + 2.8) / 2 = 1.0 ; w = 0.5 * (2.8 - 1.2) / 0.4 = 2.0
    geometry = DiffDriveGeometry(0.5, 0.4)
    linear, angular = wheel_velocities_to_twist(geometry, 1.2, 2.8)
    assert linear == pytest.approx(1.0)
    assert angular == pytest.approx(2.0)


@pytest.mark.parametrize('linear, angular', [
    (1.0, 2.0), (-0.3, 0.0), (0.0, -1.5), (0.25, -0.75),
])
def test_twist_wheels_twist_round_trip(linear, angular):
    geometry = DiffDriveGeometry(0.5, 0.4)
    left, right = twist_to_wheel_velocities(geometry, linear, angular)
    assert wheel_velocities_to_twist(geometry, left, right) == pytest.approx(
        (linear, angular), abs=1e-12)


def test_twist_forward_and_backward_sign():
    # r = 1, s = 2: v = -1, w = 0 -> both wheels -1 rad/s (roll backwards).
    geometry = DiffDriveGeometry(1.0, 2.0)
    assert twist_to_wheel_velocities(geometry, -1.0, 0.0) == pytest.approx((-1.0, -1.0))
    # Counter-clockwise turn in place: right wheel forward, left backward.
    assert twist_to_wheel_velocities(geometry, 0.0, 1.0) == pytest.approx((-1.0, 1.0))


def test_clamping_preserves_curvature_and_caps_exactly():
    # r = 1, s = 2, max 2 rad/s, v = 3, w = 1:
    # unclamped left = 3 - 1 = 2, right = 3 + 1 = 4 -> scale 2 / 4 = 0.5 -> (1, 2)
    # resulting twist v = (1 + 2) / 2 = 1.5, w = (2 - 1) / 2 = 0.5, w / v = 1/3 as commanded
    geometry = DiffDriveGeometry(1.0, 2.0, max_wheel_velocity_rad_s=2.0)
    left, right = twist_to_wheel_velocities(geometry, 3.0, 1.0)
    assert right == 2.0
    assert left == pytest.approx(1.0)
    linear, angular = wheel_velocities_to_twist(geometry, left, right)
    assert angular / linear == pytest.approx(1.0 / 3.0)


def test_clamping_with_backward_motion_caps_magnitude():
    # r = 1, s = 2, max 2, v = -3, w = 1: left = -3 - 1 = -4, right = -3 + 1 = -2
    # scale 0.5 -> (-2, -1)
    geometry = DiffDriveGeometry(1.0, 2.0, max_wheel_velocity_rad_s=2.0)
    left, right = twist_to_wheel_velocities(geometry, -3.0, 1.0)
    assert left == -2.0
    assert right == pytest.approx(-1.0)


def test_pure_spin_clamping():
    # r = 1, s = 2, max 2, v = 0, w = 3: left = -3, right = +3 -> scale 2/3 -> (-2, +2)
    geometry = DiffDriveGeometry(1.0, 2.0, max_wheel_velocity_rad_s=2.0)
    left, right = twist_to_wheel_velocities(geometry, 0.0, 3.0)
    assert (left, right) == pytest.approx((-2.0, 2.0))
    assert max(abs(left), abs(right)) == 2.0


def test_no_clamping_below_limit():
    # r = 1, s = 2, max 2: v = 1, w = 1 -> (0, 2); 2 is not above the limit.
    geometry = DiffDriveGeometry(1.0, 2.0, max_wheel_velocity_rad_s=2.0)
    assert twist_to_wheel_velocities(geometry, 1.0, 1.0) == pytest.approx((0.0, 2.0))


@pytest.mark.parametrize('linear, angular', [
    (math.nan, 0.0), (0.0, math.nan), (math.inf, 0.0), (0.0, -math.inf),
])
def test_twist_to_wheels_rejects_non_finite(linear, angular):
    geometry = DiffDriveGeometry(1.0, 2.0)
    with pytest.raises(ValueError):
        twist_to_wheel_velocities(geometry, linear, angular)


@pytest.mark.parametrize('limit_rad_s', [math.inf, 10.0])
@pytest.mark.parametrize('linear, angular', [(1e308, 0.0), (0.0, -1e308), (1e307, 1e307)])
def test_twist_to_wheels_refuses_wheel_speeds_that_overflow(limit_rad_s, linear, angular):
    """1e308 m/s on a 0.035 m wheel is inf rad/s: unscaled inf, scaled by 10 / inf NaN."""
    geometry = DiffDriveGeometry(0.035, 0.484, limit_rad_s)
    with pytest.raises(ValueError, match='overflow'):
        twist_to_wheel_velocities(geometry, linear, angular)


# --------------------------------------------------------------------------- quaternions


@pytest.mark.parametrize('yaw, expected', [
    # (x, y, z, w) = (0, 0, sin(yaw / 2), cos(yaw / 2))
    (0.0, (0.0, 0.0, 0.0, 1.0)),
    (math.pi / 2, (0.0, 0.0, HALF_SQRT2, HALF_SQRT2)),
    (-math.pi / 2, (0.0, 0.0, -HALF_SQRT2, HALF_SQRT2)),
    (math.pi, (0.0, 0.0, 1.0, 0.0)),
])
def test_yaw_to_quaternion_hand_values(yaw, expected):
    assert yaw_to_quaternion(yaw) == pytest.approx(expected, abs=1e-15)


@pytest.mark.parametrize('yaw', [0.0, 0.3, -0.3, 1.0, -2.5, 3.0, math.pi])
def test_quaternion_round_trip(yaw):
    assert quaternion_to_yaw(*yaw_to_quaternion(yaw)) == pytest.approx(yaw, abs=1e-12)


def test_quaternion_to_yaw_wraps_into_half_open_range():
    # yaw 3 pi / 2 -> -pi / 2 ; yaw -pi is reported as +pi.
    assert quaternion_to_yaw(*yaw_to_quaternion(1.5 * math.pi)) == pytest.approx(-math.pi / 2)
    assert quaternion_to_yaw(0.0, 0.0, -1.0, 0.0) == math.pi
    assert quaternion_to_yaw(0.0, 0.0, 1.0, 0.0) == math.pi


def test_quaternion_to_yaw_ignores_roll_and_pitch():
    # q = qz(psi) * qy(theta) (yaw then pitch, ZYX), expanded by hand with half angles
    # c = cos(./2), s = sin(./2):  x = -s_psi s_th, y = c_psi s_th, z = c_th s_psi,
    # w = c_psi c_th.  Its ZYX yaw is psi = 0.7 for any |theta| < pi / 2.
    psi, theta = 0.7, 0.4
    cp, sp = math.cos(psi / 2), math.sin(psi / 2)
    ct, st = math.cos(theta / 2), math.sin(theta / 2)
    q = (-sp * st, cp * st, ct * sp, cp * ct)
    assert quaternion_to_yaw(*q) == pytest.approx(0.7)
    # Pure roll of 0.5 rad about x: (sin 0.25, 0, 0, cos 0.25) -> yaw 0.
    assert quaternion_to_yaw(math.sin(0.25), 0.0, 0.0, math.cos(0.25)) == pytest.approx(0.0)


def test_quaternion_to_yaw_accepts_unnormalised():
    # 2 * (0, 0, sqrt(1/2), sqrt(1/2)) still means yaw pi / 2.
    assert quaternion_to_yaw(0.0, 0.0, 2 * HALF_SQRT2, 2 * HALF_SQRT2) == pytest.approx(
        math.pi / 2)


@pytest.mark.parametrize('q', [(0.0, 0.0, 0.0, 0.0), (math.nan, 0.0, 0.0, 1.0)])
def test_quaternion_to_yaw_rejects_degenerate(q):
    with pytest.raises(ValueError):
        quaternion_to_yaw(*q)


# --------------------------------------------------------------------------- odometry


def test_initial_state():
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0), x_m=1.0, y_m=-2.0, yaw_rad=0.5)
    assert (odom.x_m, odom.y_m, odom.yaw_rad) == (1.0, -2.0, 0.5)
    assert (odom.linear_m_s, odom.angular_rad_s, odom.distance_m) == (0.0, 0.0, 0.0)


def test_straight_line_from_velocities():
    # r = 0.5, both wheels 1 rad/s for 1 s -> x = 0.5 * 1 * 1 = 0.5 m, v = 0.5 m/s.
    odom = DiffDriveOdometry(DiffDriveGeometry(0.5, 1.0))
    assert odom.update_from_velocities(1.0, 1.0, 1.0) is True
    assert odom.x_m == pytest.approx(0.5)
    assert odom.y_m == pytest.approx(0.0, abs=1e-15)
    assert odom.yaw_rad == pytest.approx(0.0, abs=1e-15)
    assert odom.linear_m_s == pytest.approx(0.5)
    assert odom.angular_rad_s == pytest.approx(0.0, abs=1e-15)
    assert odom.distance_m == pytest.approx(0.5)


def test_straight_line_from_positions_in_ten_steps():
    # r = 0.5, wheel angle grows 0.1 rad every 0.1 s for 1 s -> x = 0.5 * 1.0 = 0.5 m.
    odom = DiffDriveOdometry(DiffDriveGeometry(0.5, 1.0))
    assert odom.update_from_positions(0.0, 0.0, 0.1) is False
    for step in range(1, 11):
        assert odom.update_from_positions(0.1 * step, 0.1 * step, 0.1) is True
    assert odom.x_m == pytest.approx(0.5)
    assert odom.y_m == pytest.approx(0.0, abs=1e-12)
    assert odom.linear_m_s == pytest.approx(0.5)


def test_straight_line_along_heading():
    # Starting at yaw pi / 2 (facing +y), 1 m of travel ends at (0, 1).
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 1.0), yaw_rad=math.pi / 2)
    odom.update_from_velocities(1.0, 1.0, 1.0)
    assert odom.x_m == pytest.approx(0.0, abs=1e-12)
    assert odom.y_m == pytest.approx(1.0)


def test_spin_in_place():
    # r = 1, s = 2, left -1, right +1: w = 1 * (1 - (-1)) / 2 = 1 rad/s, v = 0.
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    assert odom.update_from_velocities(-1.0, 1.0, 0.1) is True
    assert odom.angular_rad_s == pytest.approx(1.0)
    assert odom.linear_m_s == pytest.approx(0.0, abs=1e-15)
    assert odom.yaw_rad == pytest.approx(0.1)
    assert (odom.x_m, odom.y_m) == pytest.approx((0.0, 0.0), abs=1e-15)
    assert odom.distance_m == pytest.approx(0.0, abs=1e-15)


def test_spin_quarter_turn_from_positions():
    # r = 1, s = 2: left -pi/2 rad, right +pi/2 rad -> dth = (pi/2 + pi/2) / 2 = pi/2.
    # Done in pi/2 s, so the yaw rate is 1 rad/s.
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    odom.update_from_positions(0.0, 0.0, 0.0)
    assert odom.update_from_positions(-math.pi / 2, math.pi / 2, math.pi / 2) is True
    assert odom.yaw_rad == pytest.approx(math.pi / 2)
    assert odom.angular_rad_s == pytest.approx(1.0)
    assert (odom.x_m, odom.y_m) == pytest.approx((0.0, 0.0), abs=1e-15)


# Half circle of radius R = 2 with r = 1, s = 2: the left wheel runs on radius
# R - s/2 = 1 and the right one on R + s/2 = 3, so over a half circle they roll
# pi * 1 = pi rad and pi * 3 = 3 pi rad.  ds = (pi + 3 pi) / 2 = 2 pi = pi * R and
# dth = (3 pi - pi) / 2 = pi.  The robot ends at (0, 2R) = (0, 4) facing yaw pi.


def assert_half_circle_end(odom):
    assert odom.x_m == pytest.approx(0.0, abs=1e-9)
    assert odom.y_m == pytest.approx(4.0, abs=1e-9)
    assert angle_error_rad(odom.yaw_rad, math.pi) == pytest.approx(0.0, abs=1e-9)
    assert odom.distance_m == pytest.approx(2 * math.pi, abs=1e-9)


def test_arc_single_big_step_is_exact():
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    odom.update_from_positions(0.0, 0.0, 1.0)
    assert odom.update_from_positions(math.pi, 3 * math.pi, math.pi) is True
    assert_half_circle_end(odom)
    # Over pi seconds: v = 2 pi / pi = 2 m/s, w = pi / pi = 1 rad/s.
    assert odom.linear_m_s == pytest.approx(2.0)
    assert odom.angular_rad_s == pytest.approx(1.0)


def test_arc_many_small_steps_from_positions():
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    steps = 1000
    dt = math.pi / steps
    odom.update_from_positions(0.0, 0.0, dt)
    for step in range(1, steps + 1):
        fraction = step / steps
        odom.update_from_positions(math.pi * fraction, 3 * math.pi * fraction, dt)
    assert_half_circle_end(odom)


def test_arc_many_small_steps_from_velocities():
    # left 1 rad/s, right 3 rad/s for pi s gives the same half circle.
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    steps = 1000
    for _ in range(steps):
        odom.update_from_velocities(1.0, 3.0, math.pi / steps)
    assert_half_circle_end(odom)
    # v = 1 * (1 + 3) / 2 = 2 m/s, w = 1 * (3 - 1) / 2 = 1 rad/s.
    assert odom.linear_m_s == pytest.approx(2.0)
    assert odom.angular_rad_s == pytest.approx(1.0)


def test_quarter_circle_single_step():
    # Same wheels as the half circle over pi/2 s: quarter circle of R = 2 ends at
    # (R, R) = (2, 2) with yaw pi / 2.
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    odom.update_from_velocities(1.0, 3.0, math.pi / 2)
    assert (odom.x_m, odom.y_m) == pytest.approx((2.0, 2.0), abs=1e-12)
    assert odom.yaw_rad == pytest.approx(math.pi / 2)


def test_tiny_yaw_increment_uses_rk2_without_blowing_up():
    # r = 1, s = 1, left travel 1 m, right 1 + 2e-7 m:
    # ds = 1 + 1e-7, dth = 2e-7 (below the 1e-6 threshold).
    # RK2: x = ds cos(1e-7) ~ 1 + 1e-7, y = ds sin(1e-7) ~ 1e-7, yaw = 2e-7.
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 1.0))
    assert odom.update_from_velocities(1.0, 1.0 + 2e-7, 1.0) is True
    assert odom.x_m == pytest.approx(1.0 + 1e-7, abs=1e-12)
    assert odom.y_m == pytest.approx(1e-7, rel=1e-6)
    assert odom.yaw_rad == pytest.approx(2e-7, rel=1e-6)


def test_first_position_update_only_sets_baseline():
    # Encoders start at arbitrary angles: no motion is inferred from them.
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    assert odom.update_from_positions(5.0, -3.0, 0.1) is False
    assert (odom.x_m, odom.y_m, odom.yaw_rad) == (0.0, 0.0, 0.0)
    assert odom.distance_m == 0.0
    # Then both wheels roll +1 rad in 0.5 s: x = 1 m, v = 1 / 0.5 = 2 m/s.
    assert odom.update_from_positions(6.0, -2.0, 0.5) is True
    assert odom.x_m == pytest.approx(1.0)
    assert odom.linear_m_s == pytest.approx(2.0)


@pytest.mark.parametrize('dt', [0.0, -0.1, math.nan, math.inf])
def test_bad_dt_is_ignored_for_velocities(dt):
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    odom.update_from_velocities(1.0, 1.0, 1.0)  # x = 1, v = 1
    assert odom.update_from_velocities(5.0, 7.0, dt) is False
    assert (odom.x_m, odom.y_m, odom.yaw_rad) == pytest.approx((1.0, 0.0, 0.0))
    assert (odom.linear_m_s, odom.angular_rad_s) == pytest.approx((1.0, 0.0))


@pytest.mark.parametrize('left, right', [(math.nan, 1.0), (1.0, math.inf)])
def test_non_finite_velocities_are_ignored(left, right):
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    assert odom.update_from_velocities(left, right, 0.1) is False
    assert (odom.x_m, odom.y_m, odom.yaw_rad, odom.distance_m) == (0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize('dt', [0.0, -0.1, math.nan])
def test_bad_dt_for_positions_keeps_baseline(dt):
    # A rejected reading does not move the baseline, so its travel is counted
    # by the next valid reading: 0 -> 1 rad (rejected) -> 2 rad gives x = 2 m.
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    odom.update_from_positions(0.0, 0.0, 0.1)
    assert odom.update_from_positions(1.0, 1.0, dt) is False
    assert odom.x_m == 0.0
    assert odom.update_from_positions(2.0, 2.0, 1.0) is True
    assert odom.x_m == pytest.approx(2.0)
    assert odom.linear_m_s == pytest.approx(2.0)


@pytest.mark.parametrize('left, right', [(math.nan, 1.0), (1.0, math.nan), (math.inf, 0.0)])
def test_non_finite_positions_are_ignored(left, right):
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    # Not even accepted as a baseline.
    assert odom.update_from_positions(left, right, 0.1) is False
    assert odom.update_from_positions(0.0, 0.0, 0.1) is False  # this is the baseline
    assert odom.update_from_positions(left, right, 0.1) is False
    assert (odom.x_m, odom.y_m, odom.yaw_rad) == (0.0, 0.0, 0.0)
    assert odom.update_from_positions(1.0, 1.0, 0.1) is True
    assert odom.x_m == pytest.approx(1.0)


def test_reset():
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    odom.update_from_positions(0.0, 0.0, 0.1)
    odom.update_from_positions(1.0, 2.0, 0.1)
    assert odom.linear_m_s != 0.0
    odom.reset(x_m=1.0, y_m=2.0, yaw_rad=0.5)
    assert (odom.x_m, odom.y_m, odom.yaw_rad) == (1.0, 2.0, 0.5)
    assert (odom.linear_m_s, odom.angular_rad_s, odom.distance_m) == (0.0, 0.0, 0.0)
    # Baseline forgotten: the next reading (far from the old one) only re-arms.
    assert odom.update_from_positions(10.0, 10.0, 0.1) is False
    assert (odom.x_m, odom.y_m) == (1.0, 2.0)
    # Then 1 rad on both wheels along yaw 0.5: (1 + cos 0.5, 2 + sin 0.5).
    assert odom.update_from_positions(11.0, 11.0, 0.1) is True
    assert (odom.x_m, odom.y_m) == pytest.approx((1.0 + math.cos(0.5), 2.0 + math.sin(0.5)))


def test_reset_defaults_to_origin():
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0), x_m=3.0, y_m=4.0, yaw_rad=1.0)
    odom.reset()
    assert (odom.x_m, odom.y_m, odom.yaw_rad) == (0.0, 0.0, 0.0)


def test_yaw_wraps_around():
    # r = 1, s = 2, left -1, right +1 rad/s -> 1 rad/s.  Two 3 pi / 4 s steps turn
    # 3 pi / 2 in total, which is reported as -pi / 2.
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    odom.update_from_velocities(-1.0, 1.0, 0.75 * math.pi)
    assert odom.yaw_rad == pytest.approx(0.75 * math.pi)
    odom.update_from_velocities(-1.0, 1.0, 0.75 * math.pi)
    assert odom.yaw_rad == pytest.approx(-0.5 * math.pi)
    # Clockwise: from -pi/2 turning -3 pi / 4 reaches -5 pi / 4, reported as 3 pi / 4.
    odom.update_from_velocities(1.0, -1.0, 0.75 * math.pi)
    assert odom.yaw_rad == pytest.approx(0.75 * math.pi)


@pytest.mark.parametrize('yaw_in, yaw_out', [
    (math.pi, math.pi), (-math.pi, math.pi), (3 * math.pi, math.pi),
    (2 * math.pi, 0.0), (-0.5 * math.pi, -0.5 * math.pi), (2.5 * math.pi, 0.5 * math.pi),
])
def test_initial_yaw_is_wrapped_to_half_open_range(yaw_in, yaw_out):
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0), yaw_rad=yaw_in)
    assert odom.yaw_rad == pytest.approx(yaw_out, abs=1e-12)
    assert -math.pi < odom.yaw_rad <= math.pi


def test_distance_grows_for_forward_and_backward_motion():
    # r = 1: 1 m forward then 1 m backward -> back at x = 0, distance 2 m.
    odom = DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0))
    odom.update_from_velocities(1.0, 1.0, 1.0)
    assert odom.distance_m == pytest.approx(1.0)
    odom.update_from_velocities(-1.0, -1.0, 1.0)
    assert odom.x_m == pytest.approx(0.0, abs=1e-15)
    assert odom.distance_m == pytest.approx(2.0)
    assert odom.linear_m_s == pytest.approx(-1.0)


def test_distance_from_positions_going_backward():
    # Encoders run down by 0.5 rad with r = 2: x = -1 m, distance +1 m.
    odom = DiffDriveOdometry(DiffDriveGeometry(2.0, 1.0))
    odom.update_from_positions(3.0, 3.0, 0.1)
    odom.update_from_positions(2.5, 2.5, 0.1)
    assert odom.x_m == pytest.approx(-1.0)
    assert odom.distance_m == pytest.approx(1.0)


def test_constructor_rejects_non_finite_pose():
    with pytest.raises(ValueError):
        DiffDriveOdometry(DiffDriveGeometry(1.0, 2.0), x_m=math.nan)


class TestLimitTwist:
    """limit_twist keeps the curvature and never overflows."""

    # r = 1, s = 2, limit 10 rad/s: fastest wheel = |v| + |w| * 1.
    GEOMETRY = DiffDriveGeometry(wheel_radius_m=1.0, wheel_separation_m=2.0,
                                 max_wheel_velocity_rad_s=10.0)

    def test_within_limits_unchanged(self):
        """Leave a feasible twist (3 + 2 = 5 <= 10) untouched."""
        assert limit_twist(self.GEOMETRY, 3.0, 2.0) == (3.0, 2.0)

    def test_scales_both_components(self):
        """Scale (30, 10): fastest wheel 40 -> factor 1/4 -> (7.5, 2.5)."""
        v, w = limit_twist(self.GEOMETRY, 30.0, 10.0)
        assert v == pytest.approx(7.5)
        assert w == pytest.approx(2.5)

    @pytest.mark.parametrize('v, w, expected', [
        # (1e308, 1e308): fastest wheel 2e308 (overflow) -> (5, 5) after normalising.
        (1e308, 1e308, (5.0, 5.0)),
        (-1e308, 0.0, (-10.0, 0.0)),
        (0.0, 1e308, (0.0, 10.0)),
        (-0.0, -0.0, (0.0, 0.0)),
    ])
    def test_huge_values_stay_finite(self, v, w, expected):
        """Turn huge but finite commands into the fastest feasible twist."""
        result = limit_twist(self.GEOMETRY, v, w)
        assert result == pytest.approx(expected)
        assert all(math.isfinite(c) for c in result)

    def test_rejects_nan(self):
        """Refuse a NaN component."""
        with pytest.raises(ValueError):
            limit_twist(self.GEOMETRY, math.nan, 0.0)
