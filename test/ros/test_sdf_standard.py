"""
SDF through ROS 2's simulation standard and the testing API, in process.

The arena (``sdf_files.arena``: a Gazebo world with includes, a nested model
and DAE, STL and OBJ meshes) is listed by GetAvailableWorlds, loaded by
LoadWorld (what is not simulated in one line of its message, or refused with
``fail_on_unsupported_element``), and its models spawn by SpawnEntity from a
``model://`` URI or as SDF text; every bad SDF gets its standard code.
"""

import pytest
from simulation_interfaces import msg, srv

from sdf_files import arena, box_model, CRATE_SIZE_M, sdf

OK = msg.Result.RESULT_OK
SPAWN = srv.SpawnEntity.Response
LOAD = srv.LoadWorld.Response


@pytest.fixture
def arena_dir(tmp_path_factory):
    """Write the arena once per test (its own directory), with a model-only file beside it."""
    root = tmp_path_factory.mktemp('arena')
    arena(root)
    (root / 'lonely_box.sdf').write_text(sdf(box_model('lonely')))  # a model: not a world
    return root


@pytest.fixture
def r2d2_sim_parameters(arena_dir, monkeypatch):
    """Start in the empty world, the arena's directory a world path, its models on the path."""
    monkeypatch.setenv('R2D2_SIM_CACHE_DIR', str(arena_dir / 'cache'))
    return {'cmd_vel_timeout': 0.0, 'world_paths': [str(arena_dir)],
            'model_paths': [str(arena_dir / 'models')], 'scan_rate': 0.0}


@pytest.fixture
def call(r2d2_sim):
    """Provide a function that calls a standard service by its name and request, in process."""
    def call(name, request):
        srv_type = getattr(srv, type(request).__name__[:-len('_Request')])
        return r2d2_sim.call_service(srv_type, '/' + name, request)
    return call


def test_the_features_say_sdf_spawns(call):
    features = call('get_simulator_features', srv.GetSimulatorFeatures.Request()).features
    assert features.spawn_formats == ['urdf', 'sdf']
    assert 'sdf' in features.custom_info


def test_available_worlds_lists_the_sdf_world_and_not_a_model_file(call, arena_dir):
    reply = call('get_available_worlds', srv.GetAvailableWorlds.Request())
    assert reply.result.result == OK
    sdf_worlds = [w for w in reply.worlds if 'sdf' in w.tags]
    assert [(w.name, w.world_resource.uri) for w in sdf_worlds] == [
        ('arena', f'file://{arena_dir}/arena.sdf')]


def test_load_world_loads_the_gazebo_world_and_says_what_it_does_not_simulate(call, arena_dir):
    reply = call('load_world', srv.LoadWorld.Request(uri=f'file://{arena_dir}/arena.sdf'))
    assert reply.result.result == OK, reply.result.error_message
    assert reply.result.error_message == (
        'not simulated: physics max_step_size 0.001 s (r2d2_sim steps 0.00416667 s: '
        'physics_rate), plugin, light')
    entities = call('get_entities', srv.GetEntities.Request()).entities
    assert entities == ['ground_plane', 'r2d2', 'arena_wall', 'pillar', 'corner']
    current = call('get_current_world', srv.GetCurrentWorld.Request()).world
    assert current.name == 'arena' and 'not simulated: ' in current.description
    poses = call('get_named_poses', srv.GetNamedPoses.Request()).poses
    assert [p.name for p in poses] == ['start', 'goal']
    strict = call('load_world', srv.LoadWorld.Request(uri=f'file://{arena_dir}/arena.sdf',
                                                      fail_on_unsupported_element=True))
    assert strict.result.result == LOAD.UNSUPPORTED_ELEMENTS
    assert strict.result.error_message.endswith('not simulated: physics max_step_size 0.001 s '
                                                '(r2d2_sim steps 0.00416667 s: physics_rate), '
                                                'plugin, light')


BAD_LOADS = {
    'entities': (sdf('<world name="w"/>').replace(
        '<sdf', '<!DOCTYPE s [<!ENTITY e "x">]><sdf'), LOAD.RESOURCE_PARSE_ERROR),
    'a missing model': (sdf('<world name="w"><include><uri>model://gone</uri></include>'
                            '</world>'), LOAD.MISSING_ASSETS),
    'a remote model': (sdf('<world name="w"><include><uri>https://example.com/m</uri>'
                           '</include></world>'), LOAD.UNSUPPORTED_ASSETS),
    'a bad value': (sdf('<world name="w"><model name="m"><link name="l"><collision name="c">'
                        '<geometry><sphere><radius>-1</radius></sphere></geometry>'
                        '</collision></link></model></world>'), LOAD.RESOURCE_PARSE_ERROR),
}


@pytest.mark.parametrize('text, code', BAD_LOADS.values(), ids=BAD_LOADS.keys())
def test_a_bad_sdf_world_gets_its_code_and_one_line(call, text, code):
    reply = call('load_world', srv.LoadWorld.Request(resource_string=text))
    assert reply.result.result == code, reply.result.error_message
    assert '\n' not in reply.result.error_message and reply.result.error_message


def spawn(call, **fields):
    pose = fields.pop('position', (0.0, 0.0, 0.0))
    request = srv.SpawnEntity.Request(**fields)
    request.initial_pose.pose.position.x, request.initial_pose.pose.position.y, \
        request.initial_pose.pose.position.z = pose
    return call('spawn_entity', request)


def test_sdf_models_spawn_by_model_uri_and_as_text_and_come_to_rest(call, r2d2_sim):
    by_uri = spawn(call, name='crate', uri='model://crate', position=(1.5, 0.0, 0.5))
    assert by_uri.result.result == OK, by_uri.result.error_message
    text = spawn(call, resource_string=sdf(box_model('block', size=(0.2, 0.2, 0.2))),
                 position=(-1.5, 0.0, 0.5))
    assert (text.result.result, text.entity_name) == (OK, 'block')
    r2d2_sim.advance(seconds=2.0)
    states = call('get_entities_states', srv.GetEntitiesStates.Request())
    heights = {name: state.pose.position.z for name, state in
               zip(states.entities, states.states)}
    assert heights['crate'] == pytest.approx(CRATE_SIZE_M / 2.0, abs=0.003)
    assert heights['block'] == pytest.approx(0.1, abs=0.003)


BAD_SPAWNS = {
    'no such model': ({'uri': 'model://nothing_like_it'}, msg.Result.RESULT_NOT_FOUND),
    'a world': ({'resource_string': sdf('<world name="w"/>')}, SPAWN.UNSUPPORTED_FORMAT),
    'two models': ({'resource_string': sdf(box_model('a') + box_model('b'))},
                   SPAWN.UNSUPPORTED_FORMAT),
    'does not parse': ({'resource_string': '<sdf version="1.9"><model name="m">'},
                       SPAWN.RESOURCE_PARSE_ERROR),
    'a missing mesh': ({'resource_string': sdf(
        '<model name="m"><link name="l"><visual name="v"><geometry><mesh>'
        '<uri>model://crate/meshes/none.obj</uri></mesh></geometry></visual></link></model>')},
        SPAWN.MISSING_ASSETS),
    'links apart': ({'resource_string': sdf('<model name="m"><link name="a"/><link name="b"/>'
                                            '</model>')}, SPAWN.UNSUPPORTED_ASSETS),
}


@pytest.mark.parametrize('fields, code', BAD_SPAWNS.values(), ids=BAD_SPAWNS.keys())
def test_a_bad_sdf_spawn_gets_its_code_and_one_line(call, fields, code):
    reply = spawn(call, **fields)
    assert reply.result.result == code, reply.result.error_message
    assert '\n' not in reply.result.error_message and reply.result.error_message
    assert call('get_entities', srv.GetEntities.Request()).entities == ['ground_plane', 'r2d2']


def test_the_testing_api_loads_sdf_worlds_and_spawns_sdf_models(r2d2_sim, arena_dir):
    entry = r2d2_sim.load_world(str(arena_dir / 'arena.sdf'))
    assert (entry.name, entry.tags) == ('arena', ('sdf',))
    assert r2d2_sim.named_pose('goal').position[:2] == pytest.approx((0.4, 1.2))
    name = r2d2_sim.spawn(sdf(box_model('parcel', size=(0.2, 0.2, 0.2))), at='goal',
                          position=(0.0, 0.0, 0.5))
    r2d2_sim.advance(seconds=1.5)
    assert r2d2_sim.entity_state(name).position == pytest.approx((0.4, 1.2, 0.1), abs=0.005)
