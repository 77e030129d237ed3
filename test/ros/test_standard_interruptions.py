"""
The standard's state machine when requests meet: a load and entity changes, a stop and a step.

In process, on the simulator node's standard services (simulation_interfaces,
Jazzy 1.x). What the services do while another request runs in the
executor's other thread is played here between a step's chunks (the
server takes its lock per chunk, as a request from that thread would), or
with a world load marked running. Each of these failed before its fix: a
spawn during a load answered OK and was lost with the old world; a stop
during a step answered OK while the step went on stepping the reset world;
a reset or a spawn made STOPPED read PAUSED; pausing at time 0 read STOPPED.
"""

import os
import threading

from geometry_msgs.msg import PoseStamped
import pytest
from simulation_interfaces import msg, srv

from common import BOX, FakeGoal

OK = msg.Result.RESULT_OK
STATE = msg.SimulationState


@pytest.fixture
def standard(r2d2_sim):
    """Return call(name, srv_type, **fields) on the in-process simulator's standard services."""
    def call(service, srv_type, **fields):
        return r2d2_sim.call_service(srv_type, '/' + service, srv_type.Request(**fields))
    return call


def state_of(standard):
    """Return the standard's state now."""
    return standard('get_simulation_state', srv.GetSimulationState).state.state


def set_state(standard, value):
    """Ask for a state; return the reply's result code."""
    return standard('set_simulation_state', srv.SetSimulationState,
                    state=STATE(state=value)).result.result


def box_pose(x=2.0):
    """Return a pose for the small box, on the ground ahead."""
    pose = PoseStamped()
    pose.pose.position.x, pose.pose.position.z = x, 0.1
    pose.pose.orientation.w = 1.0
    return pose


def test_entity_changes_while_a_world_loads_are_refused(r2d2_sim, standard):
    """INCORRECT_STATE for every change (it would be lost with the old world); reads answer."""
    standard('spawn_entity', srv.SpawnEntity, name='crate', resource_string=BOX,
             initial_pose=box_pose())
    before = standard('get_entities', srv.GetEntities).entities
    loading = r2d2_sim.sim.standard.activity.loading
    loading.set()  # LoadWorld running in the other thread
    try:
        replies = [
            standard('spawn_entity', srv.SpawnEntity, name='other', resource_string=BOX,
                     initial_pose=box_pose(3.0)),
            standard('spawn_entities', srv.SpawnEntities, spawn_requests=[msg.SpawnEntity(
                name='more', entity_resource=msg.Resource(resource_string=BOX),
                initial_pose=box_pose(4.0))]),
            standard('delete_entity', srv.DeleteEntity, entity='crate'),
            standard('set_entity_state', srv.SetEntityState, entity='crate'),
            standard('set_entity_info', srv.SetEntityInfo, entity='crate'),
        ]
        for reply in replies:
            assert reply.result.result == msg.Result.RESULT_INCORRECT_STATE, reply
            assert 'a world is loading' in reply.result.error_message
        assert standard('get_entities', srv.GetEntities).entities == before
    finally:
        loading.clear()
    assert standard('delete_entity', srv.DeleteEntity, entity='crate').result.result == OK


def test_spawns_refused_while_a_world_loads_leave_no_temporary_files(r2d2_sim, standard,
                                                                     monkeypatch, tmp_path):
    """
    A resource_string (URDF or SDF) is written to a temporary directory before the lock.

    Refused with INCORRECT_STATE, SpawnEntity and SpawnEntities left that
    directory behind, one per request; once the load is done, a spawn keeps
    its own (the temporary directory watched is the one these are written to).
    """
    import tempfile
    made = tmp_path / 'tmp'
    made.mkdir()
    monkeypatch.setattr(tempfile, 'tempdir', str(made))
    sdf_box = ('<sdf version="1.9"><model name="pillar"><link name="l"><collision name="c">'
               '<geometry><box><size>0.2 0.2 0.2</size></box></geometry></collision></link>'
               '</model></sdf>')
    loading = r2d2_sim.sim.standard.activity.loading
    loading.set()  # LoadWorld running in the other thread
    try:
        for index, text in enumerate((BOX, sdf_box)):
            reply = standard('spawn_entity', srv.SpawnEntity, name=f'one_{index}',
                             resource_string=text, initial_pose=box_pose(3.0 + index))
            assert reply.result.result == msg.Result.RESULT_INCORRECT_STATE, reply
        reply = standard('spawn_entities', srv.SpawnEntities, spawn_requests=[
            msg.SpawnEntity(name=f'many_{index}', entity_resource=msg.Resource(
                resource_string=text), initial_pose=box_pose(5.0 + index))
            for index, text in enumerate((BOX, sdf_box))])
        assert reply.result.result == msg.Result.RESULT_INCORRECT_STATE, reply
        assert sorted(os.listdir(made)) == []
    finally:
        loading.clear()
    reply = standard('spawn_entity', srv.SpawnEntity, name='kept', resource_string=BOX,
                     initial_pose=box_pose(3.0))
    assert reply.result.result == OK, reply
    assert len(os.listdir(made)) == 1


@pytest.mark.parametrize('ask, says', [
    (lambda server: server._set_state(srv.SetSimulationState.Request(
        state=STATE(state=STATE.STATE_STOPPED)), srv.SetSimulationState.Response()),
     'the simulation was stopped or reset after 10 steps'),
    (lambda server: server._reset(srv.ResetSimulation.Request(scope=255),
                                  srv.ResetSimulation.Response()),
     'the simulation was stopped or reset after 10 steps'),
])
def test_a_stop_or_a_reset_during_a_step_ends_the_step(r2d2_sim, standard, ask, says):
    """The request is done (OK), the step ends there (failed, saying why), nothing steps after."""
    server = r2d2_sim.sim.standard
    assert set_state(standard, STATE.STATE_PAUSED) == OK
    goal = FakeGoal(100, call_after=10, call=lambda: ask(server))
    result = server._simulate_steps(goal)
    assert [reply.result.result for reply in goal.replies] == [OK]
    assert (result.result.result, result.result.error_message) == \
        (msg.Result.RESULT_OPERATION_FAILED, says)
    assert goal.ended == 'aborted' and len(goal.feedback) == 10
    assert r2d2_sim.sim.step_count == 0
    assert state_of(standard) == STATE.STATE_STOPPED  # paused, at 0, not played since

    def each(done):  # StepSimulation's path: chunks of 24 steps
        if done == 48:
            ask(server)
        return True
    assert set_state(standard, STATE.STATE_PLAYING) == OK
    r2d2_sim.advance(steps=24)
    assert set_state(standard, STATE.STATE_PAUSED) == OK
    error, done = server._run_steps(240, each, chunk=24)
    assert (error, done) == (says.replace('10', '48'), 48)
    assert r2d2_sim.sim.step_count == 0
    reply = standard('step_simulation', srv.StepSimulation, steps=24)
    assert reply.result.result == OK and r2d2_sim.sim.step_count == 24


@pytest.mark.parametrize('reset', [
    lambda server: server._reset(srv.ResetSimulation.Request(scope=2),
                                 srv.ResetSimulation.Response()).result.result,
    lambda server: server._reset(srv.ResetSimulation.Request(scope=4),
                                 srv.ResetSimulation.Response()).result.result,
    lambda server: server._reset(srv.ResetSimulation.Request(scope=6),
                                 srv.ResetSimulation.Response()).result.result,
    lambda server: server._simulator.reset_simulation(state=True) or OK,  # ~/reset
], ids=['STATE', 'SPAWNED', 'STATE|SPAWNED', '~/reset'])
def test_a_reset_that_keeps_the_time_ends_a_step_too(r2d2_sim, standard, reset):
    """The step count stays, yet the world was put back: the step ends there, failed."""
    server = r2d2_sim.sim.standard
    assert set_state(standard, STATE.STATE_PAUSED) == OK
    r2d2_sim.advance(steps=24)
    goal = FakeGoal(100, call_after=10, call=lambda: reset(server))
    result = server._simulate_steps(goal)
    assert goal.replies == [OK]
    assert (result.result.result, result.result.error_message) == (
        msg.Result.RESULT_OPERATION_FAILED, 'the simulation was stopped or reset after 10 steps')
    assert goal.ended == 'aborted' and r2d2_sim.sim.step_count == 34

    def each(done):  # StepSimulation's path: chunks of 24 steps
        if done == 48:
            reset(server)
        return True
    error, done = server._run_steps(240, each, chunk=24)
    assert (error, done) == ('the simulation was stopped or reset after 48 steps', 48)
    assert r2d2_sim.sim.step_count == 34 + 48


def test_zero_steps_fail_where_one_step_would(r2d2_sim, standard):
    """Playing or with no world, zero steps are OPERATION_FAILED too; paused, OK with none."""
    server = r2d2_sim.sim.standard

    def zero_steps():
        reply = standard('step_simulation', srv.StepSimulation, steps=0).result
        goal = FakeGoal(0)
        result = server._simulate_steps(goal).result
        assert goal.feedback == []
        return (reply.result, reply.error_message), (result.result, result.error_message,
                                                     goal.ended)
    failed = msg.Result.RESULT_OPERATION_FAILED
    playing = 'the simulation is playing: pause it first'
    assert state_of(standard) == STATE.STATE_PLAYING
    assert zero_steps() == ((failed, playing), (failed, playing, 'aborted'))
    assert set_state(standard, STATE.STATE_PAUSED) == OK
    assert zero_steps() == ((OK, ''), (OK, '', 'succeeded'))
    assert standard('unload_world', srv.UnloadWorld).result.result == OK
    unloaded = 'no world is loaded (UnloadWorld): load one to step'
    assert zero_steps() == ((failed, unloaded), (failed, unloaded, 'aborted'))
    assert r2d2_sim.sim.step_count == 0


def test_quitting_stops_the_simulation_first_and_reads_quitting_until_the_exit(r2d2_sim,
                                                                               standard):
    """Paused before the reply (no step after it), QUITTING read, steps refused, then exit."""
    server, sim = r2d2_sim.sim.standard, r2d2_sim.sim
    quit_called = threading.Event()
    server._on_quit = quit_called.set  # what sim_node gives: its stop event's set
    r2d2_sim.advance(steps=10)
    assert state_of(standard) == STATE.STATE_PLAYING
    assert set_state(standard, STATE.STATE_QUITTING) == OK
    assert sim.paused and not sim.advance_if_running()  # the paced loop steps no more
    stepped = sim.step_count
    assert state_of(standard) == STATE.STATE_QUITTING
    assert set_state(standard, STATE.STATE_QUITTING) == \
        srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    assert set_state(standard, STATE.STATE_PLAYING) == \
        srv.SetSimulationState.Response.INCORRECT_TRANSITION
    reply = standard('step_simulation', srv.StepSimulation, steps=1).result
    assert (reply.result, reply.error_message) == (
        msg.Result.RESULT_OPERATION_FAILED, 'the simulator is shutting down (after 0 steps)')
    assert sim.paused and sim.step_count == stepped
    assert quit_called.wait(5.0)  # after the reply, as SIGINT would
    assert state_of(standard) == STATE.STATE_QUITTING


@pytest.mark.parametrize('change', ['reset time', 'reset state', 'reset spawned', 'spawn',
                                    'set entity state'])
def test_stopped_stays_stopped_until_it_steps_or_plays(standard, change):
    """Nothing that leaves the clock at 0 un-stops it; a step makes it PAUSED, PLAYING plays."""
    assert set_state(standard, STATE.STATE_STOPPED) == OK
    reply = {
        'reset time': lambda: standard('reset_simulation', srv.ResetSimulation, scope=1),
        'reset state': lambda: standard('reset_simulation', srv.ResetSimulation, scope=2),
        'reset spawned': lambda: standard('reset_simulation', srv.ResetSimulation, scope=4),
        'spawn': lambda: standard('spawn_entity', srv.SpawnEntity, name='crate',
                                  resource_string=BOX, initial_pose=box_pose()),
        'set entity state': lambda: standard('set_entity_state', srv.SetEntityState,
                                             entity='r2d2', state=msg.EntityState(
                                                 pose=box_pose(0.5).pose)),
    }[change]()
    assert reply.result.result == OK
    assert state_of(standard) == STATE.STATE_STOPPED
    assert set_state(standard, STATE.STATE_PAUSED) == \
        srv.SetSimulationState.Response.INCORRECT_TRANSITION
    assert standard('step_simulation', srv.StepSimulation, steps=1).result.result == OK
    assert state_of(standard) == STATE.STATE_PAUSED


def test_a_time_reset_alone_while_paused_reads_paused_and_stopped_resets(r2d2_sim, standard):
    """TIME keeps the world as it is, so not STOPPED ("resetting with ALL"); STOPPED then is."""
    assert set_state(standard, STATE.STATE_PAUSED) == OK
    assert standard('step_simulation', srv.StepSimulation, steps=100).result.result == OK
    assert standard('spawn_entity', srv.SpawnEntity, name='crate', resource_string=BOX,
                    initial_pose=box_pose()).result.result == OK
    reply = standard('reset_simulation', srv.ResetSimulation, scope=1)
    assert reply.result.result == OK and r2d2_sim.sim.step_count == 0
    assert state_of(standard) == STATE.STATE_PAUSED
    assert 'crate' in standard('get_entities', srv.GetEntities).entities
    assert set_state(standard, STATE.STATE_STOPPED) == OK  # not ALREADY_IN_TARGET_STATE
    assert state_of(standard) == STATE.STATE_STOPPED
    assert 'crate' not in standard('get_entities', srv.GetEntities).entities
    # A step, then a time reset: the same, whatever came before.
    assert standard('step_simulation', srv.StepSimulation, steps=1).result.result == OK
    assert standard('reset_simulation', srv.ResetSimulation, scope=1).result.result == OK
    assert state_of(standard) == STATE.STATE_PAUSED


def test_pausing_a_simulation_playing_at_time_zero_reads_paused(r2d2_sim, standard):
    """It played: PAUSED (not STOPPED), and a second PAUSED is already in the target state."""
    assert r2d2_sim.sim.step_count == 0 and state_of(standard) == STATE.STATE_PLAYING
    assert set_state(standard, STATE.STATE_PAUSED) == OK
    assert state_of(standard) == STATE.STATE_PAUSED
    assert set_state(standard, STATE.STATE_PAUSED) == \
        srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE


@pytest.mark.parametrize('scope', [8, 16, 128, 8 | 1])
def test_a_reset_scope_this_simulator_does_not_know_resets_nothing(r2d2_sim, standard, scope):
    """FEATURE_UNSUPPORTED naming the bits; the time goes on as it was."""
    r2d2_sim.advance(steps=24)
    reply = standard('reset_simulation', srv.ResetSimulation, scope=scope)
    assert reply.result.result == msg.Result.RESULT_FEATURE_UNSUPPORTED
    assert f'scope bits {scope & ~7}' in reply.result.error_message
    assert r2d2_sim.sim.step_count == 24
