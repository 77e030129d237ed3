"""
The go-to-goal task as numbers: what the policy sees, what it is paid, when an episode ends.

No PyBullet, no ROS: both backends measure the same things (a laser scan,
the true pose and twist of the robot) and hand them here, so the same
readings give the same observation and reward, bit for bit.

What one control period gives (:class:`Reading`) becomes

- the observation of ``R2D2Nav-v0`` (:func:`nav_observation`), float32:
  the scan down-sampled to ``scan_beams`` sectors (the nearest return in
  each, over the range: 0 touching, 1 nothing within it), the goal in the
  robot's frame over ``goal_range`` (x ahead, y left, clipped to [-1, 1]),
  and the robot's forward and turning speed over its limits;
- the dictionaries of ``R2D2NavGoal-v0`` (:func:`goal_observation`): the
  scan, speeds and heading as ``observation``, where the robot stands as
  ``achieved_goal`` and the goal as ``desired_goal`` (metres, world frame);
- the reward (:func:`nav_reward`, weights in :class:`Rewards`) and the
  outcome of the period (:class:`Outcome`: the goal, a contact, a fall,
  as the run's watch saw them at any physics step of it).
"""

import math
from typing import NamedTuple, Optional, Sequence, Tuple

import numpy

__all__ = ['Command', 'Reading', 'Outcome', 'Rewards', 'ObservationShape', 'nav_observation',
           'goal_observation', 'nav_reward', 'goal_reward', 'scan_sectors', 'WORLD_EXTENT_M',
           'GOAL_MARGIN_M']

# One robot's command: forward speed (m/s) and turning speed (rad/s).
Command = Tuple[float, float]
# R2D2NavGoal-v0 gives positions in the world within this many metres of the origin (in x
# and in y): a robot farther out ends its episode, truncated, where the observation clips it.
WORLD_EXTENT_M = 20.0
# Its starts and goal circles keep this far inside that: a position clipped to the edge is
# never within a goal's tolerance, so a clipped observation scores what the robot did.
GOAL_MARGIN_M = 1.0


class Reading(NamedTuple):
    """What one robot measured at the end of a control period: its scan and its true state."""

    scan: numpy.ndarray                         # REP-117 ranges (float32), the laser's beams
    position: Tuple[float, float, float]        # body frame in the world (m)
    orientation: Tuple[float, float, float, float]  # x, y, z, w
    linear: Tuple[float, float, float]          # body frame (m/s)
    angular: Tuple[float, float, float]         # body frame (rad/s)

    @property
    def yaw(self) -> float:
        """Return the heading (rad, 0 along the world's x)."""
        x, y, z, w = self.orientation
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


class Outcome(NamedTuple):
    """How a control period ended for one robot, as the run's watch saw every physics step."""

    reached: bool            # the base stood in the goal region
    contact: Optional[str]   # the first body touched ('' none), the ground aside
    tipped: bool             # leaned past the tip angle

    @property
    def failed(self) -> bool:
        """Return True for a contact or a fall: the episode ends badly."""
        return bool(self.contact) or self.tipped

    @property
    def success(self) -> bool:
        """Return True when the goal was reached without touching anything or falling."""
        return self.reached and not self.failed

    @property
    def terminated(self) -> bool:
        """Return True when the episode ends here (goal, contact or fall)."""
        return self.reached or self.failed


class Rewards(NamedTuple):
    """The reward's weights (the docs' reward table): per period, per event."""

    progress: float = 1.0     # per metre nearer the goal's centre (negative when farther)
    step: float = -0.01       # every period
    goal: float = 10.0        # the goal reached without contact
    collision: float = -10.0  # anything touched but the ground (ends the episode)
    tipped: float = -10.0     # fell over (ends the episode)


class ObservationShape(NamedTuple):
    """Sizes and scales of the observation: how the readings become numbers in [-1, 1]."""

    scan_beams: int           # sectors of the scan seen by the policy
    scan_range_m: float       # a scan's farthest range: 1 in the observation
    goal_range_m: float       # a goal this far ahead: 1
    max_linear_m_s: float     # forward speed: 1
    max_angular_rad_s: float  # turning speed: 1

    @property
    def nav_size(self) -> int:
        """Return the length of R2D2Nav-v0's observation: scan, goal (2), speeds (2)."""
        return self.scan_beams + 4

    @property
    def goal_observation_size(self) -> int:
        """Return the length of R2D2NavGoal-v0's ``observation``: scan, speeds, cos and sin."""
        return self.scan_beams + 4


def scan_sectors(ranges: numpy.ndarray, beams: int, range_max_m: float) -> numpy.ndarray:
    """
    Return the scan as ``beams`` sectors in [0, 1]: the nearest return of each over the range.

    REP-117's -inf (nearer than the laser's minimum) counts as 0, +inf (no
    return) as the range; the beams split evenly into sectors, in the scan's
    order (counter-clockwise from behind the robot, for a full circle).
    """
    values = numpy.nan_to_num(numpy.asarray(ranges, dtype=numpy.float32),
                              nan=range_max_m, posinf=range_max_m, neginf=0.0)
    nearest = values.reshape(beams, -1).min(axis=1)
    return numpy.clip(nearest / numpy.float32(range_max_m), 0.0, 1.0).astype(numpy.float32)


def _goal_in_body(reading: Reading, goal: Sequence[float]) -> Tuple[float, float]:
    """Return the goal's x (ahead) and y (left) in the robot's frame (m)."""
    dx, dy = goal[0] - reading.position[0], goal[1] - reading.position[1]
    yaw = reading.yaw
    c, s = math.cos(yaw), math.sin(yaw)
    return c * dx + s * dy, -s * dx + c * dy


def _speeds(reading: Reading, shape: ObservationShape) -> Tuple[float, float]:
    return (reading.linear[0] / shape.max_linear_m_s,
            reading.angular[2] / shape.max_angular_rad_s)


def nav_observation(reading: Reading, goal: Sequence[float],
                    shape: ObservationShape) -> numpy.ndarray:
    """Return R2D2Nav-v0's observation: scan sectors, the goal ahead and left, the speeds."""
    ahead, left = _goal_in_body(reading, goal)
    rest = numpy.clip(numpy.array(
        (ahead / shape.goal_range_m, left / shape.goal_range_m, *_speeds(reading, shape)),
        dtype=numpy.float32), -1.0, 1.0)
    return numpy.concatenate((scan_sectors(reading.scan, shape.scan_beams, shape.scan_range_m),
                              rest))


def goal_observation(reading: Reading, goal: Sequence[float], shape: ObservationShape) -> dict:
    """Return R2D2NavGoal-v0's dictionary: observation, achieved_goal, desired_goal."""
    yaw = reading.yaw
    rest = numpy.clip(numpy.array((*_speeds(reading, shape), math.cos(yaw), math.sin(yaw)),
                                  dtype=numpy.float32), -1.0, 1.0)
    extent = WORLD_EXTENT_M
    return {
        'observation': numpy.concatenate(
            (scan_sectors(reading.scan, shape.scan_beams, shape.scan_range_m), rest)),
        'achieved_goal': numpy.clip(numpy.array(reading.position[:2], dtype=numpy.float32),
                                    -extent, extent),
        'desired_goal': numpy.clip(numpy.array(goal[:2], dtype=numpy.float32), -extent, extent),
    }


def goal_distance(reading: Reading, goal: Sequence[float]) -> float:
    """Return the distance (m) from the robot's body frame to the goal's centre, on the ground."""
    return math.hypot(goal[0] - reading.position[0], goal[1] - reading.position[1])


def nav_reward(before_m: float, after_m: float, outcome: Outcome,
               weights: Rewards = Rewards()) -> float:
    """Return one period's reward: progress, the step's cost, and the period's events."""
    reward = weights.progress * (before_m - after_m) + weights.step
    if outcome.contact:
        reward += weights.collision
    if outcome.tipped:
        reward += weights.tipped
    if outcome.success:
        reward += weights.goal
    return float(reward)


def goal_reward(achieved: numpy.ndarray, desired: numpy.ndarray,
                tolerance_m: float) -> numpy.ndarray:
    """Return HER's sparse reward, batched over the last axis: 0 within the goal, else -1."""
    distance = numpy.linalg.norm(numpy.asarray(achieved, dtype=numpy.float64)
                                 - numpy.asarray(desired, dtype=numpy.float64), axis=-1)
    return -(distance > tolerance_m).astype(numpy.float32)
