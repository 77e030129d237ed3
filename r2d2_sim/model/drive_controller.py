"""
The drive controller: a body-twist command in, wheel joint velocity targets out, odometry back.

No ROS and no PyBullet: the same job as ros2_controllers' diff_drive_controller
(``update_reference_from_subscribers`` and ``update_and_write_commands``) as a
plain object, tested with hand-computable numbers. Per command: refuse
non-finite values, scale to the speed limits keeping the curvature (and refuse
what would still turn a wheel faster than a float holds), then, per
physics step, brake after the timeout, ramp within the acceleration limits and
fan the left/right wheel speeds out to every wheel joint with the URDF's sign.
Wheel encoder angles come back in, are counted by the encoders (exact, or
erring as :mod:`r2d2_sim.model.encoders` says) and integrated into odometry,
with its covariance when the encoders err.
"""

from fractions import Fraction
import math
from typing import List, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.model.encoders import Encoders, OdometryCovariance
from r2d2_sim.model.kinematics import (
    DiffDriveGeometry, DiffDriveOdometry, limit_twist, OdometryState, ramp_twist,
    twist_to_wheel_velocities, Twist2D, TwistLimits)
from r2d2_sim.model.timing import exact_rate

STOP = Twist2D(0.0, 0.0)

# The Twist fields a differential drive cannot follow.
IGNORED_AXES = ('linear.y', 'linear.z', 'angular.x', 'angular.y')


class CommandVerdict(NamedTuple):
    """What became of one command: the twist taken (None if refused) and why."""

    accepted: Optional[Twist2D]
    problem: Optional[str] = None       # why it was refused: 'NaN', 'infinite value', OVERFLOW
    ignored_axes: Tuple[str, ...] = ()  # non-zero fields a differential drive ignores
    clamped: bool = False               # scaled down to the speed limits


# Why a finite command is refused when, even within the limits, its wheel speeds are not:
# without a wheel speed limit (DiffDriveGeometry's default) 1e308 m/s would be inf rad/s.
OVERFLOW = 'wheel speeds too large for a float'

# The verdict on any command for a robot that has no wheels to drive.
NO_WHEELS = CommandVerdict(None, 'no wheels')


def timeout_steps(timeout_s: float, physics_rate_hz: float) -> int:
    """Return the whole physics steps of a command timeout; 0 (none) for 0 or beyond any run."""
    steps = timeout_s * physics_rate_hz
    # A timeout beyond any run (1e308 s) is as good as none, and would overflow ceil.
    if not steps < 2.0**62:
        return 0
    # Exactly, as the numbers were written: the floats' product of 0.07 s and 100 Hz is
    # 7.000000000000001, which rounded up to 8 steps.
    return math.ceil(Fraction(repr(timeout_s)) * exact_rate(physics_rate_hz))


class DriveController:
    """
    Commands to wheel targets, and wheel angles to odometry, for a differential drive.

    Wheel lists are always left wheels first, then right, in joint space:
    ``wheel_velocity_sign`` -1 is for a URDF whose wheels roll forward with a
    negative velocity. :meth:`command` may be called from another thread than
    :meth:`update` (the ROS subscription and the physics loop): it only
    replaces one attribute, which the next update reads once and compares by
    identity with the last one it took. ``encoders`` count the wheel angles
    odometry integrates (None: exactly); with them, ``covariance`` follows
    what their errors do to the odometry (None: none is computed).
    """

    def __init__(self, geometry: DiffDriveGeometry, limits: TwistLimits, time_step_s: float,
                 timeout_steps: int, left_count: int, right_count: int,
                 wheel_velocity_sign: int = 1,
                 initial_pose: Tuple[float, float, float] = (0.0, 0.0, 0.0),
                 encoders: Optional[Encoders] = None,
                 covariance: Optional[OdometryCovariance] = None) -> None:
        if left_count < 1 or right_count < 1:
            raise ValueError(f'need wheels on both sides, got {left_count} left and '
                             f'{right_count} right')
        if wheel_velocity_sign not in (1, -1):
            raise ValueError(f'wheel_velocity_sign must be 1 or -1, got {wheel_velocity_sign}')
        self.geometry = geometry
        self.limits = limits
        self.time_step_s = time_step_s
        self.timeout_steps = timeout_steps
        self.left_count = left_count
        self.right_count = right_count
        self.wheel_velocity_sign = wheel_velocity_sign
        self.initial_pose = initial_pose
        self.odometry = DiffDriveOdometry(geometry, *initial_pose)
        self.encoders = encoders
        self.covariance = covariance
        self.target = STOP          # the command being followed (after limits)
        self.ramped = STOP          # where the acceleration ramp has got to
        self.wheel_targets = (0.0, 0.0)  # left, right wheel speeds in rad/s (REP-103 sign)
        # The latest command (written by command(), maybe from another thread)
        # and the one update() took last: compared by identity, never cleared by
        # the reader, so a command written between a read and a clear is not lost.
        self._latest: Optional[Twist2D] = None
        self._taken: Optional[Twist2D] = None
        self._command_step = 0
        self._odometry_step = 0

    # -- commands ---------------------------------------------------------------

    def command(self, linear_x: float, angular_z: float, linear_y: float = 0.0,
                linear_z: float = 0.0, angular_x: float = 0.0,
                angular_y: float = 0.0) -> CommandVerdict:
        """Take a Twist's six fields; the limited planar twist applies from the next update."""
        values = (linear_x, linear_y, linear_z, angular_x, angular_y, angular_z)
        if any(math.isnan(v) for v in values):
            return CommandVerdict(None, 'NaN')
        if any(math.isinf(v) for v in values):
            return CommandVerdict(None, 'infinite value')
        ignored = tuple(name for name, value in zip(
            IGNORED_AXES, (linear_y, linear_z, angular_x, angular_y)) if value != 0.0)
        limited = limit_twist(self.geometry, linear_x, angular_z, self.limits)
        try:
            twist_to_wheel_velocities(self.geometry, *limited)
        except ValueError:  # finite, so its wheel speeds overflow
            return CommandVerdict(None, OVERFLOW)
        clamped = (max(map(abs, limited))
                   < max(abs(linear_x), abs(angular_z)) * (1.0 - 1e-9))
        self._latest = limited  # one assignment, which update() reads once
        return CommandVerdict(limited, ignored_axes=ignored, clamped=clamped)

    def update(self, step: int) -> Optional[List[float]]:
        """
        Advance the command state to physics step ``step``, before that step runs.

        Takes a new command (or brakes after the timeout) and ramps towards it
        by one step. Returns the wheel joint velocity targets (left wheels, then
        right, in joint space) when they changed, else None.
        """
        latest = self._latest
        # None only before the first command, and then nothing was taken either.
        if latest is not None and latest is not self._taken:
            self._taken = latest
            self._command_step = step
            self.target = latest
        elif (self.timeout_steps and self.target != STOP
              and step - self._command_step >= self.timeout_steps):
            self.target = STOP
        if self.ramped == self.target:
            return None
        self.ramped = ramp_twist(self.ramped, self.target, self.limits, self.time_step_s)
        return self._wheel_velocities(*twist_to_wheel_velocities(self.geometry, *self.ramped))

    def joint_targets(self) -> List[float]:
        """Return the wheel joint velocity targets now (left wheels, then right, joint space)."""
        return self._wheel_velocities(*self.wheel_targets)

    def _wheel_velocities(self, left_rad_s: float, right_rad_s: float) -> List[float]:
        self.wheel_targets = (left_rad_s, right_rad_s)
        sign = self.wheel_velocity_sign
        return ([sign * left_rad_s] * self.left_count
                + [sign * right_rad_s] * self.right_count)

    # -- odometry ---------------------------------------------------------------

    def _sides(self, wheel_positions_rad: Sequence[float]) -> Tuple[float, float]:
        """Return the (left, right) wheel angles odometry counts: each side's mean, signed."""
        n_left, sign = self.left_count, self.wheel_velocity_sign
        return (sign * sum(wheel_positions_rad[:n_left]) / n_left,
                sign * sum(wheel_positions_rad[n_left:]) / self.right_count)

    def take_encoders(self, encoders: Optional[Encoders],
                      covariance: Optional[OdometryCovariance]) -> None:
        """
        Count with ``encoders`` from now on (their noise started again), ``covariance`` following.

        Odometry goes on as it was: the new encoders count on from the old
        count (or from the baseline, when the old ones were exact), so the next
        odometry step errs over its whole interval with their noise, as the
        first after start-up does; exact ones move the baseline by the old
        error, so the pose keeps the error it has and gains none. The new
        covariance keeps the pose's so far (:meth:`OdometryCovariance.carry_on`).
        Fresh encoders that counted from the true angle jumped the odometry by
        the old encoders' whole error (about 9 cm after 2 m at a 5 % bias).
        """
        before = self.encoders
        self.encoders = encoders
        if covariance is not None and self.covariance is not None:
            covariance.carry_on(self.covariance)
        self.covariance = covariance
        baseline = self.odometry.baseline
        if baseline is None:  # nothing counted yet: the next reading is the baseline
            return
        if before is None:  # exact so far: the baseline is the true angles
            if encoders is not None:
                encoders.count_on(baseline, baseline)
            return
        last = before.last_reading
        if last is None:
            return
        true, counted = last
        if encoders is not None:
            encoders.count_on(true, counted)
        else:
            self.odometry.move_baseline(true[0] - counted[0], true[1] - counted[1])

    def update_odometry(self, wheel_positions_rad: Sequence[float], step: int) -> None:
        """Integrate the wheel joint angles (left wheels, then right) read after ``step``."""
        left, right = self._sides(wheel_positions_rad)
        dt_s = (step - self._odometry_step) * self.time_step_s
        if self.encoders is not None:
            left, right = self.encoders.read(left, right, dt_s)
        odometry = self.odometry
        before, yaw_rad = odometry.baseline, odometry.yaw_rad
        # Integrated (True) only from a baseline, so then ``before`` is one.
        integrated = odometry.update_from_positions(left, right, dt_s)
        if integrated and before is not None and self.covariance is not None:
            radius_m = self.geometry.wheel_radius_m
            self.covariance.update(yaw_rad, radius_m * (left - before[0]),
                                   radius_m * (right - before[1]), dt_s)
        self._odometry_step = step

    def odometry_state(self) -> OdometryState:
        """Return the odometry now, with its covariances when the encoders err."""
        state = self.odometry.state()
        covariance = self.covariance
        if covariance is None:
            return state
        return state._replace(pose_covariance=tuple(covariance.pose.ravel().tolist()),
                              twist_covariance=tuple(covariance.twist.ravel().tolist()))

    def shift_time(self, steps: int) -> None:
        """Move the step anchors by ``steps`` when the step count is set back (a time reset)."""
        self._command_step += steps
        self._odometry_step += steps

    def reset(self, step: int, wheel_positions_rad: Sequence[float]) -> List[float]:
        """Drop the command, go back to the initial pose; return the wheel targets (all 0)."""
        self._taken = self._latest  # a command from before the reset is dropped
        self.target = self.ramped = STOP
        self.odometry.reset(*self.initial_pose)
        if self.encoders is not None:
            self.encoders.restart()
        if self.covariance is not None:
            self.covariance.reset()
        self._odometry_step = step
        self.update_odometry(wheel_positions_rad, step)  # the encoder baseline
        return self._wheel_velocities(0.0, 0.0)
