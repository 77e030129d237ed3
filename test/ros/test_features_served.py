"""
The features GetSimulatorFeatures declares are exactly what is served, and each works.

For every feature of simulation_interfaces 1.5.1: the services (or the
action) it names are among those the simulator's standard node serves, and
a request that uses it is answered with something other than
FEATURE_UNSUPPORTED. The other way round, every standard service served
belongs to a declared feature (or is one of the two every simulator has:
GetSimulatorFeatures and GetEntities).
"""

from geometry_msgs.msg import Vector3
import pytest
from simulation_interfaces import msg, srv

ROOM = 'package://r2d2_sim/urdf/room.world.yaml'
FEATURES = msg.SimulatorFeatures
UNSUPPORTED = msg.Result.RESULT_FEATURE_UNSUPPORTED
CRATE = ('<robot name="crate"><link name="crate"><collision><geometry><box size="0.2 0.2 0.2"/>'
         '</geometry></collision></link></robot>')

# Each feature's services (action: its send_goal service), from SimulatorFeatures.msg's text.
SERVES = {
    'SPAWNING': ['spawn_entity'], 'DELETING': ['delete_entity'],
    'NAMED_POSES': ['get_named_poses'], 'POSE_BOUNDS': ['get_named_pose_bounds'],
    'ENTITY_TAGS': ['get_entities', 'get_entities_states'],
    'ENTITY_BOUNDS': ['get_entity_bounds'], 'ENTITY_BOUNDS_BOX': ['get_entities'],
    'ENTITY_BOUNDS_CONVEX': ['get_entities'], 'ENTITY_CATEGORIES': ['get_entities'],
    'SPAWNING_RESOURCE_STRING': ['spawn_entity'],
    'ENTITY_STATE_GETTING': ['get_entity_state', 'get_entities_states'],
    'ENTITY_STATE_SETTING': ['set_entity_state'], 'ENTITY_INFO_GETTING': ['get_entity_info'],
    'ENTITY_INFO_SETTING': ['set_entity_info'], 'SPAWNABLES': ['get_spawnables'],
    'SIMULATION_RESET': ['reset_simulation'], 'SIMULATION_RESET_TIME': ['reset_simulation'],
    'SIMULATION_RESET_STATE': ['reset_simulation'],
    'SIMULATION_RESET_SPAWNED': ['reset_simulation'],
    'SIMULATION_STATE_GETTING': ['get_simulation_state'],
    'SIMULATION_STATE_SETTING': ['set_simulation_state'],
    'SIMULATION_STATE_PAUSE': ['set_simulation_state'],
    'STEP_SIMULATION_SINGLE': ['step_simulation'],
    'STEP_SIMULATION_MULTIPLE': ['step_simulation', 'simulate_steps/_action/send_goal'],
    'STEP_SIMULATION_ACTION': ['simulate_steps/_action/send_goal'],
    'WORLD_LOADING': ['load_world'], 'WORLD_RESOURCE_STRING': ['load_world'],
    'WORLD_TAGS': ['get_available_worlds'], 'WORLD_UNLOADING': ['unload_world'],
    'WORLD_INFO_GETTING': ['get_current_world'], 'AVAILABLE_WORLDS': ['get_available_worlds'],
    'SPAWNING_ENTITIES': ['spawn_entities'],
}
EVERY_SIMULATOR = ['get_simulator_features', 'get_entities']


def feature_names():
    """Return the name of every feature constant of SimulatorFeatures."""
    return sorted(name for name in dir(FEATURES) if name.isupper() and not name.startswith('_')
                  and isinstance(getattr(FEATURES, name), int))


def box(low, high):
    """Return a Bounds message of the box from ``low`` to ``high`` (upper corner first)."""
    return msg.Bounds(type=msg.Bounds.TYPE_BOX, points=[Vector3(x=h[0], y=h[1], z=h[2])
                                                        for h in (high, low)])


def probes():
    """Return, per feature, a request that uses it: (service, request)."""
    filters = srv.GetEntities.Request()
    filters.filters.tags.tags = ['astromech']
    boxed = srv.GetEntities.Request()
    boxed.filters.bounds = box((-1.0, -1.0, 0.0), (1.0, 1.0, 1.0))
    hull = srv.GetEntities.Request()
    hull.filters.bounds = msg.Bounds(type=msg.Bounds.TYPE_CONVEX_HULL, points=[
        Vector3(x=0.0, y=0.0, z=0.5), Vector3(x=1.0, y=0.0, z=0.5), Vector3(x=0.0, y=1.0, z=0.5)])
    robots = srv.GetEntities.Request()
    robots.filters.categories = [msg.EntityCategory(category=msg.EntityCategory.CATEGORY_ROBOT)]
    spawn = srv.SpawnEntity.Request(name='crate', resource_string=CRATE)
    spawn.initial_pose.pose.position.x, spawn.initial_pose.pose.position.z = 1.0, 0.1
    spawn.initial_pose.pose.orientation.w = 1.0
    batch = srv.SpawnEntities.Request(spawn_requests=[msg.SpawnEntity(
        name='crate2', entity_resource=msg.Resource(uri='cube_small.urdf'))])
    batch.spawn_requests[0].initial_pose.pose.position.y = 1.0
    batch.spawn_requests[0].initial_pose.pose.orientation.w = 1.0
    info = srv.SetEntityInfo.Request(entity='r2d2')
    info.info.category.category = msg.EntityCategory.CATEGORY_ROBOT
    info.info.tags = ['astromech']
    tags = srv.GetAvailableWorlds.Request()
    tags.filter.tags = ['indoor']
    state = msg.SimulationState
    place = srv.SetEntityState.Request(entity='crate')
    place.state.pose.position.z, place.state.pose.orientation.w = 0.1, 1.0
    return [  # in an order that works: every probe leaves the next one a world to use
        ('SIMULATION_STATE_GETTING', 'get_simulation_state', srv.GetSimulationState.Request()),
        ('SIMULATION_STATE_SETTING', 'set_simulation_state',
         srv.SetSimulationState.Request(state=state(state=state.STATE_STOPPED))),
        ('STEP_SIMULATION_SINGLE', 'step_simulation', srv.StepSimulation.Request(steps=1)),
        ('STEP_SIMULATION_MULTIPLE', 'step_simulation', srv.StepSimulation.Request(steps=5)),
        ('SIMULATION_STATE_PAUSE', 'set_simulation_state',
         srv.SetSimulationState.Request(state=state(state=state.STATE_PLAYING))),
        ('SIMULATION_STATE_PAUSE', 'set_simulation_state',
         srv.SetSimulationState.Request(state=state(state=state.STATE_PAUSED))),
        ('ENTITY_INFO_SETTING', 'set_entity_info', info),
        ('ENTITY_TAGS', 'get_entities', filters),
        ('ENTITY_BOUNDS_BOX', 'get_entities', boxed),
        ('ENTITY_BOUNDS_CONVEX', 'get_entities', hull),
        ('ENTITY_CATEGORIES', 'get_entities', robots),
        ('ENTITY_INFO_GETTING', 'get_entity_info', srv.GetEntityInfo.Request(entity='r2d2')),
        ('ENTITY_BOUNDS', 'get_entity_bounds', srv.GetEntityBounds.Request(entity='r2d2')),
        ('ENTITY_STATE_GETTING', 'get_entity_state', srv.GetEntityState.Request(entity='r2d2')),
        ('SPAWNABLES', 'get_spawnables', srv.GetSpawnables.Request()),
        ('SPAWNING_RESOURCE_STRING', 'spawn_entity', spawn),
        ('SPAWNING_ENTITIES', 'spawn_entities', batch),
        ('ENTITY_STATE_SETTING', 'set_entity_state', place),
        ('DELETING', 'delete_entity', srv.DeleteEntity.Request(entity='crate2')),
        ('SIMULATION_RESET_STATE', 'reset_simulation', srv.ResetSimulation.Request(scope=2)),
        ('SIMULATION_RESET_SPAWNED', 'reset_simulation', srv.ResetSimulation.Request(scope=4)),
        ('SIMULATION_RESET_TIME', 'reset_simulation', srv.ResetSimulation.Request(scope=1)),
        ('SIMULATION_RESET', 'reset_simulation', srv.ResetSimulation.Request()),
        ('AVAILABLE_WORLDS', 'get_available_worlds', srv.GetAvailableWorlds.Request()),
        ('WORLD_TAGS', 'get_available_worlds', tags),
        ('WORLD_INFO_GETTING', 'get_current_world', srv.GetCurrentWorld.Request()),
        ('WORLD_UNLOADING', 'unload_world', srv.UnloadWorld.Request()),
        ('WORLD_RESOURCE_STRING', 'load_world', srv.LoadWorld.Request(
            resource_string='r2d2_sim_world: 1\nname: bare\n')),
        ('WORLD_LOADING', 'load_world', srv.LoadWorld.Request(uri=ROOM)),
        ('NAMED_POSES', 'get_named_poses', srv.GetNamedPoses.Request()),
        ('POSE_BOUNDS', 'get_named_pose_bounds',
         srv.GetNamedPoseBounds.Request(name='spawn_area')),
        ('SPAWNING', 'spawn_entity', srv.SpawnEntity.Request(name='cube', uri='cube_small.urdf')),
    ]


def served(harness):
    """Return the standard node's service names, relative to its namespace."""
    node = harness.sim.standard.node
    names = node.get_service_names_and_types_by_node(node.get_name(), node.get_namespace())
    prefix = node.get_namespace().rstrip('/') + '/'
    return {name[len(prefix):] for name, _ in names if name.startswith(prefix)}


def declared(harness):
    """Return the names of the features GetSimulatorFeatures declares."""
    reply = harness.call_service(srv.GetSimulatorFeatures, '/get_simulator_features',
                                 srv.GetSimulatorFeatures.Request())
    names = {getattr(FEATURES, name): name for name in feature_names()}
    return sorted(names[value] for value in reply.features.features)


@pytest.fixture
def r2d2_sim_parameters():
    """Start in the room."""
    return {'world': ROOM}


def test_all_32_features_are_declared(r2d2_sim):
    assert len(feature_names()) == 32
    assert declared(r2d2_sim) == feature_names()


def test_declared_features_are_served_and_served_services_are_declared(r2d2_sim):
    names = served(r2d2_sim)
    features = declared(r2d2_sim)
    missing = {feature: [s for s in SERVES[feature] if s not in names] for feature in features}
    assert {f: m for f, m in missing.items() if m} == {}
    standard = {name for name in names if not name.endswith(('/get_result', '/cancel_goal'))
                and not name.startswith('simulate_steps/_action/') or name.endswith('send_goal')}
    standard -= {'get_type_description'}
    covered = set(EVERY_SIMULATOR) | {s for f in features for s in SERVES[f]}
    assert standard - covered == set()


def test_every_declared_feature_is_answered_as_supported(r2d2_sim):
    probed = set()
    for feature, service, request in probes():
        srv_type = getattr(srv, type(request).__name__[:-len('_Request')])
        reply = r2d2_sim.call_service(srv_type, '/' + service, request)
        assert reply.result.result not in (UNSUPPORTED,), (feature, reply.result.error_message)
        assert reply.result.result == msg.Result.RESULT_OK, (feature, reply.result)
        probed.add(feature)
    assert probed == set(declared(r2d2_sim)) - {'STEP_SIMULATION_ACTION'}


def test_the_step_action_is_served_and_steps(r2d2_sim):
    standard, sim = r2d2_sim.sim.standard, r2d2_sim.sim
    sim.set_paused(True)
    before = sim.step_count

    class Goal:
        request = __import__('simulation_interfaces.action', fromlist=['x']).SimulateSteps.Goal(
            steps=3)
        is_cancel_requested = False

        def publish_feedback(self, feedback):
            pass

        def succeed(self):
            pass
    assert standard._simulate_steps(Goal()).result.result == msg.Result.RESULT_OK
    assert sim.step_count - before == 3
    assert 'simulate_steps/_action/send_goal' in served(r2d2_sim)
