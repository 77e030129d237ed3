"""
ROS 2's simulation standard (simulation_interfaces, Jazzy 1.x) on sim_node in its own process.

A client in another process that knows only the standard drives sim_node
through the whole sequence of a test that changes its world; then what a long
step leaves answered, the action, names and signals. Each result code in
process is ros/test_sim_interfaces.py's.
"""

import json
import math
from pathlib import Path
import subprocess
import sys

from action_msgs.msg import GoalStatus
import pytest
from simulation_interfaces import msg, srv
from simulation_interfaces.action import SimulateSteps

from common import BOX, REPO, TEST_DIR
from r2d2_sim.client import ros_child_env
from r2d2_sim.testing import RefusedError

OK = msg.Result.RESULT_OK
CLIENT = Path(TEST_DIR) / 'children' / 'standard_client.py'


def test_a_client_of_the_standard_alone_drives_the_whole_sequence(r2d2_sim_process, tmp_path):
    """Features, pause, 240 steps = 1 s, spawn, scan, teleport, states, resets, delete, step."""
    sim = r2d2_sim_process(cmd_vel_timeout=0.0, scan_rate=60.0)
    out = tmp_path / 'seen.json'
    result = subprocess.run([sys.executable, str(CLIENT), str(out)],
                            env=ros_child_env(sim.domain_id), cwd=REPO, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    seen = json.loads(out.read_text())
    features = msg.SimulatorFeatures
    assert {features.SPAWNING, features.DELETING, features.STEP_SIMULATION_MULTIPLE,
            features.STEP_SIMULATION_ACTION, features.SIMULATION_RESET_SPAWNED,
            features.ENTITY_STATE_SETTING} <= set(seen['features'])
    assert seen['custom_info']['simulator'] == 'r2d2_sim'
    assert seen['custom_info']['step_s'] == pytest.approx(1 / 240)
    assert seen['clock_advance_ns'] == 10**9
    assert seen['robot'] == 'r2d2' and seen['entities_at_start'] == ['ground_plane', 'r2d2']
    # The box's near face is 1.35 m ahead of base_link; the laser is on the body's axis.
    assert seen['scan_ahead_m'] == pytest.approx(1.35, abs=0.01)
    robot_x, robot_y, robot_z, frame = seen['states']['r2d2']
    assert (robot_x, robot_y, frame) == (pytest.approx(-1.0, abs=0.01),
                                         pytest.approx(0.0, abs=0.01), 'world')
    assert seen['states']['box'][0] == pytest.approx(1.5, abs=0.01)
    resets = seen['resets']
    assert resets['SCOPE_TIME']['clock_ns'] == 10**9 // 240  # back to 0, plus the one step
    assert resets['SCOPE_TIME']['robot_x'] == pytest.approx(-1.0, abs=0.01)  # still there
    assert resets['SCOPE_STATE']['robot_x'] == pytest.approx(0.0, abs=0.01)  # back home
    assert 'box' in resets['SCOPE_STATE']['entities']  # a state reset keeps spawned ones
    assert 'box' not in resets['SCOPE_SPAWNED']['entities']
    assert seen['after_delete'] == ['ground_plane', 'r2d2']
    # rclpy's ActionClient drops feedback that arrives after the result: not all of it is seen.
    action = seen['action']
    assert action['result'] == OK and action['clock_advance_ns'] == 12 * 10**9 // 240
    assert action['feedback'] == sorted(set(action['feedback']))
    assert set(action['feedback']) <= set(range(1, 13))
    assert seen['final_state'] == msg.SimulationState.STATE_PAUSED


def test_a_long_step_repeats_bit_for_bit_however_it_is_cut(r2d2_sim_process):
    """Two sim_node processes: 480 steps in one step_simulation, or in 48 of 10: one pose."""
    poses = []
    for calls, steps in ((1, 480), (48, 10)):
        sim = r2d2_sim_process(start_paused=True, cmd_vel_timeout=0.0)
        sim.send_cmd_vel(linear=0.3, angular=0.5)  # returns once the node has counted it
        for _ in range(calls):
            sim.step_physics(steps)
        state = sim.entity_state('r2d2')
        poses.append((state.position, state.orientation, state.linear_velocity))
        assert sim.status()['step'] == 480
    assert poses[0] == poses[1]  # exactly: the lock released between chunks changes nothing
    assert poses[0][0][0] > 0.3  # it did drive


def test_a_negative_step_count_is_refused_here_and_nothing_is_sent(r2d2_sim_process):
    """step_physics(-1) and step(-1): ValueError in one line; the simulator stays where it was."""
    sim = r2d2_sim_process(start_paused=True)
    before = sim.status()['step']
    for call in (sim.step_physics, sim.step):
        with pytest.raises(ValueError, match='must be a whole number >= 0, got -1'):
            call(-1)
    after = sim.step_physics(24)  # the next request is served: no runaway step holds it
    assert after['step'] == before + 24 and after['paused']


def test_a_long_step_leaves_the_other_services_answered(r2d2_sim_process):
    """While 40 s of simulated time are stepped, get_simulation_state and cmd_vel are answered."""
    sim = r2d2_sim_process(start_paused=True, cmd_vel_timeout=0.0)
    client = sim.standard
    step = sim.probe.node.create_client(srv.StepSimulation, '/step_simulation')
    assert sim.probe.spin_until(step.service_is_ready, 30.0)
    long_step = step.call_async(srv.StepSimulation.Request(steps=240 * 40))
    assert sim.probe.spin_until(lambda: sim.status()['step'] > 0, 30.0)  # under way
    assert client.state() == msg.SimulationState.STATE_PAUSED  # answered meanwhile
    sim.send_cmd_vel(linear=0.3)  # taken meanwhile (the count of ~/get_status rose)
    assert not long_step.done(), 'the step ended before the other calls: make it longer'
    assert sim.probe.spin_until(long_step.done, 60.0)
    assert long_step.result().result.result == OK
    assert sim.status()['step'] == 240 * 40


def test_simulate_steps_gives_feedback_and_can_be_cancelled(r2d2_sim_process):
    """The action steps with feedback after each step; a cancel stops it, still paused."""
    sim = r2d2_sim_process(start_paused=True)
    sim.standard.simulate_steps(1)  # feedback is a topic: matched from the first goal on
    seen = []
    status, result = sim.standard.simulate_steps(
        240, feedback=lambda f: seen.append(f.feedback.completed_steps))
    assert result.result.result == OK and status == GoalStatus.STATUS_SUCCEEDED
    assert sim.status()['step'] == 1 + 240
    # One feedback per step, in order; rclpy's ActionClient drops those arriving after
    # the result, so the last few may not be seen.
    assert seen and seen == sorted(set(seen)) and set(seen) <= set(range(1, 241))
    from rclpy.action import ActionClient
    client = ActionClient(sim.probe.node, SimulateSteps, '/simulate_steps')
    assert sim.probe.spin_until(client.server_is_ready, 30.0)
    goal = client.send_goal_async(SimulateSteps.Goal(steps=240 * 60))
    assert sim.probe.spin_until(goal.done, 30.0)
    handle = goal.result()
    cancel = handle.cancel_goal_async()
    assert sim.probe.spin_until(cancel.done, 30.0)
    outcome = handle.get_result_async()
    assert sim.probe.spin_until(outcome.done, 30.0)
    assert outcome.result().status == GoalStatus.STATUS_CANCELED
    assert sim.status()['paused'] and 5 < sim.status()['step'] < 5 + 240 * 60


def test_the_standard_node_keeps_its_name_under_a_node_remap(r2d2_sim_process):
    """-r __node:=x (launch's name=) renames the simulator; its standard node is x_standard."""
    sim = r2d2_sim_process(node_name='custom_sim', start_paused=True)

    def names():
        return {name for name, _ in sim.probe.node.get_node_names_and_namespaces()}
    assert sim.probe.spin_until(lambda: {'custom_sim', 'custom_sim_standard'} <= names(), 30.0), \
        names()  # the graph's node names arrive with discovery, after the services
    assert sim.standard.state() == msg.SimulationState.STATE_STOPPED


def test_sigint_during_a_long_step_stops_cleanly(r2d2_sim_process):
    """The step under way ends at its chunk before physics closes: exit 0, nothing on stderr."""
    sim = r2d2_sim_process(start_paused=True)
    step = sim.probe.node.create_client(srv.StepSimulation, '/step_simulation')
    assert sim.probe.spin_until(step.service_is_ready, 30.0)
    step.call_async(srv.StepSimulation.Request(steps=240 * 600))
    assert sim.probe.spin_until(lambda: sim.status()['step'] > 0, 30.0)
    result = sim.stop()
    assert result.returncode == 0, result.stderr
    assert 'never retrieved' not in result.stderr and 'Traceback' not in result.stderr
    assert 'physics server' not in result.stderr


def test_the_testing_api_changes_the_world_in_process_and_across(r2d2_sim, r2d2_sim_process):
    """spawn, entity_state, set_entity_state, delete_entity, reset_world: both harnesses."""
    process = r2d2_sim_process(start_paused=True)
    for harness, step in ((r2d2_sim, lambda: r2d2_sim.advance(24)),
                          (process, lambda: process.step_physics(24))):
        box = harness.spawn(BOX, position=(1.0, 0.0, 0.1))
        assert harness.spawn(BOX, position=(2.0, 0.0, 0.1)) == box + '_1'
        step()
        assert harness.entity_state(box).position[0] == pytest.approx(1.0, abs=0.01)
        harness.set_entity_state('r2d2', (-1.0, 0.5, 0.471), yaw=math.pi / 2)
        step()
        assert harness.entity_state('r2d2').position[:2] == pytest.approx((-1.0, 0.5), abs=0.01)
        harness.delete_entity(box + '_1')
        with pytest.raises(RefusedError, match='NOT_FOUND') as refused:
            harness.delete_entity(box + '_1')
        assert refused.value.code == 'NOT_FOUND' and str(refused.value).count('NOT_FOUND') == 1
        # A name given is that name or an error; renaming only on request.
        with pytest.raises(RefusedError, match='NAME_NOT_UNIQUE'):
            harness.spawn(BOX, name=box)
        with pytest.raises(RefusedError, match='NAME_INVALID'):
            harness.spawn(BOX, name='a box/1')
        assert harness.spawn(BOX, name=box, allow_renaming=True) == box + '_1'
        harness.reset_world()  # all: time back to 0, spawned gone, everything home
        assert harness.entities() == ['ground_plane', 'r2d2']
        assert harness.entity_state('r2d2').position[0] == pytest.approx(0.0, abs=1e-3)
    process.resume()
    with pytest.raises(RefusedError, match='OPERATION_FAILED'):
        process.step_physics(24)  # the standard steps only a paused simulation


def test_a_process_reset_with_no_scope_is_refused_as_in_process(r2d2_sim_process):
    """A SimProcess refuses every scope False as SimHarness does; it used to reset it all."""
    process = r2d2_sim_process(start_paused=True)
    box = process.spawn(BOX, position=(1.0, 0.0, 0.1))
    with pytest.raises(ValueError, match='all False, which resets nothing'):
        process.reset_world(time=False, state=False, spawned=False)
    assert box in process.entities()
