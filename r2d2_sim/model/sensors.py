"""
Sensor math for the laser scan, the IMU and the depth camera.

No ROS and no PyBullet here (numpy only): PyBullet's rays are cast in
``raycast.py`` and the messages are filled by the node. Frames follow REP-103
(x forward, y left, z up; the world is ENU); laser ranges follow REP-117, IMU
data REP-145 and depth images REP-118. Every quantity carries its unit in its
name. Noise is Gazebo's (:mod:`r2d2_sim.model.noise`: white noise, a bias drawn
once, a drifting bias, rounding) and draws from a ``numpy.random.Generator``
the caller passes in, so a seeded generator gives the same readings on every run.
"""

from dataclasses import dataclass
import math
import numbers
from typing import Optional, Sequence, Tuple

import numpy

from r2d2_sim.errors import SetupError
from r2d2_sim.model.noise import NoiseModel, NoiseSpec
from r2d2_sim.model.transforms import (
    quaternion_from_axis_angle, quaternion_multiply, rotate, rotate_inverse, rotation_matrix)

__all__ = [
    'SensorConfigError',
    'ScanGeometry',
    'beam_directions',
    'ray_endpoints',
    'ranges_from_hits',
    'rotate_vector',
    'rotate_vector_inverse',
    'ImuReading',
    'ImuModel',
    'linearize_depth',
    'noisy_depth',
    'LidarGeometry',
    'lidar_directions',
    'lidar_ranges',
]

Vec3 = Tuple[float, float, float]
Quat = Tuple[float, float, float, float]

# A scan whose span is 2 pi within this is a full circle (see ScanGeometry).
FULL_CIRCLE_TOLERANCE_RAD = 1e-9
STANDARD_GRAVITY_M_S2: Vec3 = (0.0, 0.0, -9.8)


class SensorConfigError(SetupError, ValueError):
    """Invalid sensor setting; the message names the field and its value."""


def _require_number(name: str, value: float, *, minimum: float = -math.inf,
                    strict: bool = False) -> float:
    """Return ``value`` as a float, or raise SensorConfigError naming ``name``."""
    ok = not isinstance(value, bool) and isinstance(value, numbers.Real) and math.isfinite(value)
    if ok:
        ok = value > minimum if strict else value >= minimum
    if not ok:
        bound = '' if minimum == -math.inf else f' {">" if strict else ">="} {minimum}'
        raise SensorConfigError(f'{name} must be a finite number{bound}, got {value!r}')
    return float(value)


def _require_generator(rng: Optional[numpy.random.Generator], *stds: float) -> None:
    """Refuse noise without a generator: unseeded noise would not be reproducible."""
    if any(std > 0.0 for std in stds) and not isinstance(rng, numpy.random.Generator):
        raise SensorConfigError(
            f'noise needs rng, a numpy.random.Generator (e.g. numpy.random.default_rng(seed)), '
            f'got {rng!r}')


# --------------------------------------------------------------------------- laser scan


@dataclass(frozen=True)
class ScanGeometry:
    """
    Beam angles and range limits of a planar laser (sensor_msgs/LaserScan).

    Beams lie in the sensor's x-y plane, counter-clockwise from
    ``angle_min_rad`` (0 is x forward, pi/2 is y left). ``samples`` beams share
    the span evenly with both ends included, so a LaserScan reader's count
    round((angle_max - angle_min) / angle_increment) + 1 is ``samples``.
    A full circle (span 2 pi within 1e-9) is the exception: its last beam
    would repeat the first, so the beams are 2 pi / samples apart and the
    angle_max to publish is :attr:`last_angle_rad`, angle_min + (samples - 1)
    * increment, which keeps the reader's count at ``samples``.
    """

    angle_min_rad: float
    angle_max_rad: float
    samples: int
    range_min_m: float
    range_max_m: float

    def __post_init__(self) -> None:
        """Validate the fields; store the angles and ranges as floats, samples as an int."""
        angle_min_rad = _require_number('angle_min_rad', self.angle_min_rad)
        angle_max_rad = _require_number('angle_max_rad', self.angle_max_rad)
        span_rad = angle_max_rad - angle_min_rad
        if not 0.0 < span_rad <= 2.0 * math.pi + FULL_CIRCLE_TOLERANCE_RAD:
            raise SensorConfigError(
                f'angle_max_rad must be above angle_min_rad by at most 2 pi, got '
                f'angle_min_rad={self.angle_min_rad!r}, angle_max_rad={self.angle_max_rad!r}')
        if isinstance(self.samples, bool) or not isinstance(self.samples, numbers.Integral) \
                or self.samples < 2:
            raise SensorConfigError(f'samples must be an integer >= 2, got {self.samples!r}')
        range_min_m = _require_number('range_min_m', self.range_min_m, minimum=0.0)
        range_max_m = _require_number('range_max_m', self.range_max_m, minimum=range_min_m,
                                      strict=True)
        object.__setattr__(self, 'angle_min_rad', angle_min_rad)
        object.__setattr__(self, 'angle_max_rad', angle_max_rad)
        object.__setattr__(self, 'range_min_m', range_min_m)
        object.__setattr__(self, 'range_max_m', range_max_m)
        object.__setattr__(self, 'samples', int(self.samples))

    @classmethod
    def from_increment(cls, angle_min_rad: float, angle_max_rad: float,
                       angle_increment_rad: float, range_min_m: float,
                       range_max_m: float) -> 'ScanGeometry':
        """
        Build the geometry with about ``angle_increment_rad`` between beams.

        samples = round(span / increment) + 1, or round(2 pi / increment) for
        a full circle; the increment is then adjusted so the beams fill the
        span exactly.
        """
        increment_rad = _require_number('angle_increment_rad', angle_increment_rad,
                                        minimum=0.0, strict=True)
        span_rad = angle_max_rad - angle_min_rad
        if abs(span_rad - 2.0 * math.pi) <= FULL_CIRCLE_TOLERANCE_RAD:
            samples = round(2.0 * math.pi / increment_rad)
        else:
            samples = round(span_rad / increment_rad) + 1
        return cls(angle_min_rad, angle_max_rad, samples, range_min_m, range_max_m)

    @property
    def full_circle(self) -> bool:
        """Return True when the beams go all the way round (span 2 pi)."""
        span_rad = self.angle_max_rad - self.angle_min_rad
        return abs(span_rad - 2.0 * math.pi) <= FULL_CIRCLE_TOLERANCE_RAD

    @property
    def angle_increment_rad(self) -> float:
        """Return the angle between neighbouring beams."""
        if self.full_circle:
            return 2.0 * math.pi / self.samples
        return (self.angle_max_rad - self.angle_min_rad) / (self.samples - 1)

    @property
    def last_angle_rad(self) -> float:
        """Return the angle of the last beam: the LaserScan angle_max to publish."""
        if self.full_circle:
            return self.angle_min_rad + (self.samples - 1) * self.angle_increment_rad
        return self.angle_max_rad

    @property
    def angles_rad(self) -> numpy.ndarray:
        """Return the angles of the ``samples`` beams, first to last."""
        return numpy.linspace(self.angle_min_rad, self.last_angle_rad, self.samples)


def beam_directions(geometry: ScanGeometry) -> numpy.ndarray:
    """Return the unit directions of the beams in the sensor frame, shape (samples, 3)."""
    angles_rad = geometry.angles_rad
    return numpy.stack([numpy.cos(angles_rad), numpy.sin(angles_rad),
                        numpy.zeros_like(angles_rad)], axis=1)


def ray_endpoints(geometry: ScanGeometry, origin_m: Sequence[float],
                  orientation_xyzw: Sequence[float] = (0.0, 0.0, 0.0, 1.0)
                  ) -> Tuple[numpy.ndarray, numpy.ndarray]:
    """
    Return the (samples, 3) start and end points of the beams of a laser at ``origin_m``.

    Every ray starts at the laser origin and is ``range_max_m`` long, so a hit
    fraction f is a range of f * range_max_m from the laser origin, as REP-117
    ranges are. ``orientation_xyzw`` is the sensor frame's orientation in the
    frame of ``origin_m`` (usually the world).
    """
    origin = numpy.asarray(origin_m, dtype=float).reshape(3)
    directions = beam_directions(geometry) @ numpy.array(
        rotation_matrix(_unit_quaternion(orientation_xyzw))).T
    starts = numpy.broadcast_to(origin, directions.shape).copy()
    return starts, origin + geometry.range_max_m * directions


def ranges_from_hits(hit_fractions: Sequence[float], geometry: ScanGeometry,
                     noise_std_m: float = 0.0,
                     rng: Optional[numpy.random.Generator] = None,
                     noise: Optional[NoiseModel] = None) -> numpy.ndarray:
    """
    Turn hit fractions along rays of length ``range_max_m`` into REP-117 ranges (float32).

    Fraction 1.0 (or more) means no return within range_max: +inf. A hit
    closer than range_min: -inf. Any other hit is fraction * range_max with
    the noise added (``noise``, a NoiseModel of one channel, or Gaussian noise
    of standard deviation ``noise_std_m`` from ``rng``; 0 and None: exact),
    rounded to its precision, then clipped into [range_min, range_max] so
    that noise never turns a hit into a miss or a too-close reading. Noise
    is drawn for every beam whatever was hit, so a seeded generator gives
    the same noise sequence in any world.
    """
    std_m = _require_number('noise_std_m', noise_std_m, minimum=0.0)
    _require_generator(rng, std_m)
    if noise is not None and std_m > 0.0:
        raise SensorConfigError('give either noise or noise_std_m, not both')
    if noise is None and std_m > 0.0:
        noise = NoiseModel(NoiseSpec(stddev=std_m), rng)
    fractions = numpy.asarray(hit_fractions, dtype=float)
    if fractions.shape != (geometry.samples,):
        raise ValueError(f'expected {geometry.samples} hit fractions, got shape '
                         f'{fractions.shape}')
    ranges_m = fractions * geometry.range_max_m
    no_return = fractions >= 1.0
    too_close = ~no_return & (ranges_m < geometry.range_min_m)
    if noise is not None and not noise.exact:
        ranges_m = numpy.clip(noise.apply(ranges_m), geometry.range_min_m, geometry.range_max_m)
    ranges_m[no_return] = math.inf
    ranges_m[too_close] = -math.inf
    return ranges_m.astype(numpy.float32)


# --------------------------------------------------------------------------- 3D lidar


@dataclass(frozen=True)
class LidarGeometry:
    """
    A multi-ring lidar: ``rings`` cones of beams, each with ``samples`` beams around a full turn.

    Ring 0 is the lowest (elevation ``angle_min_rad``, negative below the
    sensor's x-y plane), the last the highest (``angle_max_rad``), evenly
    apart; the rings are numbered as Velodyne drivers number them. Each
    ring's beams start behind the sensor (azimuth -pi) and go round
    counter-clockwise, 2 pi / samples apart, as a full-circle LaserScan's.
    """

    rings: int
    angle_min_rad: float
    angle_max_rad: float
    samples: int
    range_min_m: float
    range_max_m: float

    def __post_init__(self) -> None:
        """Validate the fields; store the angles and ranges as floats."""
        for name in ('rings', 'samples'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
                raise SensorConfigError(f'{name} must be an integer >= 1, got {value!r}')
            object.__setattr__(self, name, int(value))
        low = _require_number('angle_min_rad', self.angle_min_rad, minimum=-math.pi / 2)
        high = _require_number('angle_max_rad', self.angle_max_rad, minimum=low)
        if high > math.pi / 2:
            raise SensorConfigError(f'angle_max_rad must be at most pi/2, got {high!r}')
        if self.rings > 1 and high == low:
            raise SensorConfigError('several rings need angle_max_rad above angle_min_rad, '
                                    f'got both {low!r}')
        range_min_m = _require_number('range_min_m', self.range_min_m, minimum=0.0)
        range_max_m = _require_number('range_max_m', self.range_max_m, minimum=range_min_m,
                                      strict=True)
        object.__setattr__(self, 'angle_min_rad', low)
        object.__setattr__(self, 'angle_max_rad', high)
        object.__setattr__(self, 'range_min_m', range_min_m)
        object.__setattr__(self, 'range_max_m', range_max_m)

    @property
    def elevations_rad(self) -> numpy.ndarray:
        """Return each ring's elevation, lowest first."""
        return numpy.linspace(self.angle_min_rad, self.angle_max_rad, self.rings)

    @property
    def azimuths_rad(self) -> numpy.ndarray:
        """Return each beam's azimuth within a ring, from -pi counter-clockwise."""
        return -math.pi + 2.0 * math.pi / self.samples * numpy.arange(self.samples)


def lidar_directions(geometry: LidarGeometry) -> numpy.ndarray:
    """Return the unit direction of every beam in the sensor frame, (rings, samples, 3)."""
    elevation = geometry.elevations_rad[:, None]
    azimuth = geometry.azimuths_rad[None, :]
    return numpy.stack(numpy.broadcast_arrays(numpy.cos(elevation) * numpy.cos(azimuth),
                                              numpy.cos(elevation) * numpy.sin(azimuth),
                                              numpy.sin(elevation)), axis=-1)


def lidar_ranges(hit_fractions: Sequence[float], geometry: LidarGeometry,
                 noise: Optional[NoiseModel] = None) -> numpy.ndarray:
    """
    Turn hit fractions along rays of ``range_max_m`` into ranges, (rings, samples) float64.

    As :func:`ranges_from_hits` does (noise drawn for every beam, rounded,
    clipped into the range), except that a beam without a return within
    range, or with one closer than ``range_min_m``, is NaN: a point cloud
    has no place for REP-117's infinities, and an organised one keeps a NaN
    point in the place of every beam that measured nothing.
    """
    fractions = numpy.asarray(hit_fractions, dtype=float)
    shape = (geometry.rings, geometry.samples)
    if fractions.size != geometry.rings * geometry.samples:
        raise ValueError(f'expected {shape[0] * shape[1]} hit fractions, got {fractions.size}')
    ranges_m = fractions.reshape(shape) * geometry.range_max_m
    invalid = (fractions.reshape(shape) >= 1.0) | (ranges_m < geometry.range_min_m)
    if noise is not None and not noise.exact:
        ranges_m = numpy.clip(noise.apply(ranges_m), geometry.range_min_m, geometry.range_max_m)
    ranges_m[invalid] = numpy.nan
    return ranges_m


# --------------------------------------------------------------------------- rotations


def _unit_quaternion(q: Sequence[float]) -> Tuple[float, float, float, float]:
    """Return ``q`` (x, y, z, w) normalised, or raise ValueError if it has no direction."""
    x, y, z, w = (float(c) for c in q)
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    if not (math.isfinite(norm) and norm > 0.0):
        raise ValueError(f'quaternion must be finite and non-zero, got {tuple(q)!r}')
    return (x / norm, y / norm, z / norm, w / norm)


def rotate_vector(q: Sequence[float], v: Sequence[float]) -> numpy.ndarray:
    """Rotate ``v`` by the quaternion ``q`` (x, y, z, w): a frame's vector into its parent."""
    return numpy.array(rotate(_unit_quaternion(q), v))


def rotate_vector_inverse(q: Sequence[float], v: Sequence[float]) -> numpy.ndarray:
    """Rotate ``v`` by the inverse of ``q``: a parent (world) vector into the frame ``q``."""
    return numpy.array(rotate_inverse(_unit_quaternion(q), v))


def _rotation_vector_quaternion(rotation_rad: numpy.ndarray) -> Tuple[float, ...]:
    """Return the quaternion of a rotation by |r| about the axis r."""
    angle_rad = float(numpy.linalg.norm(rotation_rad))
    if angle_rad == 0.0:
        return (0.0, 0.0, 0.0, 1.0)
    return quaternion_from_axis_angle(rotation_rad.tolist(), angle_rad)


# --------------------------------------------------------------------------- IMU


@dataclass(frozen=True)
class ImuReading:
    """One IMU sample as sensor_msgs/Imu carries it (REP-145)."""

    orientation_xyzw: Quat          # the sensor frame in the fixed world (ENU) frame
    angular_velocity_rad_s: Vec3    # in the sensor frame
    linear_acceleration_m_s2: Vec3  # specific force in the sensor frame: +9.8 up at rest


def _diagonal_covariance(variance: float) -> Tuple[float, ...]:
    return (variance, 0.0, 0.0, 0.0, variance, 0.0, 0.0, 0.0, variance)


def _imu_noise(name: str, std: float, spec: Optional[NoiseSpec]) -> NoiseSpec:
    """Return the spec of one IMU quantity, from its legacy std or its full spec (not both)."""
    std = _require_number(name, std, minimum=0.0)
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
    about the world axes. ``period_s`` (the IMU's period) steps the dynamic
    biases. All three quantities are provided, so their covariances are
    diagonal, each the spec's mean square error (never the -1 that marks a
    missing one).
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
        self.gravity_m_s2 = numpy.array([_require_number(f'gravity_m_s2[{i}]', value)
                                         for i, value in enumerate(gravity_m_s2)])
        self._gravity = tuple(self.gravity_m_s2.tolist())
        specs = (_imu_noise('orientation_std_rad', orientation_std_rad, orientation_noise),
                 _imu_noise('angular_velocity_std_rad_s', angular_velocity_std_rad_s,
                            angular_velocity_noise),
                 _imu_noise('linear_acceleration_std_m_s2', linear_acceleration_std_m_s2,
                            linear_acceleration_noise))
        if any(not spec.exact for spec in specs) and not isinstance(rng, numpy.random.Generator):
            _require_generator(rng, 1.0)
        period_s = _require_number('period_s', period_s, minimum=0.0)
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

    def _acceleration(self, time_s: float, velocity_m_s: Tuple[float, ...]) -> Tuple[float, ...]:
        """Difference the velocity with the previous update's (zero for the first)."""
        if self._previous_time_s is None:
            acceleration_m_s2 = (0.0, 0.0, 0.0)
        else:
            dt_s = time_s - self._previous_time_s
            if not dt_s > 0.0:
                raise ValueError(f'IMU time must increase: {time_s!r} s after '
                                 f'{self._previous_time_s!r} s (reset() after a time jump)')
            previous = self._previous_velocity_m_s
            acceleration_m_s2 = tuple((v - p) / dt_s for v, p in zip(velocity_m_s, previous))
        self._previous_time_s = time_s
        self._previous_velocity_m_s = velocity_m_s
        return acceleration_m_s2

    def _with_noise(self, q, angular_rad_s, specific_force_m_s2) -> ImuReading:
        if not self._exact:
            if not self._orientation.exact:
                error_rad = self._orientation.apply(numpy.zeros(3))
                q = quaternion_multiply(_rotation_vector_quaternion(error_rad), q)
            if not self._angular.exact:
                angular_rad_s = tuple(self._angular.apply(numpy.array(angular_rad_s)).tolist())
            if not self._linear.exact:
                specific_force_m_s2 = tuple(
                    self._linear.apply(numpy.array(specific_force_m_s2)).tolist())
        return ImuReading(orientation_xyzw=q, angular_velocity_rad_s=angular_rad_s,
                          linear_acceleration_m_s2=specific_force_m_s2)


# --------------------------------------------------------------------------- depth image


def linearize_depth(depth_buffer: numpy.ndarray, near_m: float, far_m: float) -> numpy.ndarray:
    """
    Convert an OpenGL depth buffer (d in [0, 1]) into REP-118 depths in metres (float32).

    z = far * near / (far - (far - near) * d) is the distance along the
    optical axis (not along the pixel's ray), for any near and far plane.
    d >= 1 is the far plane, where nothing was drawn: +inf. d < 0 would be
    before the near plane: -inf (d = 0 is an object at the near plane).
    ``depth_buffer`` must be shaped (height, width), as ``getCameraImage``
    returns it with numpy.
    """
    near_m = _require_number('near_m', near_m, minimum=0.0, strict=True)
    far_m = _require_number('far_m', far_m, minimum=near_m, strict=True)
    d = numpy.asarray(depth_buffer, dtype=float)
    if d.ndim != 2:
        raise ValueError(f'depth buffer must be shaped (height, width), got shape {d.shape}')
    with numpy.errstate(divide='ignore', invalid='ignore'):
        depth_m = far_m * near_m / (far_m - (far_m - near_m) * d)
    depth_m[d >= 1.0] = math.inf
    depth_m[d < 0.0] = -math.inf
    return depth_m.astype(numpy.float32)


def noisy_depth(depth_m: numpy.ndarray, noise: NoiseModel, near_m: float, far_m: float
                ) -> numpy.ndarray:
    """
    Return a REP-118 depth image (float32) with ``noise`` (one channel) on every finite pixel.

    The noise is drawn for every pixel, finite or not (so the stream does
    not depend on what is in view), and a noisy depth is clipped into
    [near, far] so that noise never makes a miss or a negative depth; +inf
    and -inf pixels stay as they are.
    """
    if noise.exact:
        return depth_m
    depth = numpy.asarray(depth_m, dtype=float)
    finite = numpy.isfinite(depth)
    noisy = numpy.clip(noise.apply(numpy.where(finite, depth, 0.0)), near_m, far_m)
    return numpy.where(finite, noisy, depth).astype(numpy.float32)
