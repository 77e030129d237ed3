"""Unit tests for r2d2_sim.model.sensors: laser scan, IMU and depth math (no ROS, no PyBullet)."""

import math

import numpy
import pytest

from r2d2_sim.model.sensors import (
    beam_directions,
    ImuModel,
    linearize_depth,
    ranges_from_hits,
    ray_endpoints,
    rotate_vector,
    rotate_vector_inverse,
    ScanGeometry,
    SensorConfigError,
)
from r2d2_sim.model.noise import NoiseSpec
from r2d2_sim.model.transforms import quaternion_from_rpy

HALF_SQRT2 = math.sqrt(0.5)
IDENTITY = (0.0, 0.0, 0.0, 1.0)
ROLL_90 = (HALF_SQRT2, 0.0, 0.0, HALF_SQRT2)  # +90 deg about x
YAW_90 = (0.0, 0.0, HALF_SQRT2, HALF_SQRT2)   # +90 deg about z


def laser_scan_reader_count(angle_min_rad, angle_max_rad, angle_increment_rad):
    """Count readings as a LaserScan consumer does (REP-117)."""
    return round((angle_max_rad - angle_min_rad) / angle_increment_rad) + 1


# --------------------------------------------------------------------------- scan geometry


def test_full_circle_of_360_beams_is_one_degree_apart_without_a_duplicate():
    """-pi..pi with 360 beams: 1 deg apart, last at 179 deg, and a reader counts 360."""
    geometry = ScanGeometry(-math.pi, math.pi, 360, 0.1, 10.0)
    assert geometry.full_circle
    assert geometry.angle_increment_rad == pytest.approx(math.radians(1.0))
    angles = geometry.angles_rad
    assert angles.shape == (360,)
    assert angles[0] == -math.pi
    assert angles[-1] == pytest.approx(math.radians(179.0))
    assert geometry.last_angle_rad == pytest.approx(math.radians(179.0))
    # One more increment after the last beam is the first beam again, a full turn later.
    assert angles[-1] + geometry.angle_increment_rad == pytest.approx(angles[0] + 2 * math.pi)
    assert laser_scan_reader_count(geometry.angle_min_rad, geometry.last_angle_rad,
                                   geometry.angle_increment_rad) == 360
    assert numpy.diff(angles) == pytest.approx(numpy.full(359, math.radians(1.0)))


def test_270_degree_scan_at_one_degree_has_271_readings():
    """-135..+135 deg at 1 deg: 270 gaps, 271 readings, both ends included."""
    geometry = ScanGeometry.from_increment(math.radians(-135), math.radians(135),
                                           math.radians(1.0), 0.05, 30.0)
    assert geometry.samples == 271
    assert not geometry.full_circle
    assert geometry.angle_increment_rad == pytest.approx(math.radians(1.0))
    assert geometry.last_angle_rad == geometry.angle_max_rad
    assert geometry.angles_rad[[0, 135, 270]] == pytest.approx(
        [math.radians(-135), 0.0, math.radians(135)])
    assert laser_scan_reader_count(geometry.angle_min_rad, geometry.angle_max_rad,
                                   geometry.angle_increment_rad) == 271


def test_from_increment_of_a_full_circle_does_not_add_the_closing_beam():
    """0..2 pi at 0.5 deg: 720 beams (not 721), 0.5 deg apart."""
    geometry = ScanGeometry.from_increment(0.0, 2 * math.pi, math.radians(0.5), 0.1, 5.0)
    assert geometry.samples == 720
    assert geometry.angle_increment_rad == pytest.approx(math.radians(0.5))


@pytest.mark.parametrize('field, value', [
    ('angle_max_rad', -1.0),            # below angle_min
    ('angle_max_rad', 2 * math.pi),     # span above 2 pi
    ('angle_min_rad', math.nan),
    ('samples', 1),
    ('samples', 10.0),
    ('range_min_m', -0.1),
    ('range_max_m', 0.05),              # below range_min
    ('range_max_m', math.inf),
])
def test_scan_geometry_rejects_bad_fields_by_name(field, value):
    kwargs = dict(angle_min_rad=-1.0, angle_max_rad=1.0, samples=10, range_min_m=0.1,
                  range_max_m=10.0)
    kwargs[field] = value
    with pytest.raises(SensorConfigError, match=field):
        ScanGeometry(**kwargs)


def test_beam_directions_follow_rep_103():
    """Angle 0 is +x (forward), +90 deg is +y (left), 180 deg is -x."""
    geometry = ScanGeometry(-math.pi, math.pi, 4, 0.1, 10.0)  # -180, -90, 0, 90 deg
    directions = beam_directions(geometry)
    assert directions == pytest.approx(numpy.array(
        [[-1, 0, 0], [0, -1, 0], [1, 0, 0], [0, 1, 0]]), abs=1e-12)


def test_rays_start_at_the_laser_origin_and_are_range_max_long():
    """A laser at (1, 2, 0.3) yawed +90 deg: its forward beam runs along world +y for 10 m."""
    geometry = ScanGeometry(-math.pi / 2, math.pi / 2, 3, 0.1, 10.0)  # -90, 0, +90 deg
    starts, ends = ray_endpoints(geometry, (1.0, 2.0, 0.3), YAW_90)
    assert starts == pytest.approx(numpy.tile([1.0, 2.0, 0.3], (3, 1)))
    # Sensor +x is world +y, sensor +y is world -x, sensor -y is world +x.
    assert ends == pytest.approx(numpy.array(
        [[11.0, 2.0, 0.3], [1.0, 12.0, 0.3], [-9.0, 2.0, 0.3]]), abs=1e-12)


# --------------------------------------------------------------------------- ranges


def scan_of(samples, range_min_m=0.2, range_max_m=10.0):
    return ScanGeometry(-1.0, 1.0, samples, range_min_m, range_max_m)


def test_ranges_follow_rep_117():
    """Half of 10 m is 5 m; no hit is +inf; 0.1 m is inside range_min 0.2: -inf."""
    ranges = ranges_from_hits([0.5, 1.0, 0.01, 0.0, 0.02], scan_of(5))
    assert ranges.dtype == numpy.float32
    assert ranges[0] == pytest.approx(5.0)
    assert ranges[1] == math.inf
    assert ranges[2] == -math.inf and ranges[3] == -math.inf
    assert ranges[4] == pytest.approx(0.2)  # exactly range_min is a valid reading


def test_noise_is_clipped_into_the_valid_range_never_turned_into_inf():
    """Hits near either limit with noise far larger than the margin stay finite readings."""
    geometry = scan_of(1000)
    fractions = numpy.where(numpy.arange(1000) % 2 == 0, 0.999, 0.021)  # 9.99 m and 0.21 m
    ranges = ranges_from_hits(fractions, geometry, 0.5, numpy.random.default_rng(7))
    assert numpy.isfinite(ranges).all()
    assert ranges.min() == pytest.approx(0.2) and ranges.max() == pytest.approx(10.0)
    assert (ranges >= numpy.float32(0.2)).all() and (ranges <= numpy.float32(10.0)).all()


def test_noise_keeps_misses_and_too_close_hits():
    ranges = ranges_from_hits([1.0, 0.001, 0.5], scan_of(3), 1.0, numpy.random.default_rng(1))
    assert ranges[0] == math.inf and ranges[1] == -math.inf and math.isfinite(ranges[2])


def test_seeded_noise_is_reproducible_and_has_the_requested_spread():
    geometry = scan_of(20000)
    fractions = numpy.full(20000, 0.5)  # 5 m, far from both limits
    first = ranges_from_hits(fractions, geometry, 0.01, numpy.random.default_rng(42))
    again = ranges_from_hits(fractions, geometry, 0.01, numpy.random.default_rng(42))
    other = ranges_from_hits(fractions, geometry, 0.01, numpy.random.default_rng(43))
    assert numpy.array_equal(first, again)
    assert not numpy.array_equal(first, other)
    errors_m = first.astype(float) - 5.0
    # The mean of 20000 samples is within 4 standard errors (4 * 0.01 / sqrt(20000)).
    assert abs(errors_m.mean()) < 4 * 0.01 / math.sqrt(20000)
    assert errors_m.std() == pytest.approx(0.01, rel=0.05)


def test_noise_without_a_generator_is_refused():
    with pytest.raises(SensorConfigError, match='rng'):
        ranges_from_hits([0.5, 0.5], scan_of(2), 0.1)


def test_ranges_need_one_fraction_per_beam():
    with pytest.raises(ValueError, match='expected 5'):
        ranges_from_hits([0.5, 0.5], scan_of(5))


# --------------------------------------------------------------------------- rotations


def test_rotate_vector_inverse_expresses_world_vectors_in_the_rotated_frame():
    """A frame yawed +90 deg: its x is world +y, so world +x lies along its -y."""
    assert rotate_vector_inverse(YAW_90, (1.0, 0.0, 0.0)) == pytest.approx(
        [0.0, -1.0, 0.0], abs=1e-12)
    assert rotate_vector(YAW_90, (1.0, 0.0, 0.0)) == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)
    v = (0.3, -1.2, 2.5)
    assert rotate_vector(ROLL_90, rotate_vector_inverse(ROLL_90, v)) == pytest.approx(v)


# --------------------------------------------------------------------------- IMU


def test_imu_at_rest_and_level_reads_plus_g_on_z():
    imu = ImuModel()
    for t in (0.0, 0.01, 0.02):
        reading = imu.update(t, IDENTITY, (0, 0, 0), (0, 0, 0))
        assert reading.linear_acceleration_m_s2 == pytest.approx((0.0, 0.0, 9.8))
        assert reading.angular_velocity_rad_s == (0.0, 0.0, 0.0)
        assert reading.orientation_xyzw == pytest.approx(IDENTITY)


def test_imu_rolled_90_degrees_reads_gravity_on_its_y_axis():
    """Rolled +90 deg about x, the sensor's y axis points up: it reads +9.8 on y."""
    # Sensor y = R (0, 1, 0) = (0, cos 90, sin 90) = world up; sensor z = world -y.
    imu = ImuModel()
    imu.update(0.0, ROLL_90, (0, 0, 0), (0, 0, 0))
    reading = imu.update(0.01, ROLL_90, (0, 0, 0), (0, 0, 0))
    assert reading.linear_acceleration_m_s2 == pytest.approx((0.0, 9.8, 0.0), abs=1e-12)


def test_imu_reads_constant_world_acceleration_in_its_own_frame():
    """2 m/s^2 along world x seen by a sensor yawed +90 deg: -2 on its y, +9.8 on z."""
    # Sensor x = world y, sensor y = world -x: (2, 0, 9.8) in world is (0, -2, 9.8).
    imu = ImuModel()
    readings = [imu.update(0.01 * k, YAW_90, (2.0 * 0.01 * k, 0, 0), (0, 0, 0))
                for k in range(5)]
    assert readings[0].linear_acceleration_m_s2 == pytest.approx((0.0, 0.0, 9.8), abs=1e-12)
    for reading in readings[1:]:
        assert reading.linear_acceleration_m_s2 == pytest.approx((0.0, -2.0, 9.8), abs=1e-9)


def test_imu_first_sample_has_no_acceleration_even_when_moving():
    imu = ImuModel()
    reading = imu.update(5.0, IDENTITY, (1.0, 2.0, 0.0), (0, 0, 0))
    assert reading.linear_acceleration_m_s2 == pytest.approx((0.0, 0.0, 9.8))


def test_imu_orientation_is_the_world_orientation_not_relative_to_the_start():
    """A sensor that starts yawed 30 deg reports 30 deg of yaw, not identity."""
    yaw_30 = (0.0, 0.0, math.sin(math.radians(15)), math.cos(math.radians(15)))
    imu = ImuModel()
    assert imu.update(0.0, yaw_30, (0, 0, 0), (0, 0, 0)).orientation_xyzw == \
        pytest.approx(yaw_30)
    assert imu.update(0.1, yaw_30, (0, 0, 0), (0, 0, 0)).orientation_xyzw == \
        pytest.approx(yaw_30)


def test_imu_angular_velocity_is_expressed_in_the_sensor_frame():
    """Spinning about world z at 1 rad/s, a sensor rolled +90 deg (y up) reads it on y."""
    imu = ImuModel()
    reading = imu.update(0.0, ROLL_90, (0, 0, 0), (0.0, 0.0, 1.0))
    assert reading.angular_velocity_rad_s == pytest.approx((0.0, 1.0, 0.0), abs=1e-12)


def test_imu_covariances_are_the_variances_on_the_diagonal():
    imu = ImuModel(orientation_std_rad=0.01, angular_velocity_std_rad_s=0.02,
                   linear_acceleration_std_m_s2=0.5, rng=numpy.random.default_rng(0))
    assert imu.orientation_covariance == pytest.approx(
        (1e-4, 0, 0, 0, 1e-4, 0, 0, 0, 1e-4))
    assert imu.angular_velocity_covariance == pytest.approx(
        (4e-4, 0, 0, 0, 4e-4, 0, 0, 0, 4e-4))
    assert imu.linear_acceleration_covariance == pytest.approx(
        (0.25, 0, 0, 0, 0.25, 0, 0, 0, 0.25))
    exact = ImuModel()
    assert exact.orientation_covariance == (0.0,) * 9  # provided and exact, not -1


def imu_noise_run(seed, samples=4000):
    imu = ImuModel(orientation_std_rad=0.01, angular_velocity_std_rad_s=0.02,
                   linear_acceleration_std_m_s2=0.5, rng=numpy.random.default_rng(seed))
    readings = [imu.update(0.01 * k, IDENTITY, (0, 0, 0), (0, 0, 0)) for k in range(samples)]
    return (numpy.array([r.orientation_xyzw for r in readings]),
            numpy.array([r.angular_velocity_rad_s for r in readings]),
            numpy.array([r.linear_acceleration_m_s2 for r in readings]))


def test_imu_noise_is_seeded_and_has_the_requested_spread():
    orientation, angular, linear = imu_noise_run(3)
    again = imu_noise_run(3)
    assert all(numpy.array_equal(a, b) for a, b in zip((orientation, angular, linear), again))
    assert not numpy.array_equal(linear, imu_noise_run(4)[2])
    assert angular.std(axis=0) == pytest.approx([0.02] * 3, rel=0.06)
    assert (linear - [0, 0, 9.8]).std(axis=0) == pytest.approx([0.5] * 3, rel=0.06)
    assert linear.mean(axis=0) == pytest.approx([0, 0, 9.8], abs=4 * 0.5 / math.sqrt(4000))
    # A small rotation by r about the axes has quaternion ~ (r / 2, 1): x, y, z spread 0.005.
    assert numpy.linalg.norm(orientation, axis=1) == pytest.approx(numpy.ones(4000))
    assert orientation[:, :3].std(axis=0) == pytest.approx([0.005] * 3, rel=0.06)


def rpy_of(q):
    """Return roll, pitch, yaw (fixed axes, URDF's rpy) of a quaternion (x, y, z, w)."""
    x, y, z, w = q
    return numpy.array([math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)),
                        math.asin(2 * (w * y - z * x)),
                        math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))])


@pytest.mark.parametrize('std', [0.0, 0.02])
def test_imu_orientation_precision_rounds_the_reported_angles(std):
    """
    Roll, pitch and yaw of the reading are multiples of the precision, within half a step.

    The precision once rounded only the noise's rotation (0 without white
    noise: the true orientation came out), while the covariance counted
    precision^2 / 12 of rounding.
    """
    precision = 0.1
    imu = ImuModel(orientation_noise=NoiseSpec(stddev=std, precision=precision),
                   rng=numpy.random.default_rng(1))
    assert imu.orientation_covariance[0] == pytest.approx(std ** 2 + precision ** 2 / 12)
    rng = numpy.random.default_rng(2)
    errors = []
    for k in range(500):
        true_rpy = rng.uniform([-1.0, -1.0, -3.0], [1.0, 1.0, 3.0])
        reading = imu.update(0.01 * (k + 1), quaternion_from_rpy(*true_rpy), (0, 0, 0),
                             (0, 0, 0))
        rpy = rpy_of(reading.orientation_xyzw)
        assert numpy.allclose(rpy / precision, numpy.round(rpy / precision), atol=1e-9)
        errors.append(rpy - true_rpy)
    errors = numpy.array(errors)
    if std == 0.0:
        assert numpy.abs(errors).max() <= precision / 2 + 1e-9
        # Rounding spreads the angles uniformly over a step: its variance is p^2 / 12.
        assert errors.var(axis=0) == pytest.approx([precision ** 2 / 12] * 3, rel=0.2)
    else:
        assert errors.std(axis=0) == pytest.approx([math.sqrt(std ** 2 + precision ** 2 / 12)]
                                                   * 3, rel=0.2)


def test_imu_refuses_time_going_back_until_reset():
    imu = ImuModel()
    imu.update(1.0, IDENTITY, (0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError, match='increase'):
        imu.update(1.0, IDENTITY, (0, 0, 0), (0, 0, 0))
    imu.reset()
    reading = imu.update(0.0, IDENTITY, (3.0, 0, 0), (0, 0, 0))
    assert reading.linear_acceleration_m_s2 == pytest.approx((0.0, 0.0, 9.8))


@pytest.mark.parametrize('field', ['orientation_std_rad', 'angular_velocity_std_rad_s',
                                   'linear_acceleration_std_m_s2'])
def test_imu_rejects_negative_noise_by_name(field):
    with pytest.raises(SensorConfigError, match=field):
        ImuModel(**{field: -0.1}, rng=numpy.random.default_rng(0))


def test_imu_noise_needs_a_generator():
    with pytest.raises(SensorConfigError, match='rng'):
        ImuModel(angular_velocity_std_rad_s=0.1)


# --------------------------------------------------------------------------- depth


def opengl_depth(z_m, near_m, far_m):
    """Window depth d of a point z_m in front of a gluPerspective camera, from its matrix."""
    # Eye-space z is -z_m; clip z = A z_e + B, clip w = -z_e; d = (z_clip / w + 1) / 2.
    a = (far_m + near_m) / (near_m - far_m)
    b = 2.0 * far_m * near_m / (near_m - far_m)
    z_eye = -z_m
    return ((a * z_eye + b) / -z_eye + 1.0) / 2.0


def test_depth_of_one_metre_with_near_0_01_and_far_100():
    """One metre is d = f (z - n) / (z (f - n)) = 100 * 0.99 / 99.99 = 0.990099..."""
    d = 100.0 * 0.99 / 99.99
    assert opengl_depth(1.0, 0.01, 100.0) == pytest.approx(d, abs=1e-12)
    depth = linearize_depth(numpy.array([[d]]), 0.01, 100.0)
    assert depth.dtype == numpy.float32 and depth.shape == (1, 1)
    assert depth[0, 0] == pytest.approx(1.0, rel=1e-6)


def test_depth_round_trips_for_near_0_1_and_far_10():
    """With near != 1 the full formula matters: z -> d -> z from just past near to far."""
    z_m = numpy.array([[0.11, 0.25, 0.5], [1.0, 3.7, 9.99]])
    depth = linearize_depth(opengl_depth(z_m, 0.1, 10.0), 0.1, 10.0)
    assert depth.shape == (2, 3)
    assert depth == pytest.approx(z_m.astype(numpy.float32), rel=1e-6)


def test_depth_far_plane_is_plus_inf_and_before_near_is_minus_inf():
    depth = linearize_depth(numpy.array([[1.0, -0.1], [0.5, 1.2]]), 0.1, 10.0)
    assert depth[0, 0] == math.inf and depth[1, 1] == math.inf
    assert depth[0, 1] == -math.inf
    # d = 0 is an object on the near plane: a valid distance, like a laser's range_min.
    assert linearize_depth(numpy.zeros((1, 1)), 0.1, 10.0)[0, 0] == pytest.approx(0.1)
    # Half-way in the buffer is only 2 n f / (f + n) = 0.198 m, not half-way in metres.
    assert depth[1, 0] == pytest.approx(2 * 0.1 * 10.0 / 10.1, rel=1e-6)


def test_depth_checks_its_planes_and_shape():
    with pytest.raises(SensorConfigError, match='far_m'):
        linearize_depth(numpy.zeros((2, 2)), 1.0, 0.5)
    with pytest.raises(SensorConfigError, match='near_m'):
        linearize_depth(numpy.zeros((2, 2)), 0.0, 10.0)
    with pytest.raises(ValueError, match='height, width'):
        linearize_depth(numpy.zeros(4), 0.1, 10.0)


def test_a_number_is_compared_as_the_float_returned():
    """A Fraction just above 0 is 0.0 as a float: a strict bound at 0 refuses it."""
    from fractions import Fraction
    from r2d2_sim.model.sensor_checks import require_number, SensorConfigError
    assert require_number('x', Fraction(1, 4), minimum=0.0, strict=True) == 0.25
    with pytest.raises(SensorConfigError, match='x'):
        require_number('x', Fraction(1, 10**400), minimum=0.0, strict=True)
