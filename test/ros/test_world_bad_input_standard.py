"""
Bad input through the standard's world and entity services: the code, one line, the world intact.

Issue 26's list, in process: a world file outside the allowed places, one
that does not parse, hostile ones (DOCTYPE, entity bomb, YAML aliases, huge),
an unknown named pose, a tag flood. Each reply carries the standard's code
and a message that quotes nothing of the file; the simulator keeps running
in the room it had, with its entities, named poses and state. A LoadWorld
during a step needs two threads: system/test_worlds_system.py.
"""

from geometry_msgs.msg import Twist
import pytest
from simulation_interfaces import msg, srv

from r2d2_sim.sim.tags import MAX_TAG_LENGTH, MAX_TAGS
from r2d2_sim.sim.worlds.manifest import MAX_WORLD_BYTES

ROOM = 'package://r2d2_sim/urdf/room.world.yaml'
MARK = 'SECRET_CONTENT_42'
LOAD = srv.LoadWorld.Response
BAD_LOADS = {
    'outside the allowed places': ({'uri': '/etc/passwd'}, msg.Result.RESULT_NOT_FOUND),
    'no such file': ({'uri': 'package://r2d2_sim/urdf/kitchen.world.yaml'},
                     msg.Result.RESULT_NOT_FOUND),
    'nothing': ({}, LOAD.NO_RESOURCE),
    'not YAML': ({'resource_string': f'r2d2_sim_world: 1\nname: [{MARK}\n'},
                 LOAD.RESOURCE_PARSE_ERROR),
    'not a world': ({'resource_string': f'{MARK}: 1\n'}, LOAD.UNSUPPORTED_FORMAT),
    'MJCF': ({'resource_string': f'<mujoco model="{MARK}"><worldbody/></mujoco>'},
             LOAD.UNSUPPORTED_FORMAT),
    'SDF of another version': ({'resource_string': f'<sdf version="1.2"><world name="{MARK}"/>'
                                                   '</sdf>'}, LOAD.UNSUPPORTED_FORMAT),
    'entity bomb': ({'resource_string': '<!DOCTYPE r [<!ENTITY a "' + MARK + '"><!ENTITY b '
                                        '"&a;&a;&a;&a;">]><robot name="b"><link name="&b;"/>'
                                        '</robot>'}, LOAD.RESOURCE_PARSE_ERROR),
    'YAML aliases': ({'resource_string': f'r2d2_sim_world: 1\nname: &n {MARK}\nx: [*n, *n]\n'},
                     LOAD.RESOURCE_PARSE_ERROR),
    'huge': ({'resource_string': 'r2d2_sim_world: 1\n#' + MARK * (MAX_WORLD_BYTES // 10)},
             LOAD.RESOURCE_PARSE_ERROR),
    'a tag flood': ({'resource_string': 'r2d2_sim_world: 1\ntags: [' + ','.join(
        f'{MARK}{i}' for i in range(MAX_TAGS + 1)) + ']\n'}, LOAD.RESOURCE_PARSE_ERROR),
    'a missing model': ({'resource_string': 'r2d2_sim_world: 1\nmodels: [{uri: nowhere.urdf}]\n'},
                        LOAD.MISSING_ASSETS),
    'a model outside': ({'resource_string': 'r2d2_sim_world: 1\nmodels: [{uri: /etc/x.urdf}]\n'},
                        LOAD.UNSUPPORTED_ASSETS),
    'an unsupported element': ({'resource_string': f'r2d2_sim_world: 1\n{MARK}: 1\n',
                                'fail_on_unsupported_element': True}, LOAD.UNSUPPORTED_ELEMENTS),
}


@pytest.fixture
def r2d2_sim_parameters():
    """Start in the room, commands held."""
    return {'cmd_vel_timeout': 0.0, 'world': ROOM}


def call(harness, name, request):
    """Call a standard service of the in-process simulator by its request."""
    srv_type = getattr(srv, type(request).__name__[:-len('_Request')])
    return harness.call_service(srv_type, '/' + name, request)


def world_now(harness):
    """Return what a client can see of the world: its name, entities, named poses, state."""
    current = call(harness, 'get_current_world', srv.GetCurrentWorld.Request()).world
    poses = call(harness, 'get_named_poses', srv.GetNamedPoses.Request()).poses
    state = call(harness, 'get_simulation_state', srv.GetSimulationState.Request()).state
    return (current.name, current.world_resource.uri, harness.entities(),
            [p.name for p in poses], state.state)


@pytest.mark.parametrize('fields, expected', BAD_LOADS.values(), ids=BAD_LOADS.keys())
def test_a_bad_load_is_refused_and_the_room_runs_on(r2d2_sim, fields, expected):
    r2d2_sim.send_cmd_vel(linear=0.3)
    r2d2_sim.advance(seconds=0.5)
    before = world_now(r2d2_sim)
    reply = call(r2d2_sim, 'load_world', srv.LoadWorld.Request(**fields))
    assert reply.result.result == expected, reply.result.error_message
    message = reply.result.error_message
    assert message and MARK not in message and '\n' not in message and len(message) < 600
    assert world_now(r2d2_sim) == before
    x = r2d2_sim.ground_truth().pose.pose.position.x
    r2d2_sim.advance(seconds=0.5)  # still running, still driving
    assert r2d2_sim.ground_truth().pose.pose.position.x > x + 0.1


def test_an_unknown_named_pose_is_not_found(r2d2_sim):
    reply = call(r2d2_sim, 'get_named_pose_bounds',
                 srv.GetNamedPoseBounds.Request(name='kitchen_door'))
    assert reply.result.result == msg.Result.RESULT_NOT_FOUND
    spawn = srv.SpawnEntity.Request(name='crate', uri='cube_small.urdf')
    spawn.initial_pose.header.frame_id = 'kitchen_door'
    spawn.initial_pose.pose.orientation.w = 1.0
    assert call(r2d2_sim, 'spawn_entity', spawn).result.result == \
        srv.SpawnEntity.Response.INVALID_POSE
    assert 'crate' not in r2d2_sim.entities()


@pytest.mark.parametrize('tags', [
    [f't{i}' for i in range(MAX_TAGS + 1)], ['x' * (MAX_TAG_LENGTH + 1)]],
    ids=['too many', 'too long'])
def test_a_tag_flood_is_refused_in_info_and_in_filters(r2d2_sim, tags):
    flood = srv.SetEntityInfo.Request(entity='room')
    flood.info.category.category = msg.EntityCategory.CATEGORY_STATIC_OBJECT
    flood.info.tags = tags
    assert call(r2d2_sim, 'set_entity_info', flood).result.result == \
        msg.Result.RESULT_OPERATION_FAILED
    info = call(r2d2_sim, 'get_entity_info', srv.GetEntityInfo.Request(entity='room')).info
    assert info.tags == ['walls', 'static']
    for name, request in (('get_entities', srv.GetEntities.Request()),
                          ('get_entities_states', srv.GetEntitiesStates.Request())):
        request.filters.tags.tags = tags
        assert call(r2d2_sim, name, request).result.result == msg.Result.RESULT_OPERATION_FAILED
    poses = srv.GetNamedPoses.Request()
    poses.tags.tags = tags
    assert call(r2d2_sim, 'get_named_poses', poses).result.result == \
        msg.Result.RESULT_OPERATION_FAILED
    worlds = srv.GetAvailableWorlds.Request()
    worlds.filter.tags = tags
    assert call(r2d2_sim, 'get_available_worlds', worlds).result.result == \
        msg.Result.RESULT_OPERATION_FAILED


def test_a_peer_cannot_list_a_directory_outside(r2d2_sim):
    request = srv.GetAvailableWorlds.Request(additional_sources=['/etc', 'file:///root'])
    reply = call(r2d2_sim, 'get_available_worlds', request)
    assert reply.result.result == msg.Result.RESULT_NOT_FOUND and not reply.worlds


def test_cmd_vel_still_reaches_the_robot_after_the_refusals(r2d2_sim):
    for fields, _ in BAD_LOADS.values():
        call(r2d2_sim, 'load_world', srv.LoadWorld.Request(**fields))
    twist = Twist()
    twist.angular.z = 0.5
    r2d2_sim.send_cmd_vel(twist=twist)
    r2d2_sim.advance(seconds=0.5)
    assert r2d2_sim.ground_truth().twist.twist.angular.z > 0.2
