"""
osc.r2d2, the library: osc.sim's eight actions (same names, same arguments) and the farm's.

Each scenario here runs in this process (``run_document``: scenario_execution with
R2D2Simulation, the core in lockstep, no ROS), a few simulated seconds at most.
"""

import inspect
from pathlib import Path
import re

import pytest

from r2d2_sim.osc.entry_points import ENTRY_POINTS
from r2d2_sim.osc.variations import run_document, Task

LIBRARY = Path(__file__).resolve().parents[2] / 'r2d2_sim' / 'osc' / 'lib_osc' / 'r2d2.osc'
# osc.sim's actions (scenario_execution_sim's lib_osc/sim.osc): name -> [(argument, type,
# default)], written from its file.
OSC_SIM = {
    'delete_entity': [('entity', 'string', None)],
    'load_world': [('uri', 'string', None)],
    'reset_simulation': [],
    'set_entity_state': [('entity', 'string', None), ('pose', 'pose_3d', 'pose_3d()'),
                         ('twist', 'velocity_6d', 'velocity_6d()'),
                         ('acceleration', 'acceleration_6d', 'acceleration_6d()')],
    'set_simulation_state': [('state', 'simulation_state', None)],
    'spawn_entity': [('entity_name', 'string', None), ('uri', 'string', None),
                     ('initial_pose', 'pose_3d', None), ('allow_renaming', 'bool', 'false'),
                     ('entity_namespace', 'string', "''")],
    'step_simulation': [('steps', 'int', '1')],
    'unload_world': [],
}
ACTION = re.compile(r'^action (\w+):?\n((?:    .*\n)*)', re.M)
ARGUMENT = re.compile(r'^    (\w+): (\w+)(?: = ([^#]*?))?\s*(?:#.*)?$')


def declared():
    """Return the library's actions: name -> [(argument, type, default or None)]."""
    actions = {}
    for name, body in ACTION.findall(LIBRARY.read_text(encoding='utf-8')):
        actions[name] = [m.groups() for m in map(ARGUMENT.match, body.splitlines()) if m]
    return actions


def test_the_library_has_osc_sims_actions_with_their_arguments():
    """The eight actions of osc.sim, each with osc.sim's arguments, types and defaults."""
    actions = declared()
    for name, arguments in OSC_SIM.items():
        assert actions.get(name) == arguments, name
    assert re.search(r'enum simulation_state: \[\s*stopped,\s*playing,\s*paused\s*\]',
                     LIBRARY.read_text(encoding='utf-8'))


def test_every_action_declared_has_its_plugin_and_arguments():
    """Declared actions and entry points are the same set; each execute() takes its arguments."""
    from importlib import import_module
    actions = declared()
    plugins = dict(line.split(' = ') for line in ENTRY_POINTS['scenario_execution.actions'])
    assert set(plugins) == set(actions)
    for name, target in plugins.items():
        module, cls = target.split(':')
        execute = getattr(import_module(module), cls).__dict__.get('execute')
        taken = [] if execute is None else list(inspect.signature(execute).parameters)[1:]
        assert taken == [argument for argument, _, _ in actions[name]], name


def run(tmp_path, body, parameters=''):
    """Run a scenario whose steps are ``body`` (indented for 'do serial:'); return its verdict."""
    scenario = tmp_path / 'probe.osc'
    scenario.write_text('import osc.helpers\nimport osc.r2d2\n\nscenario probe:\n'
                        '    timeout(10s)\n' + parameters + '    do serial:\n' + body)
    return run_document(Task(str(scenario), 0, None))


SPAWN_CUBE = ("        spawn_entity(entity_name: 'cube', uri: 'cube_small.urdf', initial_pose:"
              " pose_3d(position: position_3d(x: 2m, z: 0.1m)))\n")


def test_spawn_place_wait_delete(tmp_path):
    """A cube spawned, placed at (3, 1), found there, deleted; a second delete is NOT_FOUND."""
    verdict = run(tmp_path, SPAWN_CUBE + (
        "        set_entity_state(entity: 'cube', pose: pose_3d(position: position_3d("
        "x: 3m, y: 1m, z: 0.025m)))\n"
        "        wait_until_in_region(entity: 'cube', x: 3m, y: 1m, radius: 0.05m)\n"
        "        delete_entity(entity: 'cube')\n"
        "        delete_entity(entity: 'cube')\n"))
    assert not verdict.passed
    assert verdict.reason.startswith("delete_entity: NOT_FOUND: no entity named 'cube'")


def test_a_reset_removes_what_was_spawned(tmp_path):
    """reset_simulation is ALL: the cube spawned before is gone after it."""
    verdict = run(tmp_path, SPAWN_CUBE + "        reset_simulation()\n"
                  "        delete_entity(entity: 'cube')\n")
    assert verdict.reason.startswith('delete_entity: NOT_FOUND'), verdict


def test_steps_of_a_paused_simulation_are_counted(tmp_path):
    """Paused in the first tick (12 steps), then 100 single steps: 112 physics steps."""
    verdict = run(tmp_path, "        set_simulation_state(state: simulation_state!paused)\n"
                  "        step_simulation(steps: 100)\n")
    assert verdict.passed, verdict.reason
    assert verdict.outcome['steps'] == 112


def test_stepping_a_playing_simulation_is_refused(tmp_path):
    """step_simulation while playing: OPERATION_FAILED, as the standard's StepSimulation says."""
    verdict = run(tmp_path, "        step_simulation(steps: 10)\n")
    assert verdict.reason.startswith('step_simulation: OPERATION_FAILED: step_simulation '
                                     'steps a paused simulation'), verdict


def test_after_unloading_the_world_nothing_plays(tmp_path):
    """unload_world, then playing: INCORRECT_STATE until a world is loaded; load_world plays."""
    verdict = run(tmp_path, "        unload_world()\n"
                  "        set_simulation_state(state: simulation_state!playing)\n")
    assert verdict.reason == ('set_simulation_state: INCORRECT_STATE: no world is loaded: '
                              'load_world first'), verdict
    verdict = run(tmp_path, "        unload_world()\n"
                  "        load_world(uri: 'package://r2d2_sim/urdf/empty.world.yaml')\n"
                  "        set_simulation_state(state: simulation_state!playing)\n"
                  "        wait elapsed(0.5s)\n")
    assert verdict.passed, verdict.reason


def test_drive_holds_its_velocity_for_its_duration(tmp_path):
    """0.5 m/s for 2 s with the default 1 m/s^2 ramp: about 1 m, then it stands."""
    verdict = run(tmp_path, "        drive(linear: 0.5mps, duration: 2s)\n"
                  "        wait elapsed(1s)\n"
                  "        wait_until_in_region(x: 1m, y: 0m, radius: 0.1m)\n")
    assert verdict.passed, verdict.reason
    end = verdict.outcome['trajectory'][-1]
    assert end[1] == pytest.approx(1.0, abs=0.1)


def test_a_touch_fails_assert_no_contact(tmp_path):
    """Driven into a box 1 m ahead: the check fails the moment R2D2 touches it."""
    verdict = run(tmp_path, "        one_of:\n"
                  "            drive(linear: 0.5mps, duration: 5s)\n"
                  "            assert_no_contact()\n",
                  "    obstacles: string = '[[1.2, 0, 0, 0.3, 0.3, 0.5]]'\n")
    assert re.fullmatch(r'r2d2 touched box_0 at \d+\.\d{3} s', verdict.reason), verdict


def test_clearance_is_checked_against_the_distance_asked(tmp_path):
    """The same drive with 0.3 m asked fails before any touch, naming the box."""
    verdict = run(tmp_path, "        one_of:\n"
                  "            drive(linear: 0.5mps, duration: 5s)\n"
                  "            assert_min_clearance(distance: 0.3m)\n",
                  "    obstacles: string = '[[1.2, 0, 0, 0.3, 0.3, 0.5]]'\n")
    assert re.fullmatch(r'r2d2 came within 0\.3 m of box_0 \(0\.\d{3} m, at \d+\.\d{3} s\)',
                        verdict.reason), verdict
    assert verdict.outcome['contacts'] == []


def test_a_robot_laid_on_its_side_fails_assert_not_tipped(tmp_path):
    """Placed rolled 90 degrees: tipped over at once."""
    verdict = run(tmp_path, "        set_entity_state(entity: 'r2d2', pose: pose_3d(position: "
                  "position_3d(z: 0.4m), orientation: orientation_3d(roll: 90deg)))\n"
                  "        one_of:\n"
                  "            wait elapsed(1s)\n"
                  "            assert_not_tipped()\n")
    assert re.fullmatch(r'r2d2 tipped over \(leaned past 45 deg\) at \d+\.\d{3} s',
                        verdict.reason), verdict


def test_a_subclass_policy_drives_the_robot(tmp_path, monkeypatch):
    """docs/scenarios.md's policy, as written: 0.4 m/s each period, the robot gets there."""
    page = (LIBRARY.parents[3] / 'docs' / 'scenarios.md').read_text(encoding='utf-8')
    (block,) = re.findall(r'^```python\n(.*?)^```$', page, re.S | re.M)
    (tmp_path / 'my_policies.py').write_text(block)
    monkeypatch.syspath_prepend(str(tmp_path))
    scenario = tmp_path / 'probe.osc'
    scenario.write_text('import osc.helpers\nimport osc.r2d2\n\nscenario probe:\n'
                        '    timeout(10s)\n'
                        '    do serial:\n'
                        '        wait_until_in_region(x: 2m, y: 0m, radius: 0.1m)\n')
    verdict = run_document(Task(str(scenario), 0, None, 'my_policies:Forward'))
    assert verdict.passed, verdict.reason
    assert verdict.outcome['time_to_goal_s'] is not None  # the default goal at 1 m on the way


# R2D2 drives into a box 0.8 m ahead (touching it at about 1.46 s), backs off, then a check
# starts: the touch before it does not count.
TOUCHED_BEFORE = ("        drive(linear: 0.4mps, duration: 2s)\n"
                  "        drive(linear: -0.4mps, duration: 3s)\n"
                  "        wait elapsed(0.5s)\n"
                  "        one_of:\n"
                  "            wait elapsed(1s)\n")
BOX_AHEAD = "    obstacles: string = '[[0.8, 0, 0, 0.3, 0.3, 0.5]]'\n"


@pytest.mark.parametrize('check', ['assert_no_contact()', 'assert_min_clearance(distance: 0.3m)'])
def test_a_check_counts_only_what_happens_after_it_starts(tmp_path, check):
    """Touched (and near) before the check began, clear since: it passes, as over ROS."""
    verdict = run(tmp_path, TOUCHED_BEFORE + f'            {check}\n', BOX_AHEAD)
    assert verdict.passed, verdict.reason
    assert [c['other'] for c in verdict.outcome['contacts']] == ['box_0']  # the run's watch


def test_a_contact_still_going_when_a_check_starts_fails_it(tmp_path):
    """Pushing against the box when the check starts at 2.5 s: it fails then, not at 1.46 s."""
    verdict = run(tmp_path, "        one_of:\n"
                  "            drive(linear: 0.4mps, duration: 5s)\n"
                  "            serial:\n"
                  "                wait elapsed(2.5s)\n"
                  "                assert_no_contact()\n", BOX_AHEAD)
    match = re.fullmatch(r'r2d2 touched box_0 at (\d+\.\d{3}) s', verdict.reason)
    assert match and 2.5 <= float(match.group(1)) <= 2.6, verdict  # a tick late at most


@pytest.mark.parametrize('box_x, distance', [(2.7, '3m'), (3.2, '3m'), (3.2, '2.6m')])
def test_a_clearance_beyond_two_metres_is_measured(tmp_path, box_x, distance):
    """A box 2.04 m (2.54 m) away fails a 3 m (2.6 m) clearance at once, as over ROS."""
    verdict = run(tmp_path, "        one_of:\n"
                  "            wait elapsed(1s)\n"
                  f"            assert_min_clearance(distance: {distance})\n",
                  f"    obstacles: string = '[[{box_x}, 0, 0, 0.3, 0.3, 0.5]]'\n")
    assert re.fullmatch(rf'r2d2 came within {distance[:-1]} m of box_0 \(2\.[05]\d\d m, at '
                        r'0\.0\d\d s\)', verdict.reason), verdict


def test_in_process_the_laser_is_off_unless_parameters_turn_it_on():
    """
    What docs/scenarios.md says of seed and scan_noise_std in process, measured.

    Off: no laser, and two seeds give the same run. On through ``parameters``: the
    scan's noise is drawn from the seed, the same for the same seed.
    """
    import numpy
    from r2d2_sim.osc import R2D2Simulation
    from r2d2_sim.osc.parameters import DEFAULTS
    page = (LIBRARY.parents[3] / 'docs' / 'scenarios.md').read_text(encoding='utf-8')
    assert 'in process the laser is off unless `parameters` turns it on' in page
    assert "`'{\\\"scan_rate\\\": 10}'`" in page and 'simulation.robots[0].laser.scan()' in page

    def run_with(seed, parameters):
        simulation = R2D2Simulation()
        simulation.start(dict(DEFAULTS, seed=seed, scan_noise_std=0.05, parameters=parameters,
                              obstacles='[[1.5, 0, 0, 0.3, 0.3, 0.5]]'))
        try:
            assert simulation.error is None, simulation.error
            core = simulation.simulation
            core.robots[0].command(0.3, 0.2)
            for _ in range(10):
                simulation.step()
            laser = core.robots[0].laser
            ranges = None if laser is None else laser.scan()
            return ranges, core.entities.body('r2d2').world_state().position
        finally:
            simulation.shutdown()

    (off_1, where_1), (off_2, where_2) = run_with(1, ''), run_with(2, '')
    assert off_1 is None and off_2 is None and tuple(where_1) == tuple(where_2)
    on = '{"scan_rate": 10}'
    (first, _), (again, _), (other, _) = run_with(1, on), run_with(1, on), run_with(2, on)
    seen = numpy.isfinite(first)
    assert seen.any() and numpy.array_equal(first, again)
    assert not numpy.array_equal(first[seen], other[seen])
