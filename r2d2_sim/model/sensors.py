"""
Sensor math for the laser scan, the 3D lidar and the depth camera; the IMU's names too.

No ROS and no PyBullet here (numpy only): PyBullet's rays are cast in
``raycast.py`` and the messages are filled by the node. Frames follow REP-103
(x forward, y left, z up; the world is ENU); laser ranges follow REP-117, IMU
data REP-145 and depth images REP-118. Every quantity carries its unit in its
name. Noise is Gazebo's (:mod:`r2d2_sim.model.noise`: white noise, a bias drawn
once, a drifting bias, rounding) and draws from a ``numpy.random.Generator``
the caller passes in, so a seeded generator gives the same readings on every run.

The IMU model, which keeps state between readings, is :mod:`r2d2_sim.model.imu`,
and the checks every sensor's settings pass are
:mod:`r2d2_sim.model.sensor_checks`; this module exports their public names.
"""

from dataclasses import dataclass
import math
import numbers
from typing import Optional, Sequence, Tuple

import numpy
from numpy.typing import ArrayLike

from r2d2_sim.model.imu import ImuModel, ImuReading
from r2d2_sim.model.noise import NoiseModel, NoiseSpec
from r2d2_sim.model.sensor_checks import require_generator, require_number, SensorConfigError
from r2d2_sim.model.transforms import rotate, rotate_inverse, rotation_matrix

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
        angle_min_rad = require_number('angle_min_rad', self.angle_min_rad)
        angle_max_rad = require_number('angle_max_rad', self.angle_max_rad)
        span_rad = angle_max_rad - angle_min_rad
        if not 0.0 < span_rad <= 2.0 * math.pi + FULL_CIRCLE_TOLERANCE_RAD:
            raise SensorConfigError(
                f'angle_max_rad must be above angle_min_rad by at most 2 pi, got '
                f'angle_min_rad={self.angle_min_rad!r}, angle_max_rad={self.angle_max_rad!r}')
        samples: object = self.samples  # any object: typeshed's int is no numbers.Integral
        if isinstance(samples, bool) or not isinstance(samples, numbers.Integral) \
                or samples < 2:
            raise SensorConfigError(f'samples must be an integer >= 2, got {self.samples!r}')
        range_min_m = require_number('range_min_m', self.range_min_m, minimum=0.0)
        range_max_m = require_number('range_max_m', self.range_max_m, minimum=range_min_m,
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
        increment_rad = require_number('angle_increment_rad', angle_increment_rad,
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


def ranges_from_hits(hit_fractions: ArrayLike, geometry: ScanGeometry,
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
    std_m = require_number('noise_std_m', noise_std_m, minimum=0.0)
    require_generator(rng, std_m)
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
        low = require_number('angle_min_rad', self.angle_min_rad, minimum=-math.pi / 2)
        high = require_number('angle_max_rad', self.angle_max_rad, minimum=low)
        if high > math.pi / 2:
            raise SensorConfigError(f'angle_max_rad must be at most pi/2, got {high!r}')
        if self.rings > 1 and high == low:
            raise SensorConfigError('several rings need angle_max_rad above angle_min_rad, '
                                    f'got both {low!r}')
        range_min_m = require_number('range_min_m', self.range_min_m, minimum=0.0)
        range_max_m = require_number('range_max_m', self.range_max_m, minimum=range_min_m,
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


def lidar_ranges(hit_fractions: ArrayLike, geometry: LidarGeometry,
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
    near_m = require_number('near_m', near_m, minimum=0.0, strict=True)
    far_m = require_number('far_m', far_m, minimum=near_m, strict=True)
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
