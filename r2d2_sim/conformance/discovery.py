"""
Finding a simulator's services and action by type, as a generic client does.

Names are free in the standard: Gazebo serves ``/gzserver/step_simulation``,
O3DE and Isaac Sim 6 ``/step_simulation``, Isaac Sim 5 ``/isaacsim/StepSimulation``.
So, as RobotecAI's RViz panel does, the kit lists the ROS graph's services
(``get_service_names_and_types``) and keeps those whose type is one of
``simulation_interfaces``' right in the namespace it was given (the root's
own level by default: a simulator in another namespace is another user's,
named but never taken); the action is the ``<name>/_action/send_goal``
service of type ``SimulateSteps_SendGoal``. Also here: which feature stands
for which interface. No ROS imports.
"""

from typing import Any, Dict, Iterable, List, Sequence, Tuple

__all__ = ['SERVICES', 'ACTION', 'FEATURES', 'FEATURE_INTERFACES', 'SUB_FEATURES',
           'find_interfaces', 'simulator_levels', 'at_prefix', 'namespace_of', 'normal_prefix']

PACKAGE = 'simulation_interfaces'
# The 22 services of Jazzy 1.5.1, in the order of the definition files' topics.
SERVICES = (
    'GetSimulatorFeatures', 'GetSimulationState', 'SetSimulationState', 'StepSimulation',
    'ResetSimulation', 'GetEntities', 'GetEntitiesStates', 'GetEntityState', 'SetEntityState',
    'GetEntityInfo', 'SetEntityInfo', 'GetEntityBounds', 'SpawnEntity', 'SpawnEntities',
    'DeleteEntity', 'GetSpawnables', 'GetNamedPoses', 'GetNamedPoseBounds', 'LoadWorld',
    'UnloadWorld', 'GetCurrentWorld', 'GetAvailableWorlds')
ACTION = 'SimulateSteps'
# SimulatorFeatures' constants, by name (values from the message at run time).
FEATURES = (
    'SPAWNING', 'DELETING', 'NAMED_POSES', 'POSE_BOUNDS', 'ENTITY_TAGS', 'ENTITY_BOUNDS',
    'ENTITY_BOUNDS_BOX', 'ENTITY_BOUNDS_CONVEX', 'ENTITY_CATEGORIES', 'SPAWNING_RESOURCE_STRING',
    'ENTITY_STATE_GETTING', 'ENTITY_STATE_SETTING', 'ENTITY_INFO_GETTING', 'ENTITY_INFO_SETTING',
    'SPAWNABLES', 'SIMULATION_RESET', 'SIMULATION_RESET_TIME', 'SIMULATION_RESET_STATE',
    'SIMULATION_RESET_SPAWNED', 'SIMULATION_STATE_GETTING', 'SIMULATION_STATE_SETTING',
    'SIMULATION_STATE_PAUSE', 'STEP_SIMULATION_SINGLE', 'STEP_SIMULATION_MULTIPLE',
    'STEP_SIMULATION_ACTION', 'WORLD_LOADING', 'WORLD_RESOURCE_STRING', 'WORLD_TAGS',
    'WORLD_UNLOADING', 'WORLD_INFO_GETTING', 'AVAILABLE_WORLDS', 'SPAWNING_ENTITIES')
# The interfaces whose support a feature declares ("Support for this interface is
# indicated through the ... value"); any one of a tuple's will do.
FEATURE_INTERFACES: Dict[str, Tuple[str, ...]] = {
    'SPAWNING': ('SpawnEntity',), 'DELETING': ('DeleteEntity',),
    'NAMED_POSES': ('GetNamedPoses',), 'POSE_BOUNDS': ('GetNamedPoseBounds',),
    'ENTITY_BOUNDS': ('GetEntityBounds',),
    'ENTITY_STATE_GETTING': ('GetEntityState', 'GetEntitiesStates'),
    'ENTITY_STATE_SETTING': ('SetEntityState',), 'ENTITY_INFO_GETTING': ('GetEntityInfo',),
    'ENTITY_INFO_SETTING': ('SetEntityInfo',), 'SPAWNABLES': ('GetSpawnables',),
    'SIMULATION_RESET': ('ResetSimulation',),
    'SIMULATION_STATE_GETTING': ('GetSimulationState',),
    'SIMULATION_STATE_SETTING': ('SetSimulationState',),
    'STEP_SIMULATION_SINGLE': ('StepSimulation',),
    'STEP_SIMULATION_MULTIPLE': ('StepSimulation|SimulateSteps',),
    'STEP_SIMULATION_ACTION': ('SimulateSteps',),
    'WORLD_LOADING': ('LoadWorld',), 'WORLD_UNLOADING': ('UnloadWorld',),
    'WORLD_INFO_GETTING': ('GetCurrentWorld',), 'AVAILABLE_WORLDS': ('GetAvailableWorlds',),
    'SPAWNING_ENTITIES': ('SpawnEntities',),
}
# A feature about a part of an interface, and the features one of which that interface needs.
SUB_FEATURES: Dict[str, Tuple[str, ...]] = {
    'SIMULATION_RESET_TIME': ('SIMULATION_RESET',),
    'SIMULATION_RESET_STATE': ('SIMULATION_RESET',),
    'SIMULATION_RESET_SPAWNED': ('SIMULATION_RESET',),
    'SIMULATION_STATE_PAUSE': ('SIMULATION_STATE_SETTING',),
    'SPAWNING_RESOURCE_STRING': ('SPAWNING', 'SPAWNING_ENTITIES'),
    'WORLD_RESOURCE_STRING': ('WORLD_LOADING',),
    'WORLD_TAGS': ('AVAILABLE_WORLDS',),
}
_SEND_GOAL = '/_action/send_goal'


def __getattr__(name: str) -> Any:
    # snake_case is the standard client's usual_name: one rule, loaded with rclpy only when used,
    # so that the clause table reads without it.
    if name == 'snake_case':
        from r2d2_sim.testing.standard import usual_name
        return usual_name
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


def normal_prefix(prefix: str) -> str:
    """Return a prefix as a namespace: '' and '/' are the root '/', others lose a trailing '/'."""
    prefix = '/' + prefix.strip('/')
    return prefix


def namespace_of(name: str) -> str:
    """Return the namespace a fully qualified name is in: '/gz/spawn' -> '/gz', '/spawn' -> '/'."""
    return normal_prefix(name.rsplit('/', 1)[0])


def at_prefix(name: str, prefix: str) -> bool:
    """Return True for a fully qualified name right in the namespace ``prefix``, not below it."""
    return namespace_of(name) == normal_prefix(prefix)


def _preferred(candidates: Sequence[str], prefix: str, kind: str) -> str:
    """Pick one name: ``<prefix>/<usual name>`` if there, else the first in order."""
    from r2d2_sim.testing.standard import usual_name
    usual = normal_prefix(prefix).rstrip('/') + '/' + usual_name(kind)
    return usual if usual in candidates else sorted(candidates)[0]


def _standard_names(names_and_types: Iterable[Tuple[str, List[str]]]
                    ) -> Iterable[Tuple[str, str]]:
    """Yield (interface, name) for each service of the standard's types, the action by its name."""
    for name, types in names_and_types:
        for type_name in types:
            package, _, rest = type_name.partition('/')
            if package != PACKAGE:
                continue
            kind, _, short = rest.partition('/')
            if kind == 'srv' and short in SERVICES:
                yield short, name
            elif (kind == 'action' and short == f'{ACTION}_SendGoal'
                  and name.endswith(_SEND_GOAL)):
                yield ACTION, name[:-len(_SEND_GOAL)]


def simulator_levels(names_and_types: Iterable[Tuple[str, List[str]]]) -> List[str]:
    """Return the namespaces that serve GetSimulatorFeatures: a simulator in each, sorted."""
    return sorted({namespace_of(name) for kind, name in _standard_names(names_and_types)
                   if kind == 'GetSimulatorFeatures'})


def find_interfaces(names_and_types: Iterable[Tuple[str, List[str]]], prefix: str
                    ) -> Tuple[Dict[str, str], Dict[str, List[str]]]:
    """
    Return ({interface: service or action name}, {interface: every candidate when several}).

    ``names_and_types`` is what ``Node.get_service_names_and_types()``
    returns. Each standard service right in the namespace ``prefix`` (not
    below it: ``/`` is the root's own level, and a simulator under
    ``/victim`` is only found with that prefix) is keyed by its type's name
    (``SpawnEntity``); the action by ``SimulateSteps``, named without
    ``/_action/send_goal``. Several names of one type there are two
    simulators: every one is named, and the usual name is kept, else the first.
    """
    found: Dict[str, List[str]] = {}
    for kind, name in _standard_names(names_and_types):
        if at_prefix(name, prefix):
            found.setdefault(kind, []).append(name)
    chosen = {kind: _preferred(names, prefix, kind) for kind, names in found.items()}
    several = {kind: sorted(names) for kind, names in found.items() if len(names) > 1}
    return chosen, several
