"""
Wheel encoders that err as real ones do, and the covariance of odometry built on them.

No ROS and no PyBullet here (numpy only). :class:`Encoders` turns the true
rotation of each side's wheels into what its encoder counts: every rotation
since the last reading is scaled by (1 + e), e from a
:class:`~r2d2_sim.model.noise.NoiseModel` (one channel per side), and the
count is the accumulated angle rounded to the encoder's ``precision`` (its
tick, 2 pi / ticks per revolution). The error is relative because wheel
odometry errs in proportion to the distance rolled: a constant bias is a
wheel radius off by that fraction (a robot whose left wheel reads 1 % long
and right 1 % short drifts into a curve), the white noise jitters each
reading's travel, the dynamic bias is a radius that changes slowly (load,
tyre wear). A robot standing still reads no travel, as with real encoders;
wheel slip stays the physics' (the wheels turn, the robot slides).

:class:`OdometryCovariance` propagates what these errors do to the odometry's
pose, linearised along the path odometry integrates (an error-state filter
whose state is the pose error and each side's constant and dynamic bias), so
that the published covariance grows as the drift can.
"""

import math
from typing import Optional, Sequence, Tuple

import numpy

from r2d2_sim.model.noise import NoiseModel, NoiseSpec, quantize

__all__ = ['Encoders', 'OdometryCovariance']


class Encoders:
    """
    The left and right encoders odometry reads, each counting its side's (signed) wheel angle.

    ``noise`` is relative (a fraction of each reading's rotation) except its
    ``precision``, the tick in rad. :meth:`read` returns what the encoders
    count for the true angles now; the first reading after construction or
    :meth:`restart` is the true angle rounded to a tick.
    """

    def __init__(self, noise: NoiseSpec, rng: Optional[numpy.random.Generator]) -> None:
        self.spec = noise
        # Rounding applies to the angle, not to the relative error.
        self._model = NoiseModel(
            NoiseSpec(noise.mean, noise.stddev, noise.bias_mean, noise.bias_stddev,
                      noise.dynamic_bias_stddev, noise.dynamic_bias_correlation_time_s),
            rng, channels=2)
        self._true: Optional[numpy.ndarray] = None
        self._counted: Optional[numpy.ndarray] = None

    @property
    def bias(self) -> numpy.ndarray:
        """Return each side's constant relative bias, left then right, drawn once."""
        return self._model.bias

    def restart(self) -> None:
        """Take the next reading as a new baseline (the robot was put back)."""
        self._true = self._counted = None

    @property
    def last_reading(self) -> Optional[Tuple[Tuple[float, float], Tuple[float, float]]]:
        """Return the last reading's true (left, right) angles and count before rounding."""
        if self._true is None or self._counted is None:
            return None
        (true_left, true_right), (left, right) = self._true.tolist(), self._counted.tolist()
        return (true_left, true_right), (left, right)

    def count_on(self, true_rad: Sequence[float], counted_rad: Sequence[float]) -> None:
        """
        Count on from another reading: its true angles and count (before rounding).

        For encoders that replace others mid-run (their noise started again):
        their first reading counts the rotation since that one, with their
        own error over the whole interval, so odometry goes on without a jump.
        """
        self._true = numpy.array(true_rad, dtype=float)
        self._counted = numpy.array(counted_rad, dtype=float)

    def read(self, left_rad: float, right_rad: float, dt_s: float) -> Tuple[float, float]:
        """
        Return the counted (left, right) angles for the true ones, ``dt_s`` after the last.

        A reading at no interval (the same instant read again: the node
        publishes the state once built, at t = 0) draws nothing, so the
        stream does not depend on how often an instant is read.
        """
        true = numpy.array([left_rad, right_rad], dtype=float)
        if self._true is None:
            self._counted = true
        else:
            travel = true - self._true
            if not self._model.exact and dt_s > 0.0:
                travel = travel * (1.0 + self._model.error(2, dt_s))
            self._counted = self._counted + travel
        self._true = true
        counted = quantize(self._counted, self.spec.precision)
        return float(counted[0]), float(counted[1])


# The state of the error filter: pose error (x, y, yaw), then each side's
# constant bias (left, right), dynamic bias (left, right) and the rounding
# error of its latest reading (left, right; in metres of travel).
_POSE, _CONSTANT, _DYNAMIC, _ROUNDING = slice(0, 3), slice(3, 5), slice(5, 7), slice(7, 9)
_BIASES = slice(3, 7)  # constant and dynamic: what the encoders carry across a restart
_ODOMETRY = numpy.r_[_POSE, _ROUNDING]  # what odometry carries across new encoders
_STATE = 9


class OdometryCovariance:
    """
    The covariance of wheel odometry whose encoders err as ``noise`` says (see :class:`Encoders`).

    Each :meth:`update` takes one odometry step as odometry integrated it:
    the heading before, each side's travel in metres and the time it took.
    The pose error moves as the odometry's midpoint integration linearised
    (x += ds cos(yaw + dyaw/2)...); each side's travel error is its travel
    times (constant bias + dynamic bias + white noise), plus this reading's
    rounding minus the last one's (each r^2 precision^2 / 12 in m^2): the
    counts are the accumulated angle rounded, so the roundings cancel along
    the way and a robot standing still keeps its covariance (summed as fresh
    noise every step, they grew without bound). The constant biases start with
    their second moment: each side's own bias_mean^2 + bias_stddev^2 (drawn
    per side, of random sign, so uncorrelated), plus mean^2 in every entry:
    the white noise's mean is one scale error of both wheels alike (it
    stretches the path, never curves it) and as systematic as a bias. The
    dynamic biases start at 0 and follow their Gauss-Markov process; the pose
    starts known (0). The twist's covariance is that of the last step's
    travel errors over its time. All of it is the second moment of the error
    about the true path, what a consumer of odometry needs (with a mean the
    error has one, so its spread about its own mean would be smaller).
    """

    def __init__(self, noise: NoiseSpec, wheel_radius_m: float, wheel_separation_m: float
                 ) -> None:
        self.spec = noise
        self.wheel_radius_m = wheel_radius_m
        self.wheel_separation_m = wheel_separation_m
        self._to_twist = numpy.array([[0.5, 0.5],
                                      [-1.0 / wheel_separation_m, 1.0 / wheel_separation_m]])
        self.covariance = self._prior()
        self.twist = numpy.zeros((2, 2))

    @property
    def _reading_rounding_m2(self) -> float:
        """Return the variance of one reading's rounding, in m^2 of travel: (r p)^2 / 12."""
        return (self.wheel_radius_m * self.spec.precision) ** 2 / 12.0

    def _prior(self) -> numpy.ndarray:
        """Return the covariance at start-up: a known pose, the priors of biases and rounding."""
        spec = self.spec
        covariance = numpy.zeros((_STATE, _STATE))
        # Per side, independent: the biases. Shared by both sides: the mean (a scale error;
        # counted per side as independent, it curved the path and inflated the yaw's).
        own = spec.bias_mean ** 2 + spec.bias_stddev ** 2
        covariance[_CONSTANT, _CONSTANT] = (own * numpy.eye(2)
                                            + spec.mean ** 2 * numpy.ones((2, 2)))
        # The baseline reading was rounded too: it shows in the first step's travel.
        covariance[_ROUNDING, _ROUNDING] = self._reading_rounding_m2 * numpy.eye(2)
        return covariance

    def reset(self) -> None:
        """
        Start again at a known pose with the same encoders: no pose error, the biases as they are.

        The encoders keep their constant and drifting biases over a restart
        (:meth:`Encoders.restart`, a state reset), so their covariance stays;
        only the pose's is 0 (and its correlation with them), and the new
        baseline reading's rounding has its prior. Set back to the priors, the
        drifting bias went missing: 2 s after a reset that followed 10 minutes
        of driving (dynamic_bias_stddev 0.001, correlation time 1 h), the yaw
        varied 700 times as much as the covariance said.
        """
        covariance = self._prior()
        covariance[_BIASES, _BIASES] = self.covariance[_BIASES, _BIASES]
        self.covariance = covariance
        self.twist = numpy.zeros((2, 2))

    def carry_on(self, before: 'OdometryCovariance') -> None:
        """
        Take over from ``before`` for odometry that goes on with fresh encoders (a noise restart).

        The pose error so far and the last reading's rounding are the
        odometry's and stay (cross terms and twist included); the new
        encoders' biases are fresh draws, at their priors and correlated with
        nothing.
        """
        covariance = self._prior()
        kept = numpy.ix_(_ODOMETRY, _ODOMETRY)
        covariance[kept] = before.covariance[kept]
        self.covariance = covariance
        self.twist = before.twist.copy()

    @property
    def pose(self) -> numpy.ndarray:
        """Return the 3 x 3 covariance of (x, y, yaw) in m^2, m rad, rad^2."""
        return self.covariance[_POSE, _POSE]

    def update(self, yaw_rad: float, left_m: float, right_m: float, dt_s: float) -> None:
        """Propagate one odometry step: heading before it, each side's travel, its time."""
        spec = self.spec
        ds = (left_m + right_m) / 2.0
        dyaw = (right_m - left_m) / self.wheel_separation_m
        mid = yaw_rad + dyaw / 2.0
        cos, sin = math.cos(mid), math.sin(mid)
        # d(pose)/d(travel error left, right), through d(pose)/d(ds, dyaw).
        to_pose = numpy.array([[cos, -ds / 2.0 * sin], [sin, ds / 2.0 * cos], [0.0, 1.0]])
        to_pose = to_pose @ self._to_twist
        along = to_pose @ numpy.diag([left_m, right_m])  # d(pose)/d(relative error)
        decay, dynamic_step = 1.0, 0.0
        if spec.has_dynamic_bias and dt_s > 0.0:
            tau = spec.dynamic_bias_correlation_time_s
            decay = math.exp(-dt_s / tau)
            dynamic_step = (-spec.dynamic_bias_stddev ** 2 * tau / 2.0
                            * math.expm1(-2.0 * dt_s / tau))
        # The reading's error is travel * (constant + dynamic after its step + white):
        # the dynamic bias steps first (decay, then a fresh draw), as Encoders draws it.
        a = numpy.eye(_STATE)
        a[0, 2] = -ds * sin
        a[1, 2] = ds * cos
        a[_POSE, _CONSTANT] = along
        a[_POSE, _DYNAMIC] = decay * along
        a[_DYNAMIC, _DYNAMIC] = decay * numpy.eye(2)
        # Each count is the accumulated angle rounded to a tick: a step's travel holds
        # this reading's rounding minus the last one's, which then leaves the state.
        a[_POSE, _ROUNDING] = -to_pose
        a[_ROUNDING, _ROUNDING] = 0.0
        # Fresh draws: white (left, right), dynamic step (left, right), rounding (left, right).
        g = numpy.zeros((_STATE, 6))
        g[_POSE, 0:2] = along
        g[_POSE, 2:4] = along
        g[_DYNAMIC, 2:4] = numpy.eye(2)
        g[_POSE, 4:6] = to_pose
        g[_ROUNDING, 4:6] = numpy.eye(2)
        reading = self._reading_rounding_m2
        fresh = numpy.diag([spec.stddev ** 2] * 2 + [dynamic_step] * 2 + [reading] * 2)
        rounding = 2.0 * reading * numpy.eye(2)  # a step's: the difference of two roundings
        before = self.covariance
        covariance = a @ before @ a.T + g @ fresh @ g.T
        self.covariance = (covariance + covariance.T) / 2.0  # symmetric to the last bit
        if dt_s > 0.0:
            # This step's relative error per side: biases as known before it, its draws.
            c, d = before[_CONSTANT, _CONSTANT], before[_DYNAMIC, _DYNAMIC]
            cd = before[_CONSTANT, _DYNAMIC]
            relative = (c + decay * (cd + cd.T) + decay * decay * d
                        + (spec.stddev ** 2 + dynamic_step) * numpy.eye(2))
            travel = numpy.diag([left_m, right_m])
            step = travel @ relative @ travel + rounding
            twist = self._to_twist @ step @ self._to_twist.T / (dt_s * dt_s)
            self.twist = (twist + twist.T) / 2.0
