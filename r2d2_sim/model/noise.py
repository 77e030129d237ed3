"""
Sensor noise as Gazebo's ``<noise>`` means it: white noise, a bias drawn once, a drifting bias.

No ROS and no PyBullet here (numpy only). A :class:`NoiseSpec` holds the
seven numbers of Gazebo's Gaussian noise (gz-sensors ``GaussianNoiseModel``):
``mean`` and ``stddev`` of the white noise drawn for every value, a constant
bias drawn once from N(``bias_mean``, ``bias_stddev``) whose sign is then
flipped with probability 0.5, a dynamic bias following a first-order
Gauss-Markov process (``dynamic_bias_stddev``, ``dynamic_bias_correlation_time_s``),
and ``precision``, the step the result is rounded to (0: none). A
:class:`NoiseModel` applies one spec to a sensor's values.

The dynamic bias is the RotorS / Kalibr IMU model: over a step dt,
``b = exp(-dt/tau) b + N(0, sqrt(-sigma^2 tau / 2 expm1(-2 dt / tau)))``, from
0; ``sigma`` is a random-walk density (unit per sqrt(s)): for dt << tau the
bias wanders as sigma sqrt(t), and it settles at a standard deviation of
sigma sqrt(tau / 2). RotorS keeps it beside the constant ("turn-on") bias, as
here; Gazebo's own model folds both into one variable, so there a drawn bias
decays over tau once the dynamic bias is on (with tau in hours, as Gazebo's
documentation suggests, the two agree over any test run).

Draws come from the ``numpy.random.Generator`` the caller passes, in a fixed
order per value set (the bias at construction: a normal, then a uniform for
its sign; per :meth:`NoiseModel.apply`: the white noise of every value, then
one dynamic-bias step per channel), and only for the parts that are on: the
same spec and seed give the same values on every run, and an exact spec
draws nothing.
"""

from dataclasses import dataclass, fields
import math
import numbers
import zlib
from typing import Optional, overload, Tuple, Union

import numpy

from r2d2_sim.errors import SetupError

__all__ = ['NoiseConfigError', 'NoiseSpec', 'NoiseModel', 'EXACT', 'quantize',
           'noise_generator', 'SENSOR_STREAMS']

# Each sensor's own stream of draws (noise_generator): never renumber, or seeds change meaning.
SENSOR_STREAMS = {'scan': 1, 'imu': 2, 'encoders': 3, 'depth': 4, 'lidar3d': 5}


class NoiseConfigError(SetupError, ValueError):
    """An impossible noise setting; the message names the field and its value."""


@dataclass(frozen=True)
class NoiseSpec:
    """
    Gazebo's Gaussian noise, in the unit of the values it is applied to.

    ``dynamic_bias_stddev`` is in that unit per sqrt(s) and needs
    ``dynamic_bias_correlation_time_s`` > 0. Raises NoiseConfigError (one
    line naming the field) for a negative spread, precision or time, or a
    non-finite number.
    """

    mean: float = 0.0
    stddev: float = 0.0
    bias_mean: float = 0.0
    bias_stddev: float = 0.0
    dynamic_bias_stddev: float = 0.0
    dynamic_bias_correlation_time_s: float = 0.0
    precision: float = 0.0

    def __post_init__(self) -> None:
        """Check every field; store them as floats."""
        for field in fields(self):
            value = getattr(self, field.name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real) \
                    or not math.isfinite(value):
                raise NoiseConfigError(f'{field.name} must be a finite number, got {value!r}')
            if field.name not in ('mean', 'bias_mean') and value < 0.0:
                raise NoiseConfigError(f'{field.name} must be >= 0, got {value!r}')
            object.__setattr__(self, field.name, float(value))
        if self.dynamic_bias_stddev > 0.0 and self.dynamic_bias_correlation_time_s == 0.0:
            raise NoiseConfigError('dynamic_bias_stddev needs dynamic_bias_correlation_time_s '
                                   f'> 0, got {self.dynamic_bias_stddev!r} with 0')

    @property
    def exact(self) -> bool:
        """Return True when the spec changes nothing (every field 0)."""
        return not any(getattr(self, f.name) for f in fields(self))

    @property
    def has_bias(self) -> bool:
        """Return True when a constant bias is drawn."""
        return self.bias_mean != 0.0 or self.bias_stddev != 0.0

    @property
    def has_dynamic_bias(self) -> bool:
        """Return True when the Gauss-Markov bias is on."""
        return self.dynamic_bias_stddev > 0.0

    @property
    def dynamic_bias_steady_stddev(self) -> float:
        """Return the standard deviation the dynamic bias settles at: sigma sqrt(tau / 2)."""
        if not self.has_dynamic_bias:
            return 0.0
        return self.dynamic_bias_stddev * math.sqrt(self.dynamic_bias_correlation_time_s / 2.0)

    @property
    def variance(self) -> float:
        """
        Return the mean square error the model makes, for a message's covariance.

        mean^2 + stddev^2 (the white noise), + bias_mean^2 + bias_stddev^2 (the
        constant bias; its sign is random, so its mean is 0 over seeds and its
        mean square this), + the dynamic bias's settled variance sigma^2 tau / 2,
        + precision^2 / 12 (rounding, when the noise spreads over several
        steps). Gazebo publishes stddev^2 alone; a filter told only that
        would trust a biased sensor too much.
        """
        return (self.mean ** 2 + self.stddev ** 2 + self.bias_mean ** 2 + self.bias_stddev ** 2
                + self.dynamic_bias_steady_stddev ** 2 + self.precision ** 2 / 12.0)


EXACT = NoiseSpec()


@overload
def quantize(values: float, precision: float) -> float: ...
@overload
def quantize(values: numpy.ndarray, precision: float) -> numpy.ndarray: ...


def quantize(values: Union[float, numpy.ndarray], precision: float
             ) -> Union[float, numpy.ndarray]:
    """Round to a multiple of ``precision`` as std::round does (halves away from 0); 0: as is."""
    if precision <= 0.0:
        return values
    values = numpy.asarray(values, dtype=float)
    steps = numpy.copysign(numpy.floor(numpy.abs(values) / precision + 0.5), values)
    return steps * precision


def noise_generator(seed: int, robot: str, sensor: str) -> numpy.random.Generator:
    """
    Return the generator of one sensor of one robot: seeded by all three, nothing else.

    Each sensor draws from a stream of its own, so turning one sensor on or
    changing its rate leaves the others' noise as it was; the robot's name
    (CRC-32 of its UTF-8 bytes: Python's ``hash`` differs between processes)
    keeps two robots with the same seed from reading the same noise, and no
    stream depends on the order robots are stepped in.
    """
    return numpy.random.default_rng(
        [int(seed), SENSOR_STREAMS[sensor], zlib.crc32(robot.encode('utf-8'))])


class NoiseModel:
    """
    One :class:`NoiseSpec` applied to a sensor's values, ``channels`` of them independent.

    Each channel (an IMU axis, a wheel side; a laser has one for all its
    beams) draws its own constant bias at construction and has its own
    dynamic bias. :meth:`apply` takes values whose last axis is the channels
    (or any shape with one channel), adds bias, dynamic bias and white noise
    (drawn for every value, whatever it is) and rounds to ``precision``.
    ``period_s`` is the time between applications when none is given (the
    sensor's period). ``rng`` is required unless the spec is exact.
    """

    def __init__(self, spec: NoiseSpec, rng: Optional[numpy.random.Generator],
                 channels: int = 1, period_s: float = 0.0) -> None:
        if not spec.exact and not isinstance(rng, numpy.random.Generator):
            raise NoiseConfigError(
                'noise needs rng, a numpy.random.Generator (e.g. numpy.random.default_rng(seed)), '
                f'got {rng!r}')
        # Checked as any object (a setting may come from a file): typeshed's int is no
        # numbers.Integral, so on ``channels`` itself the rest would be unreachable to mypy.
        count: object = channels
        if isinstance(count, bool) or not isinstance(count, numbers.Integral) or count < 1:
            raise NoiseConfigError(f'channels must be an integer >= 1, got {channels!r}')
        self.spec = spec
        self.channels = int(channels)
        self.period_s = float(period_s)
        self._rng = rng
        self.bias = numpy.zeros(self.channels)
        if spec.has_bias:
            assert rng is not None  # the spec is not exact: checked above
            self.bias = rng.normal(spec.bias_mean, spec.bias_stddev, self.channels)
            flip = rng.uniform(0.0, 1.0, self.channels) < 0.5
            self.bias[flip] = -self.bias[flip]
        self.dynamic_bias = numpy.zeros(self.channels)

    @property
    def exact(self) -> bool:
        """Return True when :meth:`apply` returns its input unchanged."""
        return self.spec.exact

    def step_dynamic_bias(self, dt_s: float) -> None:
        """Advance the Gauss-Markov bias by ``dt_s`` seconds (one draw per channel; 0: none)."""
        spec = self.spec
        if not spec.has_dynamic_bias or not dt_s > 0.0:
            return
        tau = spec.dynamic_bias_correlation_time_s
        sigma = spec.dynamic_bias_stddev
        step_stddev = math.sqrt(-sigma * sigma * tau / 2.0 * math.expm1(-2.0 * dt_s / tau))
        rng = self._rng
        assert rng is not None  # a dynamic bias is no exact spec: the constructor had one
        self.dynamic_bias = (math.exp(-dt_s / tau) * self.dynamic_bias
                             + rng.normal(0.0, step_stddev, self.channels))

    def error(self, shape: Union[int, Tuple[int, ...]],
              dt_s: Optional[float] = None) -> numpy.ndarray:
        """
        Return the error for values of ``shape``: bias + dynamic bias + white noise.

        Steps the dynamic bias by ``dt_s`` (default: the period) after drawing
        the white noise; no rounding (:meth:`apply` rounds the sum).
        """
        spec = self.spec
        if spec.stddev > 0.0:
            rng = self._rng
            assert rng is not None  # white noise is no exact spec: the constructor had one
            white = rng.normal(spec.mean, spec.stddev, shape)
        else:
            white = numpy.full(shape, spec.mean)
        self.step_dynamic_bias(self.period_s if dt_s is None else dt_s)
        bias = self.bias + self.dynamic_bias
        return white + (bias[0] if self.channels == 1 else bias)

    @overload
    def apply(self, values: numpy.ndarray, dt_s: Optional[float] = None) -> numpy.ndarray: ...

    @overload
    def apply(self, values: float, dt_s: Optional[float] = None
              ) -> Union[float, numpy.ndarray]: ...

    def apply(self, values: Union[float, numpy.ndarray], dt_s: Optional[float] = None
              ) -> Union[float, numpy.ndarray]:
        """
        Return ``values`` with the noise added and rounded (float64); exact: as given.

        The last axis of ``values`` must be the channels when there are
        several; ``dt_s`` is the time since the previous application.
        """
        if self.spec.exact:
            return values
        values = numpy.asarray(values, dtype=float)
        if self.channels > 1 and (values.ndim == 0 or values.shape[-1] != self.channels):
            raise ValueError(f'expected values with {self.channels} channels on the last axis, '
                             f'got shape {values.shape}')
        return quantize(values + self.error(values.shape, dt_s), self.spec.precision)
