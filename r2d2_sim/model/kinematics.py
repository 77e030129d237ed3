"""
Differential-drive kinematics and wheel odometry for the simulated R2D2.

This module is deliberately free of ROS and PyBullet: it only knows the
geometry of a two-wheeled differential drive, so it can be unit-tested on its
own and reused by whichever node talks to the simulator.  It is modelled on
``odometry.cpp`` of ros2_controllers' ``diff_drive_controller``:

* inverse kinematics (``twist_to_wheel_velocities``) turns a commanded body
  twist into left/right wheel angular velocities, scaling both wheels by the
  same factor when one would exceed the limit so the path curvature is kept;
* forward kinematics (``wheel_velocities_to_twist``) does the reverse;
* ``DiffDriveOdometry`` integrates wheel encoder angles (or wheel velocities)
  into a planar pose in the odom frame using the exact arc of a constant
  curvature motion, falling back to second-order Runge-Kutta when the yaw
  increment is too small for the arc formula to be numerically safe.

Conventions follow REP-103: x forward, y left, yaw counter-clockwise positive,
and a positive wheel velocity means the wheel rolls forward.  Every quantity
carries its unit in its name (``_m``, ``_rad``, ``_m_s``, ``_rad_s``, ``_s``).
"""

from dataclasses import dataclass
import math
from typing import NamedTuple, Optional, Tuple

from r2d2_sim.errors import SetupError
# One home for rotations: re-exported here, where they used to live.
from r2d2_sim.model.transforms import quaternion_to_yaw, yaw_to_quaternion  # noqa: F401

__all__ = [
    'Twist2D',
    'DriveConfigError',
    'DiffDriveGeometry',
    'TwistLimits',
    'limit_twist',
    'ramp_twist',
    'twist_to_wheel_velocities',
    'wheel_velocities_to_twist',
    'yaw_to_quaternion',
    'quaternion_to_yaw',
    'OdometryState',
    'DiffDriveOdometry',
]

# Below this yaw increment the exact arc (radius = ds / dth) is ill-conditioned,
# so the pose is advanced with a second-order Runge-Kutta step instead.
_RK2_YAW_THRESHOLD_RAD = 1e-6


class Twist2D(NamedTuple):
    """A planar body twist: forward speed and yaw rate (REP-103 x forward, z up)."""

    linear_m_s: float
    angular_rad_s: float


class DriveConfigError(SetupError, ValueError):
    """Invalid drive geometry or limit; the message names the field and value."""


def _wrap_angle_rad(angle_rad: float) -> float:
    """Wrap an angle to the half-open range (-pi, pi]."""
    wrapped_rad = math.remainder(angle_rad, 2.0 * math.pi)
    if wrapped_rad <= -math.pi:
        wrapped_rad += 2.0 * math.pi
    return wrapped_rad


def _require_finite(**values: float) -> None:
    """Raise ValueError naming the first argument that is not a finite number."""
    for name, value in values.items():
        if not math.isfinite(value):
            raise ValueError(f'{name} must be finite, got {value!r}')


@dataclass(frozen=True)
class DiffDriveGeometry:
    """Wheel radius, effective wheel separation and wheel speed limit of the base."""

    wheel_radius_m: float
    wheel_separation_m: float  # effective separation: nominal * multiplier (caller multiplies)
    max_wheel_velocity_rad_s: float = math.inf

    def __post_init__(self) -> None:
        """Validate the fields and store them as floats."""
        for name, allow_inf in (('wheel_radius_m', False),
                                ('wheel_separation_m', False),
                                ('max_wheel_velocity_rad_s', True)):
            raw = getattr(self, name)
            requirement = 'a number > 0' if allow_inf else 'a finite number > 0'
            if isinstance(raw, bool):
                raise DriveConfigError(f'{name} must be {requirement}, got {raw!r}')
            try:
                value = float(raw)
            except (TypeError, ValueError):
                raise DriveConfigError(
                    f'{name} must be {requirement}, got {raw!r}') from None
            valid = value > 0.0 and (allow_inf or math.isfinite(value))
            if not valid:  # NaN fails 'value > 0.0' as well
                raise DriveConfigError(f'{name} must be {requirement}, got {raw!r}')
            object.__setattr__(self, name, value)


def twist_to_wheel_velocities(geometry: DiffDriveGeometry, linear_x_m_s: float,
                              angular_z_rad_s: float) -> tuple[float, float]:
    """
    Convert a body twist into (left, right) wheel angular velocities in rad/s.

    left = (v - w * s / 2) / r and right = (v + w * s / 2) / r.  If either wheel
    would exceed ``geometry.max_wheel_velocity_rad_s`` in magnitude, both are
    scaled by the same factor, which preserves the curvature w / v (the robot
    follows the same path, only slower).  Non-finite inputs raise ValueError, as
    does a twist whose wheel speeds overflow to infinity (:func:`limit_twist` first
    keeps any finite twist within a finite limit).
    """
    if not (math.isfinite(linear_x_m_s) and math.isfinite(angular_z_rad_s)):  # every step
        _require_finite(linear_x_m_s=linear_x_m_s, angular_z_rad_s=angular_z_rad_s)
    half_track_m_s = angular_z_rad_s * geometry.wheel_separation_m / 2.0
    left_rad_s = (linear_x_m_s - half_track_m_s) / geometry.wheel_radius_m
    right_rad_s = (linear_x_m_s + half_track_m_s) / geometry.wheel_radius_m
    fastest_rad_s = max(abs(left_rad_s), abs(right_rad_s))
    if fastest_rad_s == math.inf:  # scaled by limit / inf = 0 it would be NaN, unscaled inf
        raise ValueError(f'the wheel speeds of ({linear_x_m_s!r} m/s, {angular_z_rad_s!r} '
                         'rad/s) overflow')
    limit_rad_s = geometry.max_wheel_velocity_rad_s
    if fastest_rad_s > limit_rad_s:
        scale = limit_rad_s / fastest_rad_s
        left_rad_s *= scale
        right_rad_s *= scale
        # Make the capped wheel hit the limit exactly despite rounding.
        if abs(left_rad_s) >= abs(right_rad_s):
            left_rad_s = math.copysign(limit_rad_s, left_rad_s)
        else:
            right_rad_s = math.copysign(limit_rad_s, right_rad_s)
    return left_rad_s, right_rad_s


@dataclass(frozen=True)
class TwistLimits:
    """
    Body speed and acceleration limits, as diff_drive_controller's speed limiter.

    Each must be > 0; ``math.inf`` (the default) means no limit.
    """

    max_linear_m_s: float = math.inf
    max_angular_rad_s: float = math.inf
    max_linear_acceleration_m_s2: float = math.inf
    max_angular_acceleration_rad_s2: float = math.inf

    def __post_init__(self) -> None:
        """Refuse limits that are not > 0 (NaN included)."""
        for name in ('max_linear_m_s', 'max_angular_rad_s', 'max_linear_acceleration_m_s2',
                     'max_angular_acceleration_rad_s2'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise DriveConfigError(f'{name} must be a number > 0 (inf: none), got {value!r}')


NO_LIMITS = TwistLimits()


def limit_twist(geometry: DiffDriveGeometry, linear_x_m_s: float, angular_z_rad_s: float,
                limits: TwistLimits = NO_LIMITS) -> Twist2D:
    """
    Scale a twist down to the wheel and body speed limits, keeping its curvature.

    The faster wheel turns at (|v| + |w| * s / 2) / r; |v| and |w| are also held
    to ``limits``. The twist is first normalised by its largest component, so
    even 1e308 cannot overflow into inf * 0 = NaN.  Non-finite inputs raise
    ValueError.
    """
    _require_finite(linear_x_m_s=linear_x_m_s, angular_z_rad_s=angular_z_rad_s)
    magnitude = max(abs(linear_x_m_s), abs(angular_z_rad_s))
    if magnitude == 0.0:
        return Twist2D(linear_x_m_s, angular_z_rad_s)
    unit_v = linear_x_m_s / magnitude
    unit_w = angular_z_rad_s / magnitude
    unit_wheel_m_s = abs(unit_v) + abs(unit_w) * geometry.wheel_separation_m / 2.0
    allowed = geometry.max_wheel_velocity_rad_s * geometry.wheel_radius_m / unit_wheel_m_s
    if unit_v:
        allowed = min(allowed, limits.max_linear_m_s / abs(unit_v))
    if unit_w:
        allowed = min(allowed, limits.max_angular_rad_s / abs(unit_w))
    scale = min(magnitude, allowed)
    return Twist2D(unit_v * scale, unit_w * scale)


def ramp_twist(current: Twist2D, target: Twist2D, limits: TwistLimits,
               dt_s: float) -> Twist2D:
    """
    Move ``current`` (v, w) towards ``target`` within the acceleration limits over ``dt_s``.

    Both axes move by the same fraction of the way, so a ramp from or to rest
    keeps the commanded curvature: the robot starts an arc on the arc. (Limiting
    each axis on its own, as diff_drive_controller does, starts an arc with
    a turn on the spot, where a skid-steered robot slips most.) The target is
    reached exactly, and at once with infinite limits.
    """
    delta_v = target.linear_m_s - current.linear_m_s
    delta_w = target.angular_rad_s - current.angular_rad_s
    fraction = 1.0
    max_dv = limits.max_linear_acceleration_m_s2 * dt_s
    max_dw = limits.max_angular_acceleration_rad_s2 * dt_s
    if abs(delta_v) > max_dv:
        fraction = max_dv / abs(delta_v)
    if abs(delta_w) > max_dw:
        fraction = min(fraction, max_dw / abs(delta_w))
    if fraction == 1.0:
        return target
    return Twist2D(current.linear_m_s + fraction * delta_v,
                   current.angular_rad_s + fraction * delta_w)


def wheel_velocities_to_twist(geometry: DiffDriveGeometry, left_rad_s: float,
                              right_rad_s: float) -> Twist2D:
    """
    Convert (left, right) wheel angular velocities into a body twist (v, w).

    The inverse of :func:`twist_to_wheel_velocities` without the limit, as
    diff_drive_controller's odometry ``update_from_vel``; the simulator itself
    integrates wheel angles instead (:class:`DiffDriveOdometry`).

    v = r * (left + right) / 2 in m/s and w = r * (right - left) / s in rad/s.
    No limit is applied.  Non-finite inputs raise ValueError.
    """
    _require_finite(left_rad_s=left_rad_s, right_rad_s=right_rad_s)
    radius_m = geometry.wheel_radius_m
    linear_x_m_s = radius_m * (left_rad_s + right_rad_s) / 2.0
    angular_z_rad_s = radius_m * (right_rad_s - left_rad_s) / geometry.wheel_separation_m
    return Twist2D(linear_x_m_s, angular_z_rad_s)


class OdometryState(NamedTuple):
    """
    A snapshot of wheel odometry: the pose in the odom frame and the twist in the body.

    The covariances are those the encoders' noise gives (None when they are
    exact): of (x, y, yaw) as 9 numbers row by row, and of (linear, angular)
    as 4.
    """

    x_m: float
    y_m: float
    yaw_rad: float
    linear_m_s: float
    angular_rad_s: float
    pose_covariance: Optional[Tuple[float, ...]] = None
    twist_covariance: Optional[Tuple[float, ...]] = None


class DiffDriveOdometry:
    """Wheel odometry in the odom frame from wheel encoder angles."""

    def __init__(self, geometry: DiffDriveGeometry, x_m: float = 0.0, y_m: float = 0.0,
                 yaw_rad: float = 0.0) -> None:
        """Start at the given pose with zero twist and no encoder baseline."""
        self._geometry = geometry
        self.reset(x_m, y_m, yaw_rad)

    def reset(self, x_m: float = 0.0, y_m: float = 0.0, yaw_rad: float = 0.0) -> None:
        """
        Set the pose, zero the twist and forget the encoder baseline.

        The travelled distance restarts at zero as well.  Non-finite values
        raise ValueError.
        """
        _require_finite(x_m=x_m, y_m=y_m, yaw_rad=yaw_rad)
        self._x_m = float(x_m)
        self._y_m = float(y_m)
        self._yaw_rad = _wrap_angle_rad(float(yaw_rad))
        self._linear_m_s = 0.0
        self._angular_rad_s = 0.0
        self._distance_m = 0.0
        self._left_baseline_rad: float | None = None
        self._right_baseline_rad: float | None = None

    def update_from_positions(self, left_pos_rad: float, right_pos_rad: float,
                              dt_s: float) -> bool:
        """
        Integrate the wheel travel since the previous encoder reading.

        The first call after construction or reset only records the baseline
        (``dt_s`` is not needed for that) and returns False.  Later calls turn
        the angle increments into wheel travel (radius * delta angle),
        integrate the pose and set the twist to increment / ``dt_s``.  A call
        with non-finite input or ``dt_s <= 0`` changes nothing, so the travel
        is picked up by the next valid call, and returns False.  Return True
        when the pose was integrated.
        """
        if not (math.isfinite(left_pos_rad) and math.isfinite(right_pos_rad)):
            return False
        if self._left_baseline_rad is None or self._right_baseline_rad is None:
            self._left_baseline_rad = float(left_pos_rad)
            self._right_baseline_rad = float(right_pos_rad)
            return False
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            return False
        radius_m = self._geometry.wheel_radius_m
        left_travel_m = radius_m * (left_pos_rad - self._left_baseline_rad)
        right_travel_m = radius_m * (right_pos_rad - self._right_baseline_rad)
        self._left_baseline_rad = float(left_pos_rad)
        self._right_baseline_rad = float(right_pos_rad)
        linear_m, angular_rad = self._integrate(left_travel_m, right_travel_m)
        self._linear_m_s = linear_m / dt_s
        self._angular_rad_s = angular_rad / dt_s
        return True

    def update_from_velocities(self, left_rad_s: float, right_rad_s: float,
                               dt_s: float) -> bool:
        """
        Integrate constant wheel angular velocities over ``dt_s`` seconds.

        The twist becomes the forward kinematics of the wheel velocities.  A
        call with non-finite input or ``dt_s <= 0`` changes nothing and returns
        False; otherwise return True.  The encoder baseline is not touched.
        """
        if not all(math.isfinite(value) for value in (left_rad_s, right_rad_s, dt_s)):
            return False
        if dt_s <= 0.0:
            return False
        radius_m = self._geometry.wheel_radius_m
        linear_m, angular_rad = self._integrate(radius_m * left_rad_s * dt_s,
                                                radius_m * right_rad_s * dt_s)
        self._linear_m_s = linear_m / dt_s
        self._angular_rad_s = angular_rad / dt_s
        return True

    def _integrate(self, left_travel_m: float, right_travel_m: float) -> tuple[float, float]:
        """Advance the pose by one wheel-travel increment; return (ds, dth)."""
        linear_m = (left_travel_m + right_travel_m) / 2.0
        angular_rad = (right_travel_m - left_travel_m) / self._geometry.wheel_separation_m
        yaw_rad = self._yaw_rad
        if abs(angular_rad) < _RK2_YAW_THRESHOLD_RAD:
            # Runge-Kutta 2: move along the heading at the middle of the step.
            mid_yaw_rad = yaw_rad + angular_rad / 2.0
            self._x_m += linear_m * math.cos(mid_yaw_rad)
            self._y_m += linear_m * math.sin(mid_yaw_rad)
        else:
            # Exact integration of a constant-curvature arc.
            arc_radius_m = linear_m / angular_rad
            new_yaw_rad = yaw_rad + angular_rad
            self._x_m += arc_radius_m * (math.sin(new_yaw_rad) - math.sin(yaw_rad))
            self._y_m += -arc_radius_m * (math.cos(new_yaw_rad) - math.cos(yaw_rad))
        self._yaw_rad = _wrap_angle_rad(yaw_rad + angular_rad)
        self._distance_m += abs(linear_m)
        return linear_m, angular_rad

    def move_baseline(self, left_rad: float, right_rad: float) -> None:
        """Move the encoder baseline by these angles (the angles counted changed their origin)."""
        if self._left_baseline_rad is not None and self._right_baseline_rad is not None:
            self._left_baseline_rad += left_rad
            self._right_baseline_rad += right_rad

    @property
    def baseline(self) -> Optional[Tuple[float, float]]:
        """Return the (left, right) encoder angles the next update measures from, if any."""
        if self._left_baseline_rad is None or self._right_baseline_rad is None:
            return None
        return (self._left_baseline_rad, self._right_baseline_rad)

    @property
    def x_m(self) -> float:
        """Return the x position in the odom frame, metres."""
        return self._x_m

    @property
    def y_m(self) -> float:
        """Return the y position in the odom frame, metres."""
        return self._y_m

    @property
    def yaw_rad(self) -> float:
        """Return the heading in the odom frame, radians in (-pi, pi]."""
        return self._yaw_rad

    def state(self) -> OdometryState:
        """Return the pose and twist now, as a snapshot that later updates leave alone."""
        return OdometryState(self._x_m, self._y_m, self._yaw_rad, self._linear_m_s,
                             self._angular_rad_s)

    @property
    def linear_m_s(self) -> float:
        """Return the forward velocity of the last update, m/s."""
        return self._linear_m_s

    @property
    def angular_rad_s(self) -> float:
        """Return the yaw rate of the last update, rad/s."""
        return self._angular_rad_s

    @property
    def distance_m(self) -> float:
        """Return the total path length travelled since construction or reset, metres."""
        return self._distance_m
