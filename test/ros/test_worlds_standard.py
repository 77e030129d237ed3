"""
The standard's world, named pose, entity info and bounds services, in process.

Each reply's result code and fields as the Jazzy 1.5.1 text defines them:
LoadWorld leaves the simulation STOPPED (time 0 on /clock); after
UnloadWorld it is NO_WORLD, "inactive and cannot be started, stopped, or
paused", until a world is loaded; named poses are listed by tags and are
frames a spawn can be given in; tags filter entities (ANY/ALL); the box and
convex hull filters pick by shape.
"""

import math

from geometry_msgs.msg import Vector3
import pytest
from rosgraph_msgs.msg import Clock
from simulation_interfaces import msg, srv
from std_srvs.srv import SetBool, Trigger

from r2d2_sim.client import stamp_ns, wait_for

ROOM = 'package://r2d2_sim/urdf/room.world.yaml'
OK = msg.Result.RESULT_OK
STATE = msg.SimulationState
CRATE = ('<robot name="crate"><link name="crate"><collision><geometry><box size="0.2 0.2 0.2"/>'
         '</geometry></collision></link></robot>')


@pytest.fixture
def r2d2_sim_parameters():
    """Start in the room, playing, commands held."""
    return {'cmd_vel_timeout': 0.0, 'world': ROOM, 'tags': ['astromech']}


@pytest.fixture
def call(r2d2_sim):
    """Provide a function that calls a standard service by its name and request, in process."""
    def call(name, request):
        srv_type = getattr(srv, type(request).__name__[:-len('_Request')])  # GetEntities...
        return r2d2_sim.call_service(srv_type, '/' + name, request)
    return call


def code(response):
    """Return a reply's result code."""
    return response.result.result


def state(call):
    """Return the simulation state now."""
    return call('get_simulation_state', srv.GetSimulationState.Request()).state.state


def set_state(call, value):
    """Ask for a state; return the result code."""
    return code(call('set_simulation_state', srv.SetSimulationState.Request(
        state=msg.SimulationState(state=value))))


def test_available_worlds_lists_the_package_worlds_by_tags(call):
    every = call('get_available_worlds', srv.GetAvailableWorlds.Request())
    assert code(every) == OK
    names = {w.name: w for w in every.worlds}
    assert {'empty', 'room', 'samurai'} <= set(names)
    assert names['room'].world_resource.uri == ROOM and 'indoor' in names['room'].tags
    request = srv.GetAvailableWorlds.Request()
    request.filter.tags = ['indoor', 'outdoor']
    assert [w.name for w in call('get_available_worlds', request).worlds] == ['room', 'samurai']
    request.filter.filter_mode = msg.TagsFilter.FILTER_MODE_ALL
    assert code(call('get_available_worlds', request)) == OK
    assert call('get_available_worlds', request).worlds == []
    request.filter.filter_mode = 9
    assert code(call('get_available_worlds', request)) == msg.Result.RESULT_OPERATION_FAILED
    outside = srv.GetAvailableWorlds.Request(additional_sources=['/etc'])
    assert code(call('get_available_worlds', outside)) == msg.Result.RESULT_NOT_FOUND
    outside.continue_on_error = True
    reply = call('get_available_worlds', outside)
    assert code(reply) == OK and '/etc' in reply.result.error_message


def test_load_world_stops_at_time_zero_and_tells_the_world(r2d2_sim, call):
    clock = []
    r2d2_sim.create_node('clock_watcher').create_subscription(Clock, '/clock', clock.append, 10)
    r2d2_sim.spawn(CRATE, name='crate', position=(1.0, -1.0, 0.1))
    r2d2_sim.advance(seconds=0.5)
    assert state(call) == STATE.STATE_PLAYING
    empty = 'package://r2d2_sim/urdf/empty.world.yaml'
    reply = call('load_world', srv.LoadWorld.Request(uri=empty))
    assert code(reply) == OK, reply.result.error_message
    assert (reply.world.name, reply.world.world_resource.uri) == ('empty', empty)
    assert reply.world.tags == ['empty']
    assert state(call) == STATE.STATE_STOPPED and r2d2_sim.sim.step_count == 0
    assert wait_for(lambda: clock and stamp_ns(clock[-1].clock) == 0)
    assert r2d2_sim.entities() == ['ground_plane', 'r2d2']  # the crate and the room left
    current = call('get_current_world', srv.GetCurrentWorld.Request())
    assert code(current) == OK and current.world.name == 'empty'
    assert set_state(call, STATE.STATE_PLAYING) == OK  # a stopped world plays


def test_a_world_given_as_text_is_told_back_as_text(call):
    text = ('r2d2_sim_world: 1\nname: yard\ntags: [outdoor]\nnamed_poses:\n'
            '  - {name: gate, position: [2, 0, 0], tags: [entry]}\n')
    reply = call('load_world', srv.LoadWorld.Request(resource_string=text))
    assert code(reply) == OK and reply.world.name == 'yard'
    current = call('get_current_world', srv.GetCurrentWorld.Request()).world
    assert (current.world_resource.uri, current.world_resource.resource_string) == ('', text)


def test_no_world_is_inactive_until_a_world_is_loaded(r2d2_sim, call):
    assert code(call('unload_world', srv.UnloadWorld.Request())) == OK
    assert state(call) == STATE.STATE_NO_WORLD
    assert r2d2_sim.entities() == ['ground_plane', 'r2d2']
    for wanted in (STATE.STATE_PLAYING, STATE.STATE_PAUSED, STATE.STATE_STOPPED):
        assert set_state(call, wanted) == srv.SetSimulationState.Response.INCORRECT_TRANSITION
    assert set_state(call, STATE.STATE_NO_WORLD) == \
        srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    assert code(call('step_simulation', srv.StepSimulation.Request(steps=1))) == \
        msg.Result.RESULT_OPERATION_FAILED
    assert code(call('reset_simulation', srv.ResetSimulation.Request())) == \
        msg.Result.RESULT_INCORRECT_STATE
    assert code(call('unload_world', srv.UnloadWorld.Request())) == \
        srv.UnloadWorld.Response.NO_WORLD_LOADED
    assert code(call('get_current_world', srv.GetCurrentWorld.Request())) == \
        srv.GetCurrentWorld.Response.NO_WORLD_LOADED
    node = r2d2_sim.sim.get_fully_qualified_name()
    play = r2d2_sim.call_service(SetBool, node + '/pause', SetBool.Request(data=False))
    step = r2d2_sim.call_service(Trigger, node + '/step', Trigger.Request())
    assert not play.success and not step.success and 'no world is loaded' in step.message
    assert r2d2_sim.sim.step_count == 0 and r2d2_sim.sim.paused
    assert code(call('load_world', srv.LoadWorld.Request(uri=ROOM))) == OK
    assert state(call) == STATE.STATE_STOPPED
    assert code(call('step_simulation', srv.StepSimulation.Request(steps=3))) == OK
    assert state(call) == STATE.STATE_PAUSED and r2d2_sim.sim.step_count == 3


def test_setting_no_world_or_loading_world_is_an_incorrect_transition(call):
    for wanted in (STATE.STATE_NO_WORLD, STATE.STATE_LOADING_WORLD):
        assert set_state(call, wanted) == srv.SetSimulationState.Response.INCORRECT_TRANSITION


def test_loading_world_is_the_state_while_a_world_loads(r2d2_sim, call):
    """What a second thread sees mid-load (sim_node has two): LOADING_WORLD, no step, no state."""
    activity = r2d2_sim.sim.standard.activity
    activity.stepping.acquire()
    activity.loading.set()
    try:
        assert state(call) == STATE.STATE_LOADING_WORLD
        assert set_state(call, STATE.STATE_PAUSED) == \
            srv.SetSimulationState.Response.INCORRECT_TRANSITION
        reply = call('step_simulation', srv.StepSimulation.Request(steps=1))
        assert code(reply) == msg.Result.RESULT_OPERATION_FAILED
        assert 'loading' in reply.result.error_message
        again = call('load_world', srv.LoadWorld.Request(uri=ROOM))
        assert code(again) == msg.Result.RESULT_INCORRECT_STATE
    finally:
        activity.loading.clear()
        activity.stepping.release()
    assert state(call) == STATE.STATE_PLAYING


def test_named_poses_by_tags_their_bounds_and_as_frames(call):
    request = srv.GetNamedPoses.Request()
    request.tags.tags = ['corner']
    reply = call('get_named_poses', request)
    assert code(reply) == OK
    assert [p.name for p in reply.poses] == ['corner_ne', 'corner_nw', 'corner_sw', 'corner_se']
    ne = reply.poses[0]
    assert (ne.pose.position.x, ne.pose.position.y) == (1.5, 2.0)
    assert 2 * math.atan2(ne.pose.orientation.z, ne.pose.orientation.w) == pytest.approx(
        -3 * math.pi / 4)
    every = call('get_named_poses', srv.GetNamedPoses.Request())
    assert len(every.poses) == 8 and every.poses[0].name == 'start'
    bounds = call('get_named_pose_bounds', srv.GetNamedPoseBounds.Request(name='spawn_area'))
    assert code(bounds) == OK and bounds.bounds.type == msg.Bounds.TYPE_BOX
    assert [(p.x, p.y, p.z) for p in bounds.bounds.points] == [(0.7, 0.6, 1.0), (-0.7, -0.6, 0.0)]
    none = call('get_named_pose_bounds', srv.GetNamedPoseBounds.Request(name='goal'))
    assert code(none) == OK and none.bounds.type == msg.Bounds.TYPE_EMPTY
    missing = call('get_named_pose_bounds', srv.GetNamedPoseBounds.Request(name='kitchen_door'))
    assert code(missing) == msg.Result.RESULT_NOT_FOUND
    assert 'kitchen_door' in missing.result.error_message
    spawn = srv.SpawnEntity.Request(name='crate', resource_string=CRATE)
    spawn.initial_pose.header.frame_id = 'goal'  # a named pose as the frame: 0.1 m up
    spawn.initial_pose.pose.position.z = 0.1
    spawn.initial_pose.pose.orientation.w = 1.0
    assert code(call('spawn_entity', spawn)) == OK
    placed = call('get_entity_state', srv.GetEntityState.Request(entity='crate')).state.pose
    assert (placed.position.x, placed.position.y, placed.position.z) == pytest.approx(
        (-2.0, 1.5, 0.1), abs=1e-6)


def test_entity_info_is_set_with_tags_and_filters_by_them(call):
    info = call('get_entity_info', srv.GetEntityInfo.Request(entity='r2d2')).info
    assert info.tags == ['astromech']
    assert info.category.category == msg.EntityCategory.CATEGORY_ROBOT
    room = call('get_entity_info', srv.GetEntityInfo.Request(entity='room')).info
    assert room.tags == ['walls', 'static']
    request = srv.SetEntityInfo.Request(entity='room')
    request.info.category.category = msg.EntityCategory.CATEGORY_STATIC_OBJECT
    request.info.description = 'the test room'
    request.info.tags = ['walls', 'test']
    assert code(call('set_entity_info', request)) == OK
    room = call('get_entity_info', srv.GetEntityInfo.Request(entity='room')).info
    assert (room.description, room.tags) == ('the test room', ['walls', 'test'])

    def entities(tags, mode=msg.TagsFilter.FILTER_MODE_ANY):
        query = srv.GetEntities.Request()
        query.filters.tags.tags, query.filters.tags.filter_mode = tags, mode
        reply = call('get_entities', query)
        assert code(reply) == OK, reply.result.error_message
        return list(reply.entities)
    assert entities(['test', 'astromech']) == ['r2d2', 'room']
    assert entities(['walls', 'test'], msg.TagsFilter.FILTER_MODE_ALL) == ['room']
    assert entities(['walls', 'astromech'], msg.TagsFilter.FILTER_MODE_ALL) == []
    states = srv.GetEntitiesStates.Request()
    states.filters.tags.tags = ['astromech']
    reply = call('get_entities_states', states)
    assert list(reply.entities) == ['r2d2'] and len(reply.states) == 1
    bad = srv.SetEntityInfo.Request(entity='room')
    bad.info.category.category = 3  # no such category
    assert code(call('set_entity_info', bad)) == msg.Result.RESULT_OPERATION_FAILED
    missing = srv.SetEntityInfo.Request(entity='kitchen')
    assert code(call('set_entity_info', missing)) == msg.Result.RESULT_NOT_FOUND
    relabel = srv.SetEntityInfo.Request(entity='r2d2')
    relabel.info.category.category = msg.EntityCategory.CATEGORY_HUMAN
    assert code(call('set_entity_info', relabel)) == OK
    robots = srv.GetEntities.Request()
    robots.filters.categories = [msg.EntityCategory(category=msg.EntityCategory.CATEGORY_HUMAN)]
    assert list(call('get_entities', robots).entities) == ['r2d2']


def test_entity_bounds_and_the_box_and_hull_filters(call):
    bounds = call('get_entity_bounds', srv.GetEntityBounds.Request(entity='room'))
    assert code(bounds) == OK and bounds.bounds.type == msg.Bounds.TYPE_BOX
    upper, lower = bounds.bounds.points
    assert (upper.x, upper.y, upper.z, lower.x, lower.y, lower.z) == pytest.approx(
        (2.1, 2.6, 1.0, -3.1, -2.6, 0.0))
    missing = call('get_entity_bounds', srv.GetEntityBounds.Request(entity='kitchen'))
    assert code(missing) == msg.Result.RESULT_NOT_FOUND

    def entities(kind, points):
        query = srv.GetEntities.Request()
        query.filters.bounds.type = kind
        query.filters.bounds.points = [Vector3(x=float(x), y=float(y), z=float(z))
                                       for x, y, z in points]
        reply = call('get_entities', query)
        return code(reply), list(reply.entities)
    # Above the floor (z 0.5 .. 0.9), near the robot's head: the robot only.
    assert entities(msg.Bounds.TYPE_BOX, [(0.3, 0.3, 0.9), (-0.3, -0.3, 0.5)]) == (OK, ['r2d2'])
    # A triangle standing at the wall x = 2.05, off the floor: the room only.
    hull = [(1.9, -0.5, 0.3), (1.9, 0.5, 0.3), (1.95, 0.0, 0.8)]
    assert entities(msg.Bounds.TYPE_CONVEX_HULL, hull) == (OK, [])
    hull = [(1.9, -0.5, 0.3), (1.9, 0.5, 0.3), (2.05, 0.0, 0.8)]
    assert entities(msg.Bounds.TYPE_CONVEX_HULL, hull) == (OK, ['room'])
    assert entities(msg.Bounds.TYPE_CONVEX_HULL, hull[:2])[0] == \
        msg.Result.RESULT_OPERATION_FAILED  # two points are no hull
    assert entities(7, [])[0] == msg.Result.RESULT_FEATURE_UNSUPPORTED


def test_sources_that_fail_have_the_standards_codes(r2d2_sim_factory, tmp_path):
    broken = tmp_path / 'broken'
    broken.mkdir()
    (broken / 'bad.world.yaml').write_text('r2d2_sim_world: 1\nname: [unclosed\n')
    sim = r2d2_sim_factory(world_paths=[str(broken)])
    reply = sim.call_service(srv.GetAvailableWorlds, '/get_available_worlds',
                             srv.GetAvailableWorlds.Request())
    assert code(reply) == srv.GetAvailableWorlds.Response.DEFAULT_SOURCES_FAILED
    assert 'bad.world.yaml' in reply.result.error_message and not reply.worlds
    request = srv.GetAvailableWorlds.Request(continue_on_error=True)
    reply = sim.call_service(srv.GetAvailableWorlds, '/get_available_worlds', request)
    assert code(reply) == OK and 'room' in [w.name for w in reply.worlds]
    other = r2d2_sim_factory()
    request = srv.GetAvailableWorlds.Request(additional_sources=[str(broken)])
    reply = other.call_service(srv.GetAvailableWorlds, '/get_available_worlds', request)
    assert code(reply) == msg.Result.RESULT_NOT_FOUND  # outside the allowed places
    inside = r2d2_sim_factory(world_paths=[str(tmp_path)])  # broken/ is within an allowed place
    reply = inside.call_service(srv.GetAvailableWorlds, '/get_available_worlds', request)
    assert code(reply) == msg.Result.RESULT_OPERATION_FAILED  # a world file there does not read
    assert reply.result.error_message.startswith(f'{broken}/bad.world.yaml: ')  # not a defect
