"""
The task's numbers against cases worked out by hand: scan sectors, the goal ahead, rewards.

No PyBullet, no ROS: :mod:`r2d2_sim.gym.task` turns readings into
observations and rewards, the same for both backends.
"""

import math

import numpy
import pytest

from r2d2_sim.gym.task import (
    goal_distance, goal_observation, goal_reward, nav_observation, nav_reward,
    ObservationShape, Outcome, Reading, Rewards, scan_sectors)

SHAPE = ObservationShape(scan_beams=4, scan_range_m=4.0, goal_range_m=5.0, max_linear_m_s=0.5,
                         max_angular_rad_s=1.5)
NOTHING = Outcome(False, '', False)


def reading(x=0.0, y=0.0, yaw=0.0, scan=None, forward=0.0, turn=0.0):
    """Return a reading of a robot at (x, y, yaw) with a scan of 8 beams (all 2 m by default)."""
    ranges = numpy.full(8, 2.0, dtype=numpy.float32) if scan is None else numpy.asarray(
        scan, dtype=numpy.float32)
    return Reading(ranges, (x, y, 0.47), (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)),
                   (forward, 0.0, 0.0), (0.0, 0.0, turn))


def test_each_sector_is_its_nearest_return_over_the_range():
    """8 beams in 4 sectors: the smaller of each pair; +inf is the range, -inf 0."""
    scan = [1.0, 3.0, math.inf, math.inf, -math.inf, 2.0, 8.0, 0.4]
    sectors = scan_sectors(numpy.array(scan, dtype=numpy.float32), 4, 4.0)
    assert sectors.dtype == numpy.float32
    assert sectors.tolist() == numpy.array([0.25, 1.0, 0.0, 0.1], dtype=numpy.float32).tolist()


def test_the_goal_is_seen_ahead_and_left_in_the_robots_frame():
    """A goal 2 m along +y, the robot facing +y: 2 m ahead; facing +x: 2 m to the left."""
    facing_y = nav_observation(reading(yaw=math.pi / 2), (0.0, 2.0), SHAPE)
    assert facing_y[4:6] == pytest.approx([0.4, 0.0], abs=1e-6)
    facing_x = nav_observation(reading(), (0.0, 2.0), SHAPE)
    assert facing_x[4:6] == pytest.approx([0.0, 0.4], abs=1e-6)
    far = nav_observation(reading(), (-50.0, 0.0), SHAPE)
    assert far[4:6].tolist() == [-1.0, 0.0]  # clipped: 50 m behind is "behind, far"


def test_speeds_are_over_the_limits_and_clipped():
    """0.25 m/s of 0.5 is 0.5; 3 rad/s of 1.5 is clipped to 1."""
    observation = nav_observation(reading(forward=0.25, turn=-3.0), (1.0, 0.0), SHAPE)
    assert observation[6:].tolist() == [0.5, -1.0]
    assert observation.dtype == numpy.float32 and observation.shape == (SHAPE.nav_size,)


def test_the_goal_dictionaries_hold_position_goal_and_heading():
    """achieved_goal is where the robot stands, desired_goal the goal, heading as cos and sin."""
    observation = goal_observation(reading(1.0, -2.0, math.pi / 2), (3.0, 4.0), SHAPE)
    assert observation['achieved_goal'].tolist() == [1.0, -2.0]
    assert observation['desired_goal'].tolist() == [3.0, 4.0]
    assert observation['observation'][-2:] == pytest.approx([0.0, 1.0], abs=1e-6)


def test_the_reward_table():
    """Progress per metre, the step's cost, the goal's bonus, a contact's and a fall's penalty."""
    weights = Rewards()
    assert nav_reward(3.0, 2.5, NOTHING) == pytest.approx(0.5 - 0.01)
    assert nav_reward(2.5, 3.0, NOTHING) == pytest.approx(-0.5 - 0.01)
    assert nav_reward(0.4, 0.2, Outcome(True, '', False)) == pytest.approx(0.2 - 0.01 + 10.0)
    assert nav_reward(1.0, 1.0, Outcome(False, 'box_0', False)) == pytest.approx(-10.01)
    assert nav_reward(1.0, 1.0, Outcome(False, '', True)) == pytest.approx(-10.01)
    # The goal reached while touching a box is no success: the penalty, no bonus.
    touched_there = Outcome(True, 'box_0', False)
    assert not touched_there.success and touched_there.terminated
    assert nav_reward(0.4, 0.2, touched_there, weights) == pytest.approx(0.2 - 0.01 - 10.0)


def test_her_reward_is_batched_and_sparse():
    """0 within the tolerance, -1 beyond it, for one goal or a batch of them."""
    assert goal_reward(numpy.array([1.0, 1.0]), numpy.array([1.2, 1.0]), 0.3) == 0.0
    batch = goal_reward(numpy.array([[0.0, 0.0], [1.0, 0.0]]),
                        numpy.array([[0.0, 0.29], [1.0, 0.31]]), 0.3)
    assert batch.tolist() == [0.0, -1.0]


def test_goal_distance_is_on_the_ground():
    """Height plays no part: 3-4-5."""
    assert goal_distance(reading(0.0, 0.0), (3.0, 4.0)) == 5.0
