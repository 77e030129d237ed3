"""
ROS 2's simulation standard (simulation_interfaces, Jazzy 1.x) on the simulator node.

Each result code, in process, and the action's server side. A client in
another process that knows only the standard driving sim_node through the
whole sequence of a test that changes its world, and what a long step leaves
answered, are system/test_sim_interfaces_system.py's.
"""

import math
import os

from geometry_msgs.msg import Accel, Point
import pybullet_data
import pytest
from simulation_interfaces import msg, srv

from common import BOX, FakeGoal
from r2d2_sim.physics.description import resolve_description_path
from r2d2_sim.sim.entities import MAX_SPAWNED
from r2d2_sim.sim.spawnables import MAX_LINKS

ROOM = 'package://r2d2_sim/urdf/room.urdf'
OK = msg.Result.RESULT_OK


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
                     msg.Result.RESULT_NOT_FOUND),
    'nothing to spawn': ({'resource_string': ''}, srv.SpawnEntity.Response.NO_RESOURCE),
    'not a URDF file': ({'resource_string': '', 'uri': '/etc/passwd'},
                        srv.SpawnEntity.Response.UNSUPPORTED_FORMAT),
    'not a robot': ({'resource_string': '<mujoco model="m"/>'},
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


INVALID_POSE = srv.SetEntityState.Response.INVALID_POSE


@pytest.mark.parametrize('entity, acceleration, expected', [
    ('ground_plane', (0.0, 0.0, 5.0, 0.0, 0.0, 0.0), msg.Result.RESULT_OPERATION_FAILED),
    ('ground_plane', (0.0, 0.0, 0.0, 0.0, 0.0, -0.5), msg.Result.RESULT_OPERATION_FAILED),
    ('ground_plane', (0.0, 0.0, math.nan, 0.0, 0.0, 0.0), INVALID_POSE),
    ('box', (0.0, math.inf, 0.0, 0.0, 0.0, 0.0), INVALID_POSE),
    ('box', (0.0, 0.0, 0.0, math.nan, 0.0, 0.0), INVALID_POSE),
    ('box', (0.0, 0.0, 5.0, 0.0, 0.0, 1.0), OK),  # checked, not applied: the physics' own
])
def test_an_acceleration_is_checked_as_a_twist_is(standard, entity, acceleration, expected):
    """Static and not zero: OPERATION_FAILED (SetEntityState.srv); not finite: INVALID_POSE."""
    assert code(standard('spawn_entity', srv.SpawnEntity, spawn_request())) == OK
    before = standard('get_entity_state', srv.GetEntityState,
                      srv.GetEntityState.Request(entity=entity)).state.pose
    place = srv.SetEntityState.Request(entity=entity)
    place.state.pose = before
    accel = place.state.acceleration
    (accel.linear.x, accel.linear.y, accel.linear.z,
     accel.angular.x, accel.angular.y, accel.angular.z) = acceleration
    reply = standard('set_entity_state', srv.SetEntityState, place)
    assert code(reply) == expected, reply.result.error_message
    if expected != OK:
        assert 'acceleration' in reply.result.error_message
    after = standard('get_entity_state', srv.GetEntityState,
                     srv.GetEntityState.Request(entity=entity)).state
    assert after.pose == before
    assert after.acceleration == Accel()  # reads 0: PyBullet gives none (docs)


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
    assert 'torus_deform.urdf' not in uris  # pybullet_data's, which a spawn refuses (no link)
    ours = standard('get_spawnables', srv.GetSpawnables,
                    srv.GetSpawnables.Request(sources=['package://r2d2_sim/urdf', 'elsewhere']))
    assert code(ours) == OK and 'elsewhere' in ours.result.error_message
    assert [s.uri for s in ours.spawnables] == uris  # sources add to what is listed


@pytest.mark.parametrize('allowed', [False, True])
def test_a_directory_source_adds_the_models_a_spawn_takes_from_it(r2d2_sim_factory, tmp_path,
                                                                  allowed):
    """
    A directory in GetSpawnables' sources adds its model files (they are additional).

    Its URDFs, which a spawn takes from anywhere; its SDF models only where SDF files
    may be read from (``world_paths`` here). Each listed one spawns; what a spawn
    refuses (a world, a URDF with no link) is not listed, nor a file twice.
    """
    (tmp_path / 'crate.urdf').write_text(BOX)
    (tmp_path / 'notes.txt').write_text('not a model')
    (tmp_path / 'cloth.urdf').write_text('<robot name="cloth"/>')  # as torus_deform.urdf
    (tmp_path / 'yard.sdf').write_text(
        '<sdf version="1.9"><world name="yard"><model name="m"><static>true</static>'
        '<link name="l"/></model></world></sdf>')
    (tmp_path / 'pillar.sdf').write_text(
        '<sdf version="1.9"><model name="pillar"><static>true</static><link name="l">'
        '<collision name="c"><geometry><box><size>0.2 0.2 1</size></box></geometry>'
        '</collision></link></model></sdf>')
    sim = r2d2_sim_factory(**({'world_paths': [str(tmp_path)]} if allowed else {}))

    def call(name, srv_type, request):
        return sim.call_service(srv_type, '/' + name, request)
    every = [s.uri for s in call('get_spawnables', srv.GetSpawnables,
                                 srv.GetSpawnables.Request()).spawnables]
    reply = call('get_spawnables', srv.GetSpawnables,
                 srv.GetSpawnables.Request(sources=[f'file://{tmp_path}/', str(tmp_path)]))
    added = [s.uri for s in reply.spawnables][len(every):]
    assert code(reply) == OK and reply.result.error_message == ''
    sdf = [str(tmp_path / 'pillar.sdf')] if allowed else []
    assert added == [str(tmp_path / 'crate.urdf')] + sdf
    for index, uri in enumerate(added):
        request = spawn_request(name=f'listed_{index}', resource_string='', uri=uri)
        request.initial_pose.pose.position.y = 2.0 + index
        assert code(call('spawn_entity', srv.SpawnEntity, request)) == OK


def test_a_directory_source_lists_nothing_listed_already(standard):
    """pybullet_data's own directory: its URDFs are listed by their short names, not again."""
    every = standard('get_spawnables', srv.GetSpawnables, srv.GetSpawnables.Request())
    reply = standard('get_spawnables', srv.GetSpawnables,
                     srv.GetSpawnables.Request(sources=[pybullet_data.getDataPath()]))
    assert code(reply) == OK and reply.result.error_message == ''
    paths = [os.path.realpath(resolve_description_path(s.uri)) for s in reply.spawnables]
    assert len(paths) == len(set(paths)) and len(paths) >= len(every.spawnables) > 30


def apart(number):
    """Return a spawn request for box number ``number``: a grid 0.5 m apart, not a pile."""
    request = spawn_request(allow_renaming=True)
    request.initial_pose.pose.position.x = 1.0 + 0.5 * (number % 10)
    request.initial_pose.pose.position.y = 0.5 * (number // 10)
    return request


def test_names_are_renamed_when_asked_and_spawning_is_bounded(r2d2_sim, standard):
    """allow_renaming gives box, box_1; past MAX_SPAWNED a spawn is refused."""
    names = [standard('spawn_entity', srv.SpawnEntity, apart(i)).entity_name for i in range(2)]
    assert names == ['box', 'box_1']
    for i in range(2, MAX_SPAWNED):
        assert code(standard('spawn_entity', srv.SpawnEntity, apart(i))) == OK
    reply = standard('spawn_entity', srv.SpawnEntity, apart(MAX_SPAWNED))
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
