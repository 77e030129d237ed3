"""
A scenario author's mistakes, each said in one clear line, never a traceback.

Through the scenario_execution command (its own output) for an unknown action and a
missing argument; through a run's verdict for a world or named pose that does not
exist; and, over ROS, for a service namespace where no simulator answers.
"""

import os

import pytest

from common import osc_env, scenario_execution
from r2d2_sim.osc.variations import run_document, Task

HEADER = 'import osc.helpers\nimport osc.r2d2\n\nscenario oops:\n'


def write(tmp_path, text):
    """Write a scenario file; return its path."""
    path = tmp_path / 'oops.osc'
    path.write_text(HEADER + text, encoding='utf-8')
    return path


def lines_with(output, text):
    """Return the output's lines that say ``text``."""
    return [line for line in output.splitlines() if text in line]


@pytest.mark.parametrize('body, says', [
    ('    do serial:\n        drive_fast(linear: 1mps)\n',
     'BehaviorInvocation uses unknown behavior "drive_fast"'),
    ('    do serial:\n        wait_until_in_region(x: 1m, y: 0m)\n',
     "wait_until_in_region: argument 'radius' has no value: give it (it has no default)"),
])
def test_the_command_says_it_in_one_line(tmp_path, body, says):
    """An unknown action, a missing argument: a line saying so, the run failed, no traceback."""
    status, output, _ = scenario_execution(
        ['--simulation', 'r2d2_sim.osc:R2D2Simulation', write(tmp_path, body)],
        osc_env(tmp_path / 'shim'), tmp_path)
    assert status == 1
    assert lines_with(output, says), output[-3000:]
    assert 'Traceback' not in output


@pytest.mark.parametrize('parameters, says', [
    ("    world: string = 'package://r2d2_sim/urdf/nothere.world.yaml'\n",
     'world package://r2d2_sim/urdf/nothere.world.yaml: '),
    ("    world: string = 'package://r2d2_sim/urdf/room.world.yaml'\n"
     "    goal_pose: string = 'kitchen'\n",
     "no named pose 'kitchen' in package://r2d2_sim/urdf/room.world.yaml; it has: corner_ne, "),
])
def test_a_world_or_named_pose_that_does_not_exist(tmp_path, parameters, says):
    """Found at reset: the verdict's reason is that one line (logged once, not per action)."""
    path = write(tmp_path, parameters + '    do serial:\n        drive_to()\n')
    verdict = run_document(Task(str(path), 0, None))
    assert not verdict.passed and verdict.reason.startswith(says), verdict.reason
    assert '\n' not in verdict.reason


@pytest.mark.parametrize('action, says', [
    ('drive(linear: 0.5mps, duration: -1s)', 'drive: duration must be >= 0, got -1 s'),
    ('drive_to(speed: -1mps)', 'drive_to: speed must be > 0, got -1 m/s'),
    ('drive_to(stop_distance: -1m)', 'drive_to: stop_distance must be >= 0, got -1 m'),
    ("spawn_entity(entity_name: 'x', uri: 'cube.urdf', initial_pose: 5)",
     'spawn_entity: initial_pose must be a pose_3d (position, orientation), got 5'),
    ('assert_not_tipped(angle: 200deg)',
     'assert_not_tipped: angle must be in (0, 180) deg, got 200 deg'),
    ('assert_not_tipped(angle: 0deg)', 'assert_not_tipped: angle must be in (0, 180) deg, '
                                       'got 0 deg'),
])
def test_an_argument_that_cannot_be_used_fails_its_action_in_one_line(tmp_path, action, says):
    """
    Refuse an argument the action cannot use in one line, when the action starts.

    A negative duration, speed or stop distance, a pose that is no pose, a tip angle out
    of (0, 180) deg: the same line in process and over ROS (the action says it).
    """
    path = write(tmp_path, '    timeout(5s)\n    do serial:\n        ' + action + '\n'
                 '        wait elapsed(0.5s)\n')
    verdict = run_document(Task(str(path), 0, None))
    assert not verdict.passed and verdict.reason == says, verdict.reason


def test_a_mistake_found_at_reset_fails_a_run_in_which_no_action_of_ours_runs(tmp_path):
    """A world that does not exist, then only `wait elapsed`: failed with its one line."""
    path = write(tmp_path, "    world: string = 'package://r2d2_sim/urdf/nothere.world.yaml'\n"
                 '    do serial:\n        wait elapsed(0.2s)\n')
    verdict = run_document(Task(str(path), 0, None))
    assert not verdict.passed
    assert verdict.reason == ('world package://r2d2_sim/urdf/nothere.world.yaml: '
                              'no such world file'), verdict.reason


def test_a_parameter_that_cannot_be_fails_its_document_alone(tmp_path):
    """A negative goal_tolerance in document 0: its one line, no traceback; 1 and 2 still run."""
    path = write(tmp_path, '    goal_tolerance: float = 0.2\n'
                 '    do serial:\n        wait_until_in_region(x: 0m, y: 0m, radius: 0.5m)\n')
    documents = tmp_path / 'tolerances.yaml'
    documents.write_text('---\n'.join(f'oops:\n  goal_tolerance: {tolerance}\n'
                                      for tolerance in (-0.5, 0.3, 0.4)))
    status, output, cases = scenario_execution(
        ['--simulation', 'r2d2_sim.osc:R2D2Simulation', '--scenario-parameter-file', documents,
         path], osc_env(tmp_path / 'shim'), tmp_path)
    assert cases == {'oops-0': 'execution failed.', 'oops-1': None, 'oops-2': None}, \
        output[-3000:]
    says = 'r2d2_sim: parameter goal_tolerance: a radius >= 0 (m) expected, got -0.5'
    assert status == 1 and lines_with(output, says), output[-3000:]
    assert 'Traceback' not in output


def test_a_named_pose_of_a_check_that_does_not_exist(tmp_path):
    """wait_until_at_pose for a name the world lacks: NOT_FOUND, listing the names it has."""
    path = write(tmp_path, "    world: string = 'package://r2d2_sim/urdf/room.world.yaml'\n"
                 "    do serial:\n        wait_until_at_pose(pose: 'kitchen')\n")
    verdict = run_document(Task(str(path), 0, None))
    assert verdict.reason.startswith("wait_until_at_pose: NOT_FOUND: no named pose 'kitchen' in "
                                     'the world'), verdict.reason
    assert 'it has: start, goal, dock' in verdict.reason


def test_a_namespace_where_no_simulator_answers(tmp_path):
    """Over ROS, on a domain with no simulator: one line naming the namespace, after the wait."""
    from helpers import next_domain_id
    path = write(tmp_path, "    simulator_namespace: string = '/nobody'\n"
                 "    do serial:\n        drive(linear: 0.2mps)\n")
    env = osc_env(tmp_path / 'shim', ROS_DOMAIN_ID=next_domain_id(), R2D2_OSC_DISCOVERY_S=1)
    status, output, cases = scenario_execution(
        ['--simulation', 'r2d2_sim.osc:StandardSimulation', path], env, tmp_path)
    says = ("r2d2_sim: no simulator answers under simulator_namespace '/nobody' within 1 s "
            '(missing StepSimulation, ')
    assert status == 1 and len(lines_with(output, says)) == 1, output[-3000:]
    assert lines_with(output, 'simulators answer under: none')
    assert 'Traceback' not in output and cases == {'oops': 'execution failed.'}
    assert os.environ.get('R2D2_OSC_DISCOVERY_S') is None  # the child's alone


@pytest.mark.parametrize('distance, shown', [('-1m', '-1'), ('0m', '0')])
def test_a_clearance_of_none_or_less_is_refused(tmp_path, distance, shown):
    """assert_min_clearance(distance: 0m or less) could never fail: one line, not a pass."""
    path = write(tmp_path, '    do one_of:\n        wait elapsed(0.5s)\n'
                 f'        assert_min_clearance(distance: {distance})\n')
    verdict = run_document(Task(str(path), 0, None))
    assert not verdict.passed
    assert verdict.reason == f'assert_min_clearance: distance must be > 0, got {shown} m'


def physics_rate(rate):
    """Return the scenario parameter that runs the physics at ``rate`` Hz in process."""
    return f"    parameters: string = '{{\\\"physics_rate\\\": {rate}}}'\n"


@pytest.mark.parametrize('rate, steps', [(250, '12.5'), (30, '1.5')])
def test_a_physics_rate_that_does_not_fit_the_control_period(tmp_path, rate, steps):
    """250 Hz: 12.5 steps a tick, the simulated time would drift from the scenario's: refused."""
    path = write(tmp_path, physics_rate(rate) + '    do serial:\n'
                 '        drive(linear: 0.5mps, duration: 2s)\n')
    verdict = run_document(Task(str(path), 0, None))
    assert not verdict.passed
    assert verdict.reason == (
        f'physics_rate {rate} Hz: a control period of 0.05 s would be {steps} physics steps, '
        'not a whole number; use a rate that is a multiple of 20 Hz (100, 200, 240, 500, '
        '1000...)')


@pytest.mark.parametrize('rate', [100, 240, 1000])
def test_at_a_rate_that_fits_the_simulated_time_is_the_scenarios(tmp_path, rate):
    """Driven 2 s, then 2 s of waiting: 4.1 s of scenario time (82 ticks), at any such rate."""
    path = write(tmp_path, physics_rate(rate) + '    do serial:\n'
                 '        drive(linear: 0.5mps, duration: 2s)\n        wait elapsed(2s)\n')
    verdict = run_document(Task(str(path), 0, None))
    assert verdict.passed, verdict.reason
    assert verdict.outcome['seconds'] == pytest.approx(4.1, abs=1e-6)
    assert verdict.outcome['steps'] == round(4.1 * rate)


@pytest.mark.parametrize('variable', ['R2D2_OSC_DISCOVERY_S', 'R2D2_OSC_CALL_S'])
def test_a_wait_that_is_no_number_of_seconds(tmp_path, variable):
    """Over ROS, a wait given as 'soon' or -1: one line naming the variable, nothing run."""
    from helpers import next_domain_id
    path = write(tmp_path, "    do serial:\n        drive(linear: 0.2mps)\n")
    for value, why in (('soon', 'must be a number'), ('-1', 'must be > 0')):
        env = osc_env(tmp_path / 'shim', ROS_DOMAIN_ID=next_domain_id(), **{variable: value})
        status, output, cases = scenario_execution(
            ['--simulation', 'r2d2_sim.osc:StandardSimulation', path], env, tmp_path)
        says = f"r2d2_sim: {variable} (seconds) {why}, got '{value}'"
        assert status == 1 and len(lines_with(output, says)) == 1, output[-3000:]
        assert 'Traceback' not in output
