"""
One scenario run: its measures worked out by hand, its verdicts, its evidence kept only on failure.

ROS in this process (each run is a SimHarness). The controllers here command
the robot once (open loop): at 0.3 m/s with the default 1 m/s^2 ramp, the
base covers 0.045 m in the first 0.3 s and 0.3 m each second after.
"""

import json
import math
from pathlib import Path
import re

import pytest

from r2d2_sim.farm.run import (
    DeterminismError, Outcome, reached_safely, run_scenario, safe, TRAJECTORY_RATE_HZ)
from r2d2_sim.farm.scenario import Box, Pose, Scenario
from r2d2_sim.model.regions import circle_region
from r2d2_sim.sim.oracles import Contact
from r2d2_sim.testing import read_recording

REPO = Path(__file__).resolve().parents[2]
QUIET = {'scan_rate': 0.0, 'imu_rate': 0.0, 'publish_tf': False, 'publish_rate': 20.0}


def forward(harness, scenario):
    """Drive straight ahead at 0.3 m/s, once."""
    harness.send_cmd_vel(linear=0.3)


def test_the_goal_is_reached_when_the_ramp_says():
    """A goal circle of 0.1 m around x = 1.5: its edge at 1.4 m, reached at 4.8 s."""
    scenario = Scenario(start=Pose(0.0, 0.0, 0.0), goal=circle_region(1.5, 0.0, 0.1), seed=3)
    threads = []

    def forward_noting_threads(harness, scenario):
        threads.append(harness.sim.simulation.world.ray_threads)
        forward(harness, scenario)
    outcome = run_scenario(scenario, forward_noting_threads, seconds=10.0, parameters=QUIET)
    assert threads == [1]  # a farm runs a variation per core: its scans on one thread
    expected_s = 0.3 + (1.4 - 0.045) / 0.3  # 4.817 s
    assert outcome.passed and outcome.reason == ''
    assert outcome.time_to_goal_s == pytest.approx(expected_s, abs=0.05)
    # The run ends at the control period that saw the goal: 20 Hz publications.
    assert outcome.steps == math.ceil(outcome.time_to_goal_s * 20) * 12
    assert outcome.contacts == () and outcome.tipped_s is None
    assert outcome.clearance_m == 2.0 and outcome.closest is None  # nothing but the ground
    assert outcome.recording is None
    times = [point.time_ns for point in outcome.trajectory]
    assert times == [round(k * 1e9 / TRAJECTORY_RATE_HZ) for k in range(len(times))]
    assert outcome.trajectory[-1].x_m == pytest.approx(1.4, abs=0.05)


def test_the_docs_arrival_verdict_judges_the_speed_the_goal_was_entered_at():
    """docs/farm.md's arrived(): the goal entered at 0.3 m/s fails at 0.2 m/s, passes at 0.5."""
    page = (REPO / 'docs' / 'farm.md').read_text(encoding='utf-8')
    (snippet,) = [b for b in re.findall(r'^```python\n(.*?)^```$', page, re.S | re.M)
                  if 'def arrived(' in b]
    namespace = {}
    exec(snippet, namespace)
    arrived = namespace['arrived']
    scenario = Scenario(start=Pose(0.0, 0.0, 0.0), goal=circle_region(1.5, 0.0, 0.1), seed=3)
    outcome = run_scenario(scenario, forward, seconds=10.0, parameters=QUIET)
    assert outcome.passed  # reached_safely: entered, at full speed
    assert arrived(outcome) == 'entered the goal at 0.30 m/s'
    assert arrived(outcome, max_speed=0.5) == ''


def test_a_box_in_the_way_fails_with_the_box_named_and_a_recording_kept(tmp_path):
    """The robot drives into box_0: failed, touched box_0; rerun recorded, same outcome."""
    scenario = Scenario(obstacles=(Box(1.2, 0.0, 0.3, (0.3, 1.0, 0.5)),),
                        goal=circle_region(3.0, 0.0, 0.2), seed=11)
    recording = tmp_path / 'failed.mcap'
    outcome = run_scenario(scenario, forward, seconds=5.0, parameters=QUIET,
                           record_failure=str(recording))
    assert not outcome.passed and outcome.reason.startswith('touched box_0 at ')
    assert outcome.contacts[0].other == 'box_0'
    assert outcome.clearance_m <= 0.0 and outcome.closest == 'box_0'
    assert outcome.time_to_goal_s is None
    assert outcome.recording == str(recording)
    recorded = read_recording(str(recording), topics=['/clock', '/ground_truth'])
    assert recorded['/clock'][-1].log_time_ns == 5 * 10**9
    # The same run judged by another verdict: the goal is not asked.
    assert safe(outcome) == outcome.reason == reached_safely(outcome)


def test_every_time_of_an_outcome_counts_from_the_runs_start():
    """A controller that lets 1 s pass first: contacts, trajectory and reasons from the run's 0."""
    scenario = Scenario(obstacles=(Box(1.2, 0.0, 0.3, (0.3, 1.0, 0.5)),),
                        goal=circle_region(3.0, 0.0, 0.2), seed=11)

    def settle_then_forward(harness, scenario):
        harness.advance(seconds=1.0)
        forward(harness, scenario)
    outcome = run_scenario(scenario, settle_then_forward, seconds=5.0, parameters=QUIET)
    times = [point.time_ns for point in outcome.trajectory]
    assert times == [round(k * 1e9 / TRAJECTORY_RATE_HZ) for k in range(len(times))]
    assert times[-1] == 5 * 10**9  # the run's last sample, at its 5 s
    touched = outcome.contacts[0]
    assert 0 < touched.start_ns <= 5 * 10**9
    assert outcome.reason.startswith(f'touched box_0 at {touched.start_ns / 1e9:.3f} s ')
    # The clearance reached its smallest (overlapping) when the contact began, or after.
    assert outcome.clearance_m <= 0.0 and outcome.closest_s >= touched.start_ns / 1e9 - 0.01


def test_a_passing_run_records_nothing_and_a_failing_one_only_when_asked(tmp_path):
    """record_failure costs nothing for a pass; without it, a failure keeps no file."""
    scenario = Scenario(goal=circle_region(0.5, 0.0, 0.2))
    passed = run_scenario(scenario, forward, seconds=4.0, parameters=QUIET,
                          record_failure=str(tmp_path / 'never.mcap'))
    assert passed.passed and not (tmp_path / 'never.mcap').exists()
    far = Scenario(goal=circle_region(9.0, 0.0, 0.2))
    failed = run_scenario(far, forward, seconds=1.0, parameters=QUIET)
    assert failed.reason == 'goal not reached in 1 s' and failed.recording is None
    assert safe(failed) == ''
    assert run_scenario(far, forward, seconds=1.0, parameters=QUIET,
                        verdict=safe).passed


def judged(**measures):
    """Return an outcome of the default scenario with ``measures``, not yet judged."""
    values = dict(scenario=Scenario(), passed=True, reason='', seconds=10.0, time_to_goal_s=None,
                  clearance_m=1.0, closest=None, closest_s=None, contacts=(), tipped_s=None,
                  trajectory=(), steps=2400)
    values.update(measures)
    return Outcome(**values)


BUMP = Contact('box_0', 'left_tip', 'box_0', 1_500_000_000, None, (1.0, 0.0, 0.3), 12.0)


@pytest.mark.parametrize('measures, reason', [
    ({'time_to_goal_s': 4.0}, ''),
    ({}, 'goal not reached in 10 s'),
    ({'time_to_goal_s': 4.0, 'contacts': (BUMP,)}, 'touched box_0 at 1.500 s (left_tip, 12 N)'),
    ({'time_to_goal_s': 4.0, 'tipped_s': 2.25}, 'tipped over at 2.250 s'),
    ({'contacts': (BUMP,), 'tipped_s': 2.25}, 'touched box_0 at 1.500 s (left_tip, 12 N)')],
    ids=['goal', 'no-goal', 'goal-contact', 'goal-tipped', 'contact-tipped'])
def test_the_default_verdict_never_lets_the_goal_excuse_a_contact_or_a_fall(measures, reason):
    """reached_safely: the goal, and no contact, and never tipped; the first fault named."""
    assert reached_safely(judged(**measures)) == reason


def test_an_outcome_is_the_same_after_json():
    """to_json and from_dict give back an equal outcome, contacts and trajectory included."""
    scenario = Scenario(obstacles=(Box(1.0, 0.1, 0.0, (0.2, 0.2, 0.5)),),
                        goal=circle_region(3.0, 0.0, 0.2))
    outcome = run_scenario(scenario, forward, seconds=4.0, parameters=QUIET)
    assert outcome.contacts
    again = Outcome.from_dict(json.loads(outcome.to_json()))
    assert again == outcome
    assert 'seed 0, failed: touched box_0' in repr(outcome)


def test_a_run_that_does_not_repeat_is_a_determinism_error(tmp_path):
    """A controller that changes between runs: the recorded rerun differs, and says so."""
    speeds = [0.3, 0.25]

    def drifting(harness, scenario):
        harness.send_cmd_vel(linear=speeds.pop(0))
    scenario = Scenario(goal=circle_region(9.0, 0.0, 0.2), seed=5)
    with pytest.raises(DeterminismError, match='seed 5 run twice gave two outcomes; first '
                       'difference in trajectory'):
        run_scenario(scenario, drifting, seconds=1.0, parameters=QUIET,
                     record_failure=str(tmp_path / 'rerun.mcap'))


def test_a_verdict_that_returns_no_str_is_one_line():
    """A bool ('no contact: True') would read as a reason and fail the run: a TypeError."""
    with pytest.raises(TypeError) as raised:
        run_scenario(Scenario(), forward, seconds=0.1, parameters=QUIET,
                     verdict=lambda outcome: not outcome.contacts)
    message = str(raised.value)
    assert message == ("the verdict test_a_verdict_that_returns_no_str_is_one_line.<locals>."
                       "<lambda> returned bool True: a verdict returns a str, why the run "
                       "failed ('' when it passed)")


def test_bad_seconds_are_refused():
    """A run needs a positive, finite time."""
    with pytest.raises(ValueError, match='seconds'):
        run_scenario(Scenario(), forward, seconds=0.0)


TURNED_START_WORLD = """\
r2d2_sim_world: 1
name: turned
start_pose: start
models: []
named_poses:
  - name: start
    position: [1.0, -0.5, 0.0]
    yaw: 1.5707963267948966
  - name: goal
    position: [1.0, 0.7, 0.0]
"""


def test_named_start_and_goal_stand_where_the_world_says(tmp_path):
    """Start at (1, -0.5) facing +y in a world whose start pose it is; goal 1.2 m ahead."""
    world = tmp_path / 'turned.world.yaml'
    world.write_text(TURNED_START_WORLD)
    scenario = Scenario.named(str(world), start='start', goal='goal', goal_tolerance=0.1,
                              seed=5)
    assert (scenario.start_name, scenario.goal_name) == ('start', 'goal')
    outcome = run_scenario(scenario, forward, seconds=6.0, parameters=QUIET)
    first = outcome.trajectory[0]
    # initial_pose is relative to the world's start pose: the farm gives it so.
    assert (first.x_m, first.y_m) == pytest.approx((1.0, -0.5), abs=0.002)
    assert first.yaw_rad == pytest.approx(math.pi / 2, abs=0.002)
    expected_s = 0.3 + (1.1 - 0.045) / 0.3  # the circle's edge 1.1 m ahead: 3.82 s
    assert outcome.passed and outcome.time_to_goal_s == pytest.approx(expected_s, abs=0.05)
    assert json.loads(outcome.to_json())['scenario']['goal_name'] == 'goal'
