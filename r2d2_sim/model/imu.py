"""
The IMU model: orientation, angular velocity and specific force, with Gazebo's noise.

No ROS and no PyBullet (numpy only). :class:`ImuModel` takes the true
orientation and velocities of the sensor frame at each reading and returns
an :class:`ImuReading` as REP-145 has it: the acceleration comes from the
velocity's change since the last reading (so a teleport must ``reset`` it),
gravity is added as a specific force (+9.8 up at rest), and each channel's
noise (:mod:`r2d2_sim.model.noise`) draws from the ``numpy.random.Generator``
the caller passes in. The ray-cast sensors' math is in
:mod:`r2d2_sim.model.sensors`, which exports these names too.
"""

from dataclasses import dataclass
import math
from typing import Optional, Sequence, Tuple

import numpy

from r2d2_sim.model.noise import NoiseModel, NoiseSpec, quantize
from r2d2_sim.model.sensor_checks import require_generator, require_number, SensorConfigError
from r2d2_sim.model.transforms import (
    quaternion_from_axis_angle, quaternion_from_rpy, quaternion_multiply, rotate_inverse)

__all__ = ['ImuReading', 'ImuModel', 'STANDARD_GRAVITY_M_S2']

Vec3 = Tuple[float, float, float]
Quat = Tuple[float, float, float, float]

STANDARD_GRAVITY_M_S2: Vec3 = (0.0, 0.0, -9.8)


def _rotation_vector_quaternion(rotation_rad: numpy.ndarray) -> Quat:
    """Return the quaternion of a rotation by |r| about the axis r."""
    angle_rad = float(numpy.linalg.norm(rotation_rad))
    if angle_rad == 0.0:
        return (0.0, 0.0, 0.0, 1.0)
    return quaternion_from_axis_angle(rotation_rad.tolist(), angle_rad)


@dataclass(frozen=True)
class ImuReading:
    """One IMU sample as sensor_msgs/Imu carries it (REP-145)."""

    orientation_xyzw: Quat          # the sensor frame in the fixed world (ENU) frame
    angular_velocity_rad_s: Vec3    # in the sensor frame
    linear_acceleration_m_s2: Vec3  # specific force in the sensor frame: +9.8 up at rest


def _rpy(q: Quat) -> Vec3:
    """Return the roll, pitch, yaw of a unit quaternion: :func:`quaternion_from_rpy` undone."""
    x, y, z, w = q
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def _rounded_orientation(q: Quat, precision: float) -> Quat:
    """Return ``q`` with its roll, pitch and yaw each rounded to a multiple of ``precision``."""
    roll, pitch, yaw = quantize(numpy.array(_rpy(q)), precision).tolist()
    return quaternion_from_rpy(roll, pitch, yaw)


def _diagonal_covariance(variance: float) -> Tuple[float, ...]:
    return (variance, 0.0, 0.0, 0.0, variance, 0.0, 0.0, 0.0, variance)


def _imu_noise(name: str, std: float, spec: Optional[NoiseSpec]) -> NoiseSpec:
    """Return the spec of one IMU quantity, from its legacy std or its full spec (not both)."""
    std = require_number(name, std, minimum=0.0)
    if spec is None:
        return NoiseSpec(stddev=std)
    if std > 0.0:
        raise SensorConfigError(f'give either {name} or its noise spec, not both')
    if not isinstance(spec, NoiseSpec):
        raise SensorConfigError(f'the noise beside {name} must be a NoiseSpec, got {spec!r}')
    return spec


class ImuModel:
    """
    An ideal IMU plus Gazebo's noise, fed with the true motion of its frame.

    Each :meth:`update` takes the sensor frame's world orientation and the
    world-frame velocities of the sensor point. The orientation is reported
    as it is, relative to the fixed world frame (REP-145), not to the start
    pose. The acceleration is the specific force R^T (a - g), with a the
    backward difference of the world velocity since the previous update (0 on
    the first), so a level IMU at rest reads +9.8 m/s^2 on z. Each quantity
    has its :class:`~r2d2_sim.model.noise.NoiseSpec` (the ``*_std`` shorthands
    give white noise alone), applied to each of its three axes independently
    (each axis draws its own bias); the orientation noise is a small rotation
    about the world axes, and its precision rounds the noisy orientation's
    roll, pitch and yaw (fixed axes, as URDF's rpy). ``period_s`` (the IMU's
    period) steps the dynamic biases. All three quantities are provided, so
    their covariances are diagonal, each the spec's mean square error (never
    the -1 that marks a missing one).
    """

    def __init__(self, *, gravity_m_s2: Sequence[float] = STANDARD_GRAVITY_M_S2,
                 orientation_std_rad: float = 0.0,
                 angular_velocity_std_rad_s: float = 0.0,
                 linear_acceleration_std_m_s2: float = 0.0,
                 rng: Optional[numpy.random.Generator] = None,
                 orientation_noise: Optional[NoiseSpec] = None,
                 angular_velocity_noise: Optional[NoiseSpec] = None,
                 linear_acceleration_noise: Optional[NoiseSpec] = None,
                 period_s: float = 0.0) -> None:
        """Check the noise settings; the first update will have no previous sample."""
        if len(gravity_m_s2) != 3:
            raise SensorConfigError(f'gravity_m_s2 must have 3 components, got {gravity_m_s2!r}')
        self.gravity_m_s2 = numpy.array([require_number(f'gravity_m_s2[{i}]', value)
                                         for i, value in enumerate(gravity_m_s2)])
        self._gravity = tuple(self.gravity_m_s2.tolist())
        specs = (_imu_noise('orientation_std_rad', orientation_std_rad, orientation_noise),
                 _imu_noise('angular_velocity_std_rad_s', angular_velocity_std_rad_s,
                            angular_velocity_noise),
                 _imu_noise('linear_acceleration_std_m_s2', linear_acceleration_std_m_s2,
                            linear_acceleration_noise))
        if any(not spec.exact for spec in specs) and not isinstance(rng, numpy.random.Generator):
            require_generator(rng, 1.0)
        period_s = require_number('period_s', period_s, minimum=0.0)
        # Drawn in this order at construction (each axis's bias) and per update.
        self._orientation, self._angular, self._linear = (
            NoiseModel(spec, rng, channels=3, period_s=period_s) for spec in specs)
        self.orientation_std_rad = specs[0].stddev
        self.angular_velocity_std_rad_s = specs[1].stddev
        self.linear_acceleration_std_m_s2 = specs[2].stddev
        self.orientation_covariance = _diagonal_covariance(specs[0].variance)
        self.angular_velocity_covariance = _diagonal_covariance(specs[1].variance)
        self.linear_acceleration_covariance = _diagonal_covariance(specs[2].variance)
        self._exact = all(spec.exact for spec in specs)
        self._previous_time_s: Optional[float] = None
        self._previous_velocity_m_s: Optional[Tuple[float, float, float]] = None

    def reset(self) -> None:
        """Forget the previous sample (after a simulation reset, time restarts)."""
        self._previous_time_s = None
        self._previous_velocity_m_s = None

    def carry_on(self, before: 'ImuModel') -> None:
        """Take ``before``'s last sample: the motion goes on, only the noise is new."""
        self._previous_time_s = before._previous_time_s
        self._previous_velocity_m_s = before._previous_velocity_m_s

    def update(self, time_s: float, orientation_xyzw: Sequence[float],
               linear_velocity_m_s: Sequence[float],
               angular_velocity_rad_s: Sequence[float]) -> ImuReading:
        """
        Return the reading for the sensor's true state at ``time_s``.

        Velocities are in the world frame; ``linear_velocity_m_s`` is that of
        the sensor point itself (not of a link's centre of mass). ``time_s``
        must be later than the previous update's; ValueError otherwise.
        """
        # Plain float arithmetic on 3-vectors: numpy's per-call overhead made a
        # reading cost 19 us, about 60 us a message with the rest of the output.
        time_s = float(time_s)
        qx, qy, qz, qw = (float(c) for c in orientation_xyzw)
        norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        if not (norm > 0.0 and math.isfinite(norm)):
            raise ValueError(f'quaternion {tuple(orientation_xyzw)!r} has no orientation')
        q = (qx / norm, qy / norm, qz / norm, qw / norm)
        velocity_m_s = tuple(float(v) for v in linear_velocity_m_s)
        angular_world_rad_s = tuple(float(v) for v in angular_velocity_rad_s)
        if len(velocity_m_s) != 3 or len(angular_world_rad_s) != 3:
            raise ValueError('IMU velocities must have 3 components')
        if not math.isfinite(time_s + sum(velocity_m_s) + sum(angular_world_rad_s)):
            raise ValueError('IMU time and velocities must be finite, got '
                             f'{time_s!r}, {tuple(linear_velocity_m_s)!r}, '
                             f'{tuple(angular_velocity_rad_s)!r}')
        acceleration_m_s2 = self._acceleration(time_s, velocity_m_s)
        gx, gy, gz = self._gravity
        angular_rad_s = rotate_inverse(q, angular_world_rad_s)
        specific_force_m_s2 = rotate_inverse(q, (acceleration_m_s2[0] - gx,
                                                 acceleration_m_s2[1] - gy,
                                                 acceleration_m_s2[2] - gz))
        return self._with_noise(q, angular_rad_s, specific_force_m_s2)

    def _acceleration(self, time_s: float, velocity_m_s: Vec3) -> Vec3:
        """Difference the velocity with the previous update's (zero for the first)."""
        if self._previous_time_s is None:
            acceleration_m_s2 = (0.0, 0.0, 0.0)
        else:
            dt_s = time_s - self._previous_time_s
            if not dt_s > 0.0:
                raise ValueError(f'IMU time must increase: {time_s!r} s after '
                                 f'{self._previous_time_s!r} s (reset() after a time jump)')
            previous = self._previous_velocity_m_s
            assert previous is not None  # set and cleared with _previous_time_s
            (vx, vy, vz), (px, py, pz) = velocity_m_s, previous
            acceleration_m_s2 = ((vx - px) / dt_s, (vy - py) / dt_s, (vz - pz) / dt_s)
        self._previous_time_s = time_s
        self._previous_velocity_m_s = velocity_m_s
        return acceleration_m_s2

    def _with_noise(self, q: Quat, angular_rad_s: Vec3, specific_force_m_s2: Vec3
                    ) -> ImuReading:
        if not self._exact:
            orientation = self._orientation
            if not orientation.exact:
                # The error is a rotation about the world axes; precision rounds the
                # reading (its roll, pitch and yaw), as Gazebo rounds a value with
                # its noise, not the error alone.
                error_rad = orientation.error(3)
                q = quaternion_multiply(_rotation_vector_quaternion(error_rad), q)
                if orientation.spec.precision > 0.0:
                    q = _rounded_orientation(q, orientation.spec.precision)
            if not self._angular.exact:
                angular_rad_s = tuple(self._angular.apply(numpy.array(angular_rad_s)).tolist())
            if not self._linear.exact:
                specific_force_m_s2 = tuple(
                    self._linear.apply(numpy.array(specific_force_m_s2)).tolist())
        return ImuReading(orientation_xyzw=q, angular_velocity_rad_s=angular_rad_s,
                          linear_acceleration_m_s2=specific_force_m_s2)
