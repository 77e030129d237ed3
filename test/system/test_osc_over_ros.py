"""
The same scenarios over ROS: the library's actions against a running sim_node, the same verdicts.

``scenario_execution --simulation r2d2_sim.osc:StandardSimulation`` against a
``SimProcess`` started with the scenario's own parameters (its world, start and
seed: ``simulator_parameters``): the standard's services found by type, the
simulator stepped in lockstep, one control period a tick. Each verdict is compared
with the in-process run's.
"""

from pathlib import Path
import re
import xml.etree.ElementTree as ElementTree

import pytest

from common import OSC_EXAMPLES, osc_env, scenario_execution
from r2d2_sim.osc.variations import run_document, simulator_parameters, Task, tasks_of
from r2d2_sim.testing import SimProcess

OVER_ROS = 'r2d2_sim.osc:StandardSimulation'


@pytest.mark.parametrize('example, document', [('obstacle_stop.osc', None),
                                               ('crossing.osc', 1)])
def test_the_verdict_over_ros_is_the_in_process_one(tmp_path, example, document):
    """The crate spawned mid-run is stopped for (passes); r2 at 0.6 m/s comes too near (fails)."""
    scenario = OSC_EXAMPLES / example
    speeds = OSC_EXAMPLES / 'crossing_speeds.yaml'
    task = tasks_of(str(scenario), str(speeds) if document is not None else None)[document or 0]
    local = run_document(task)
    args = ['--simulation', OVER_ROS, scenario]
    if document is not None:
        single = tmp_path / 'document.yaml'
        single.write_text(speeds.read_text().split('---\n')[document])
        args = ['--scenario-parameter-file', single, *args]
    with SimProcess(**simulator_parameters(str(scenario), task.document)) as sim:
        status, output, cases = scenario_execution(
            args, osc_env(tmp_path / 'shim', ROS_DOMAIN_ID=sim.domain_id), tmp_path)
    assert list(cases.values()) == [None if local.passed else 'execution failed.'], \
        output[-3000:]
    assert local.passed == (document is None)
    if not local.passed:
        assert local.reason.split(' (')[0] in output  # the same check fails, against r2
    assert 'Traceback' not in output


def test_a_start_off_the_round_numbers_runs_over_ros_bit_for_bit_as_in_process(
        tmp_path, monkeypatch):
    """
    Start at (0.3, -0.2), yaw 0.7: the robot's pose after every tick is the same bits.

    sim_node, started at the scenario's start, reads it back in float32 (0.3 is
    0.30000001192...): the robot is not placed again (a SetEntityState changed the run).
    """
    from recording_simulations import POSES
    scenario = tmp_path / 'start.osc'
    scenario.write_text(
        'import osc.helpers\nimport osc.r2d2\n\nscenario start:\n    timeout(10s)\n'
        '    start_x: float = 0.3\n    start_y: float = -0.2\n    start_yaw: float = 0.7\n'
        '    do serial:\n        drive(linear: 0.4mps, angular: 0.3radps, duration: 1s)\n'
        '        wait elapsed(0.5s)\n')
    task = Task(str(scenario), 0, None)
    local = run_document(task._replace(simulation='recording_simulations:RecordingInProcess'))
    with SimProcess(**simulator_parameters(str(scenario))) as sim:
        monkeypatch.setenv('ROS_DOMAIN_ID', str(sim.domain_id))
        remote = run_document(task._replace(simulation='recording_simulations:RecordingOverRos'))
    assert local.passed and remote.passed, (local.reason, remote.reason)
    assert len(POSES['in_process']) > 20
    assert POSES['over_ros'] == POSES['in_process']


@pytest.mark.parametrize('back', [
    '        reset_simulation()\n',
    '        set_simulation_state(state: simulation_state!stopped)\n'
    '        set_simulation_state(state: simulation_state!playing)\n',
    "        load_world(uri: 'package://r2d2_sim/urdf/empty.world.yaml')\n"
    '        set_simulation_state(state: simulation_state!playing)\n',
], ids=['reset_simulation', 'stopped', 'load_world'])
def test_a_reset_over_ros_puts_the_robot_at_the_scenarios_start(tmp_path, back):
    """sim_node started at its own (0, 0): after a reset the robot is at the scenario's start."""
    scenario = tmp_path / 'back.osc'
    scenario.write_text(
        'import osc.helpers\nimport osc.r2d2\n\nscenario back:\n    timeout(10s)\n'
        '    start_x: float = 1.0\n    start_y: float = 0.5\n    start_yaw: float = 1.0\n'
        '    do serial:\n        drive(linear: 0.4mps, duration: 1s)\n' + back
        + '        wait elapsed(0.5s)\n'
        '        wait_until_in_region(x: 1m, y: 0.5m, radius: 0.05m)\n')
    assert run_document(Task(str(scenario), 0, None)).passed  # in process
    with SimProcess(publish_rate=20.0, scan_rate=0.0, imu_rate=0.0) as sim:
        status, output, cases = scenario_execution(
            ['--simulation', OVER_ROS, scenario],
            osc_env(tmp_path / 'shim', ROS_DOMAIN_ID=sim.domain_id), tmp_path)
    assert cases == {'back': None} and status == 0, output[-3000:]


def test_a_simulator_under_a_namespace_is_found_by_type(tmp_path):
    """sim_node under /sim: the scenario names that namespace, its services are found there."""
    scenario = tmp_path / 'spawn.osc'
    scenario.write_text(
        "import osc.r2d2\n\nscenario spawn:\n    simulator_namespace: string = '/sim'\n"
        "    do serial:\n"
        "        spawn_entity(entity_name: 'cube', uri: 'cube_small.urdf', initial_pose: "
        "pose_3d(position: position_3d(x: 1m, z: 0.1m)))\n"
        "        wait_until_in_region(entity: 'cube', x: 1m, y: 0m, radius: 0.05m)\n"
        "        delete_entity(entity: 'cube')\n")
    with SimProcess(namespace='sim', publish_rate=20.0, scan_rate=0.0, imu_rate=0.0) as sim:
        status, output, cases = scenario_execution(
            ['--simulation', OVER_ROS, scenario],
            osc_env(tmp_path / 'shim', ROS_DOMAIN_ID=sim.domain_id), tmp_path)
        names = sim.standard.entities()
    assert cases == {'spawn': None} and status == 0, output[-3000:]
    assert 'cube' not in names


def test_a_check_counts_only_what_happens_after_it_starts(tmp_path):
    """
    A touch between two checks counts for neither, over ROS as in process.

    The first assert_no_contact is given up at 0.5 s; R2D2 then touches the box and backs
    off; a second one, with the same limits, starts after: both sides pass.
    """
    scenario = tmp_path / 'past.osc'
    scenario.write_text(
        "import osc.helpers\nimport osc.r2d2\n\nscenario past:\n    timeout(20s)\n"
        "    obstacles: string = '[[0.8, 0, 0, 0.3, 0.3, 0.5]]'\n"
        "    do serial:\n"
        "        one_of:\n            wait elapsed(0.5s)\n            assert_no_contact()\n"
        "        drive(linear: 0.4mps, duration: 2s)\n"
        "        drive(linear: -0.4mps, duration: 3s)\n"
        "        wait elapsed(0.5s)\n"
        "        one_of:\n            wait elapsed(1s)\n            assert_no_contact()\n")
    local = run_document(Task(str(scenario), 0, None))
    assert local.passed, local.reason
    assert [c['other'] for c in local.outcome['contacts']] == ['box_0']  # it did touch
    with SimProcess(**simulator_parameters(str(scenario))) as sim:
        status, output, cases = scenario_execution(
            ['--simulation', OVER_ROS, scenario],
            osc_env(tmp_path / 'shim', ROS_DOMAIN_ID=sim.domain_id), tmp_path)
    assert cases == {'past': None} and status == 0, output[-3000:]


def test_a_simulator_whose_step_does_not_fit_the_control_period_is_refused(tmp_path):
    """sim_node at 250 Hz: 12.5 steps a tick would drift from the scenario's clock; one line."""
    scenario = tmp_path / 'drive.osc'
    scenario.write_text("import osc.r2d2\n\nscenario drive:\n    do serial:\n"
                        "        drive(linear: 0.2mps, duration: 1s)\n")
    with SimProcess(physics_rate=250.0, publish_rate=50.0, scan_rate=0.0, imu_rate=0.0) as sim:
        status, output, cases = scenario_execution(
            ['--simulation', OVER_ROS, scenario],
            osc_env(tmp_path / 'shim', ROS_DOMAIN_ID=sim.domain_id), tmp_path)
    says = ("r2d2_sim: the simulator's physics rate 250 Hz: a control period of 0.05 s would be "
            '12.5 physics steps, not a whole number; use a rate that is a multiple of 20 Hz')
    assert status == 1 and cases == {'drive': 'execution failed.'}, output[-3000:]
    assert len([line for line in output.splitlines() if says in line]) == 1, output[-3000:]
    assert 'Traceback' not in output


def test_the_steps_of_step_simulation_count_in_the_scenarios_time(tmp_path):
    """
    240 steps while paused are 1 s: a touch after them is reported 1 s later than without.

    Two scenarios in one file, the same drive into a box after a pause: one steps the
    paused simulator 240 times (step_simulation), the other not.
    """
    def touching(name, stepped):
        return (f'scenario {name}:\n    timeout(20s)\n'
                "    obstacles: string = '[[0.8, 0, 0, 0.3, 0.3, 0.5]]'\n"
                '    do serial:\n'
                '        set_simulation_state(state: simulation_state!paused)\n'
                + ('        step_simulation(steps: 240)\n' if stepped else '')
                + '        set_simulation_state(state: simulation_state!playing)\n'
                '        one_of:\n'
                '            drive(linear: 0.4mps, duration: 5s)\n'
                '            assert_no_contact()\n')
    scenario = tmp_path / 'stepped.osc'
    scenario.write_text('import osc.helpers\nimport osc.r2d2\n\n' + touching('plain', False)
                        + touching('stepped', True))
    with SimProcess(**simulator_parameters(str(scenario))) as sim:
        status, output, cases = scenario_execution(
            ['--simulation', OVER_ROS, scenario],
            osc_env(tmp_path / 'shim', ROS_DOMAIN_ID=sim.domain_id), tmp_path)
    assert cases == {'plain': 'execution failed.', 'stepped': 'execution failed.'}, \
        output[-3000:]
    times = re.findall(r'r2d2 touched box_0 at (\d+\.\d{3}) s', output)  # plain's first
    plain, stepped = float(times[0]), float(times[-1])
    assert stepped - plain == pytest.approx(1.0, abs=0.06), output[-3000:]


def test_a_simulator_that_goes_away_mid_run_fails_the_scenario_in_one_line(tmp_path):
    """
    sim_node stopped 1 s into a 600 s scenario: one line, the scenario failed in test.xml.

    Only the check asks the simulator anything, through each tick's step and sampling:
    that is where the simulator's going away is met (it was a traceback and no test.xml).
    """
    import subprocess
    import sys
    from rosgraph_msgs.msg import Clock
    scenario = tmp_path / 'long.osc'
    scenario.write_text("import osc.helpers\nimport osc.r2d2\n\nscenario long:\n"
                        "    do one_of:\n        wait elapsed(600s)\n"
                        "        assert_not_tipped()\n")
    command = [str(Path(sys.executable).with_name('scenario_execution')), '-o', 'out',
               '--simulation', OVER_ROS, str(scenario)]
    with SimProcess(start_paused=True, **simulator_parameters(str(scenario))) as sim:
        seconds = [0]  # of simulated time, which only the scenario's steps advance
        sim.probe.node.create_subscription(
            Clock, '/clock', lambda msg: seconds.append(msg.clock.sec), 10)
        run = subprocess.Popen(command, cwd=tmp_path, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True,
                               env=osc_env(tmp_path / 'shim', ROS_DOMAIN_ID=sim.domain_id,
                                           R2D2_OSC_CALL_S='5'))
        try:
            assert sim.probe.spin_until(lambda: seconds[-1] >= 1, 60.0), \
                'the scenario did not step the simulator'
            sim.stop()
            output, _ = run.communicate(timeout=120)
        finally:
            if run.poll() is None:
                run.kill()
                run.communicate()
    says = [line for line in output.splitlines()
            if 'r2d2_sim: the simulator failed mid-run: ' in line]
    assert run.returncode == 1 and len(says) == 1, output[-3000:]
    assert re.search(r'--> assert_not_tipped \[✕\] -- the simulator failed mid-run: ', output)
    assert 'Traceback' not in output
    cases = ElementTree.parse(tmp_path / 'out' / 'test.xml').getroot().findall('testcase')
    assert [(case.get('name'), case.find('failure') is not None) for case in cases] == \
        [('long', True)]
