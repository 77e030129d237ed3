"""
ROS 2's simulation standard (simulation_interfaces, Jazzy 1.x) on the simulator node.

A client in another process that knows only the standard drives sim_node
through the whole sequence of a test that changes its world; then each
result code, in process, and what a long step leaves answered.
"""

import json
import math
import subprocess
import sys
from pathlib import Path

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import Point
import pytest
from simulation_interfaces import msg, srv
from simulation_interfaces.action import SimulateSteps

from helpers import REPO
from r2d2_sim.client import ros_child_env
from r2d2_sim.sim.entities import MAX_SPAWNED
from r2d2_sim.sim.spawnables import MAX_LINKS
from r2d2_sim.testing import RefusedError

CLIENT = Path(__file__).resolve().parent / 'children' / 'standard_client.py'
ROOM = 'package://r2d2_sim/urdf/room.urdf'
BOX = ('<robot name="box"><link name="box"><inertial><mass value="1"/><inertia ixx="0.01" '
       'iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial><collision><geometry>'
       '<box size="0.2 0.2 0.2"/></geometry></collision></link></robot>')
OK = msg.Result.RESULT_OK


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


@pytest.fixture
def standard(r2d2_sim):
    """Return call(name, srv_type, request) on the in-process simulator's standard services."""
    def call(name, srv_type, request):
        return r2d2_sim.call_service(srv_type, '/' + name, request)
    return call


def spawn_request(**fields):
    """Return a SpawnEntity request for the small box at (1, 0, 0.1), fields overriding."""
    request = srv.SpawnEntity.Request(name='box', resource_string=BOX)
    request.initial_pose.pose.position.x, request.initial_pose.pose.position.z = 1.0, 0.1
    request.initial_pose.pose.orientation.w = 1.0
    for name, value in fields.items():
        setattr(request, name, value)
    return request


def code(response):
    """Return a reply's result code."""
    return response.result.result


BAD_SPAWNS = {
    'unknown file': ({'resource_string': '', 'uri': '/no/such/file.urdf'},
                     srv.SpawnEntity.Response.NO_RESOURCE),
    'nothing to spawn': ({'resource_string': ''}, srv.SpawnEntity.Response.NO_RESOURCE),
    'not a URDF file': ({'resource_string': '', 'uri': '/etc/passwd'},
                        srv.SpawnEntity.Response.UNSUPPORTED_FORMAT),
    'not a robot': ({'resource_string': '<sdf version="1.6"/>'},
                    srv.SpawnEntity.Response.UNSUPPORTED_FORMAT),
    'does not parse': ({'resource_string': '<robot name="x"><link name="a"></robot'},
                       srv.SpawnEntity.Response.RESOURCE_PARSE_ERROR),
    'entity bomb': ({'resource_string': '<!DOCTYPE r [<!ENTITY a "aaaaaaaaaa">'
                                        '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;">]>'
                                        '<robot name="b"><link name="&b;"/></robot>'},
                    srv.SpawnEntity.Response.RESOURCE_PARSE_ERROR),
    'huge': ({'resource_string': '<robot name="h">' + ' ' * 1_000_001 + '<link name="a"/>'
                                 '</robot>'}, srv.SpawnEntity.Response.RESOURCE_PARSE_ERROR),
    'too many links': ({'resource_string': '<robot name="l">' + ''.join(
        f'<link name="l{i}"/>' for i in range(MAX_LINKS + 1)) + '</robot>'},
        srv.SpawnEntity.Response.RESOURCE_PARSE_ERROR),
    'mesh outside': ({'resource_string': '<robot name="m"><link name="a"><visual><geometry>'
                                         '<mesh filename="/etc/passwd"/></geometry></visual>'
                                         '</link></robot>'},
                     srv.SpawnEntity.Response.UNSUPPORTED_ASSETS),
    'mesh missing': ({'resource_string': '<robot name="m"><link name="a"><visual><geometry>'
                                         '<mesh filename="package://r2d2_sim/no.stl"/>'
                                         '</geometry></visual></link></robot>'},
                     srv.SpawnEntity.Response.MISSING_ASSETS),
    'invalid name': ({'name': 'a box/with slash'}, srv.SpawnEntity.Response.NAME_INVALID),
    'duplicate name': ({'name': 'r2d2'}, srv.SpawnEntity.Response.NAME_NOT_UNIQUE),
    'invalid namespace': ({'entity_namespace': '/bad//namespace'},
                          srv.SpawnEntity.Response.NAMESPACE_INVALID),
}


@pytest.mark.parametrize('fields, expected', BAD_SPAWNS.values(), ids=BAD_SPAWNS.keys())
def test_a_bad_spawn_gets_its_code_and_changes_nothing(r2d2_sim, standard, fields, expected):
    """Refused with the standard's code, in one line that quotes no file; the world unchanged."""
    reply = standard('spawn_entity', srv.SpawnEntity, spawn_request(**fields))
    assert code(reply) == expected, reply.result.error_message
    message = reply.result.error_message
    assert message and '\n' not in message and 'root:' not in message and len(message) < 400
    assert r2d2_sim.entities() == ['ground_plane', 'r2d2']
    r2d2_sim.advance(24)
    assert all(map(math.isfinite, (r2d2_sim.ground_truth().pose.pose.position.x,
                                   r2d2_sim.ground_truth().pose.pose.position.z)))


def test_a_bad_pose_is_invalid_pose(r2d2_sim, standard):
    """NaN, a non-unit quaternion, 20 km out: INVALID_POSE for spawn and set_entity_state."""
    for bad in ({'x': math.nan, 'w': 1.0}, {'x': 0.0, 'w': 2.0}, {'x': 2.0e4, 'w': 1.0}):
        request = spawn_request()
        request.initial_pose.pose.position.x = bad['x']
        request.initial_pose.pose.orientation.w = bad['w']
        reply = standard('spawn_entity', srv.SpawnEntity, request)
        assert code(reply) == srv.SpawnEntity.Response.INVALID_POSE
        place = srv.SetEntityState.Request(entity='r2d2')
        place.state.pose.position.x = bad['x']
        place.state.pose.orientation.w = bad['w']
        reply = standard('set_entity_state', srv.SetEntityState, place)
        assert code(reply) == srv.SetEntityState.Response.INVALID_POSE
    assert r2d2_sim.entity_state('r2d2').position[0] == pytest.approx(0.0, abs=1e-3)


def test_unknown_entities_are_not_found(standard):
    """Every entity service says NOT_FOUND for a name the world does not have."""
    for name, srv_type, request in (
            ('get_entity_state', srv.GetEntityState, srv.GetEntityState.Request(entity='x')),
            ('get_entity_info', srv.GetEntityInfo, srv.GetEntityInfo.Request(entity='x')),
            ('delete_entity', srv.DeleteEntity, srv.DeleteEntity.Request(entity='x')),
            ('set_entity_state', srv.SetEntityState, srv.SetEntityState.Request(entity='x'))):
        reply = standard(name, srv_type, request)
        assert code(reply) == msg.Result.RESULT_NOT_FOUND, name
        assert 'r2d2' in reply.result.error_message  # it names the ones there are


def test_a_static_body_takes_no_twist(standard):
    """A twist for the ground plane: OPERATION_FAILED (deleting it: test_delete_and_reset_...)."""
    place = srv.SetEntityState.Request(entity='ground_plane')
    place.state.pose.orientation.w = 1.0
    place.state.twist.linear.x = 1.0
    assert code(standard('set_entity_state', srv.SetEntityState, place)) == \
        msg.Result.RESULT_OPERATION_FAILED


def test_entities_are_filtered_described_and_spawned_in_batches(standard):
    """Filters (regex search, category, sphere); entity info; spawn_entities; get_spawnables."""
    batch = srv.SpawnEntities.Request()
    for name, x, rename in (('crate', 1.0, True), ('crate', 3.0, True),
                            ('bad name!', 5.0, False)):
        one = msg.SpawnEntity(name=name, allow_renaming=rename)
        one.entity_resource.resource_string = BOX
        one.initial_pose.pose.position.x, one.initial_pose.pose.position.z = x, 0.1
        one.initial_pose.pose.orientation.w = 1.0
        batch.spawn_requests.append(one)
    reply = standard('spawn_entities', srv.SpawnEntities, batch)
    assert code(reply) == srv.SpawnEntities.Response.ENTITIES_SPAWN_FAILED
    assert [(r.result.result, r.entity_name) for r in reply.results][:2] == \
        [(OK, 'crate'), (OK, 'crate_1')]
    assert reply.results[2].result.result == msg.SpawnResult.NAME_INVALID

    def entities(**filters):
        request = srv.GetEntities.Request()
        for field, value in filters.items():
            setattr(request.filters, field, value)
        reply = standard('get_entities', srv.GetEntities, request)
        assert code(reply) == OK, reply.result.error_message
        return sorted(reply.entities)
    assert entities() == ['crate', 'crate_1', 'ground_plane', 'r2d2']
    assert entities(filter='^crate') == ['crate', 'crate_1']
    assert entities(filter='2d') == ['r2d2']  # a search: any part of the name
    robot = msg.EntityCategory(category=msg.EntityCategory.CATEGORY_ROBOT)
    assert entities(categories=[robot]) == ['r2d2']
    sphere = msg.Bounds(type=msg.Bounds.TYPE_SPHERE)
    sphere.points = [Point(x=3.0, y=0.0, z=0.1), Point(x=0.5)]  # centre, then radius in x
    assert entities(bounds=sphere, filter='crate') == ['crate_1']
    bad = srv.GetEntities.Request()
    bad.filters.filter = '(unclosed'
    assert code(standard('get_entities', srv.GetEntities, bad)) == \
        msg.Result.RESULT_OPERATION_FAILED
    info = standard('get_entity_info', srv.GetEntityInfo,
                    srv.GetEntityInfo.Request(entity='crate_1'))
    assert code(info) == OK
    assert info.info.category.category == msg.EntityCategory.CATEGORY_DYNAMIC_OBJECT
    every = standard('get_spawnables', srv.GetSpawnables, srv.GetSpawnables.Request())
    uris = [s.uri for s in every.spawnables]
    assert code(every) == OK and ROOM in uris and 'cube.urdf' in uris
    ours = standard('get_spawnables', srv.GetSpawnables,
                    srv.GetSpawnables.Request(sources=['package://r2d2_sim/urdf', 'elsewhere']))
    assert code(ours) == OK and 'elsewhere' in ours.result.error_message
    assert ROOM in [s.uri for s in ours.spawnables]
    assert all(s.uri.startswith('package://r2d2_sim/') for s in ours.spawnables)


def test_names_are_renamed_when_asked_and_spawning_is_bounded(r2d2_sim, standard):
    """allow_renaming gives box, box_1; past MAX_SPAWNED a spawn is refused."""
    names = [standard('spawn_entity', srv.SpawnEntity,
                      spawn_request(allow_renaming=True)).entity_name for _ in range(2)]
    assert names == ['box', 'box_1']
    for _ in range(MAX_SPAWNED - 2):
        assert code(standard('spawn_entity', srv.SpawnEntity,
                             spawn_request(allow_renaming=True))) == OK
    reply = standard('spawn_entity', srv.SpawnEntity, spawn_request(allow_renaming=True))
    assert code(reply) == msg.Result.RESULT_OPERATION_FAILED
    assert len(r2d2_sim.entities()) == 2 + MAX_SPAWNED


def test_states_and_steps_follow_the_standard(r2d2_sim, standard):
    """Same state: 101; STOPPED -> PAUSED: 103; unknown: 103; stepping while playing fails."""
    state = msg.SimulationState
    response = srv.SetSimulationState.Response

    def set_state(value):
        return code(standard('set_simulation_state', srv.SetSimulationState,
                             srv.SetSimulationState.Request(state=state(state=value))))

    def get_state():
        return standard('get_simulation_state', srv.GetSimulationState,
                        srv.GetSimulationState.Request()).state.state
    assert get_state() == state.STATE_PLAYING  # the harness's simulator was not paused
    assert set_state(state.STATE_PLAYING) == response.ALREADY_IN_TARGET_STATE
    before = r2d2_sim.sim.step_count
    assert code(standard('step_simulation', srv.StepSimulation,
                         srv.StepSimulation.Request(steps=10))) == \
        msg.Result.RESULT_OPERATION_FAILED
    assert r2d2_sim.sim.step_count == before  # no step taken
    assert set_state(state.STATE_STOPPED) == OK
    assert get_state() == state.STATE_STOPPED and r2d2_sim.sim.step_count == 0
    assert set_state(state.STATE_PAUSED) == response.INCORRECT_TRANSITION
    assert set_state(200) == response.INCORRECT_TRANSITION
    assert set_state(state.STATE_QUITTING) == msg.Result.RESULT_FEATURE_UNSUPPORTED
    assert code(standard('step_simulation', srv.StepSimulation,
                         srv.StepSimulation.Request(steps=24))) == OK
    assert get_state() == state.STATE_PAUSED and r2d2_sim.sim.step_count == 24


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


class FakeGoal:
    """What _simulate_steps uses of a ServerGoalHandle; a cancel requested after N feedbacks."""

    def __init__(self, steps, cancel_after=None):
        self.request = SimulateSteps.Goal(steps=steps)
        self.feedback, self.ended = [], None
        self._cancel_after = cancel_after

    @property
    def is_cancel_requested(self):
        return self._cancel_after is not None and len(self.feedback) >= self._cancel_after

    def publish_feedback(self, feedback):
        self.feedback.append((feedback.completed_steps, feedback.remaining_steps))

    def succeed(self):
        self.ended = 'succeeded'

    def canceled(self):
        self.ended = 'canceled'

    def abort(self):
        self.ended = 'aborted'


def test_the_action_sends_every_feedback_and_ends_as_it_should(r2d2_sim):
    """
    The action's server side, in process: feedback after each step, exactly; the ending.

    (A client cannot see all of it: rclpy's ActionClient drops feedback that arrives
    after the result.) A cancel after the last step is a success; a cancel mid-way ends
    it there; playing, it aborts without a step.
    """
    standard, sim = r2d2_sim.sim.standard, r2d2_sim.sim
    playing = FakeGoal(5)
    assert standard._simulate_steps(playing).result.result == msg.Result.RESULT_OPERATION_FAILED
    assert playing.ended == 'aborted' and not playing.feedback
    sim.set_paused(True)
    for goal, ended, done in ((FakeGoal(5), 'succeeded', 5),
                              (FakeGoal(5, cancel_after=5), 'succeeded', 5),
                              (FakeGoal(5, cancel_after=3), 'canceled', 3)):
        before = sim.step_count
        assert standard._simulate_steps(goal).result.result == OK
        assert goal.ended == ended and sim.step_count - before == done
        assert goal.feedback == [(i, 5 - i) for i in range(1, done + 1)]


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
