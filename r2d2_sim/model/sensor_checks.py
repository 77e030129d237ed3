"""
What every sensor model checks of its settings: finite numbers, a generator for noise.

No ROS and no PyBullet (numpy only). :class:`SensorConfigError` names the
field and its value; the scan, the 3D lidar, the depth image and the IMU
(:mod:`r2d2_sim.model.sensors`, :mod:`r2d2_sim.model.imu`) all raise it
through these checks, so a bad setting reads the same whichever sensor has it.
"""

import math
import numbers
from typing import Optional

import numpy

from r2d2_sim.errors import SetupError

__all__ = ['SensorConfigError', 'require_number', 'require_generator']


class SensorConfigError(SetupError, ValueError):
    """Invalid sensor setting; the message names the field and its value."""


def require_number(name: str, value: object, *, minimum: float = -math.inf,
                   strict: bool = False) -> float:
    """Return ``value`` as a float, or raise SensorConfigError naming ``name``."""
    # The float returned is the one compared: for floats the same, and no other Real
    # (an int past 2**53, a Fraction) can round onto the wrong side of the bound.
    number = math.nan
    if not isinstance(value, bool) and isinstance(value, numbers.Real):
        number = float(value)
    if not (math.isfinite(number) and (number > minimum if strict else number >= minimum)):
        bound = '' if minimum == -math.inf else f' {">" if strict else ">="} {minimum}'
        raise SensorConfigError(f'{name} must be a finite number{bound}, got {value!r}')
    return number


def require_generator(rng: Optional[numpy.random.Generator], *stds: float) -> None:
    """Refuse noise without a generator: unseeded noise would not be reproducible."""
    if any(std > 0.0 for std in stds) and not isinstance(rng, numpy.random.Generator):
        raise SensorConfigError(
            f'noise needs rng, a numpy.random.Generator (e.g. numpy.random.default_rng(seed)), '
            f'got {rng!r}')
