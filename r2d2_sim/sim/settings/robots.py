"""
Several robots' parameters: each robot's settings are the world's, with its own on top.

No ROS here. ``robots`` lists robots by name; each may set any per-robot
parameter of the table (:mod:`r2d2_sim.sim.settings.table`) as ``NAME.parameter``
and its namespace as ``NAME.namespace``. :func:`parse_world` validates them
all into one :class:`RobotSpec` per robot, :func:`robot_config` makes the
settings of one robot (a spawned one too), and namespaces resolve as ROS
resolves a node's.
"""

from typing import Any, Dict, List, Mapping, NamedTuple, Optional, Tuple

from r2d2_sim.sim.settings import readers as read
from r2d2_sim.sim.settings.table import ConfigError, PARAMETERS, PARAMETERS_BY_NAME
from r2d2_sim.sim.settings.config import check_fields, parse_config, read_value, SimConfig

__all__ = ['RobotSpec', 'robot_config', 'parse_world', 'resolve_namespace', 'robot_namespaces']


class RobotSpec(NamedTuple):
    """One robot listed in ``robots``: its name, its namespace as given, its settings."""

    name: str
    namespace: str   # relative (under the simulator's namespace) or absolute
    config: 'SimConfig'


def robot_config(world: 'SimConfig', name: str,
                 overrides: Optional[Mapping[str, Any]] = None) -> 'SimConfig':
    """
    Return the settings of the robot ``name``: the world's, with its own ``overrides``.

    ``overrides`` are raw values of per-robot parameters by their table
    name (``initial_pose``...). With ``tf_layout`` shared, the robot's
    frames are prefixed with its name (after the world's ``frame_prefix``)
    unless it sets ``frame_prefix`` itself. ConfigError (one line, naming
    ``name.parameter``) for a value that is bad or not a robot's to set.
    """
    overrides = dict(overrides or {})
    fields = {spec.field: getattr(world, spec.field) for spec in PARAMETERS}
    for key, value in overrides.items():
        spec = PARAMETERS_BY_NAME.get(key)
        if spec is None:
            raise ConfigError(f'unknown parameter {name}.{key}')
        if not spec.per_robot:
            raise ConfigError(f'parameter {name}.{key}: {key} is the world\'s, one for all '
                              'robots (set it without the robot\'s name)')
        fields[spec.field] = read_value(spec, value, f'{name}.{key}')
    if 'frame_prefix' not in overrides and world.tf_layout == 'shared':
        fields['frame_prefix'] = f'{world.frame_prefix}{name}/'
    try:
        check_fields(fields)
    except ConfigError as exc:
        raise ConfigError(f'robot {name}: {exc}') from None
    return SimConfig(**fields)


def resolve_namespace(base: str, namespace: str) -> str:
    """Return ``namespace`` absolute: a relative one is under ``base`` (a node's namespace)."""
    if namespace.startswith('/'):
        return namespace
    return f'{base.rstrip("/")}/{namespace}'


def robot_namespaces(values: Mapping[str, Any], base: str) -> Dict[str, str]:
    """
    Return each listed robot's namespace, resolved under ``base``, from raw parameter values.

    Empty without ``robots`` (the one default robot is in ``base`` itself).
    For clients that need the topics before the simulator runs (the harnesses).
    ConfigError, the line :func:`parse_world` would give, for a namespace
    that is not one.
    """
    names = values.get('robots') or []
    return {name: resolve_namespace(base, read.namespace(
        f'{name}.namespace', values.get(f'{name}.namespace', '')) or name) for name in names}


def parse_world(values: Mapping[str, Any]) -> Tuple['SimConfig', List[RobotSpec]]:
    """
    Validate the world's parameters and each robot's (``NAME.parameter`` keys).

    Returns the world's SimConfig (the settings of the one default robot too,
    when ``robots`` is empty) and a RobotSpec per robot listed in ``robots``;
    ``NAME.namespace`` is a robot's namespace (default: its name).
    """
    config = parse_config({k: v for k, v in values.items() if '.' not in k})
    own: Dict[str, Dict[str, Any]] = {name: {} for name in config.robots}
    for key, value in values.items():
        if '.' not in key:
            continue
        robot, _, parameter = key.partition('.')
        if robot not in own:
            listed = ', '.join(config.robots) or 'none'
            raise ConfigError(f'parameter {key} is for a robot {robot!r} that robots does not '
                              f'list (robots: {listed})')
        own[robot][parameter] = value
    specs = []
    for name in config.robots:
        namespace = read.namespace(f'{name}.namespace', own[name].pop('namespace', ''))
        specs.append(RobotSpec(name, namespace or name, robot_config(config, name, own[name])))
    if config.tf_layout == 'shared':  # one /tf: each robot's frames must be its own
        prefixes: Dict[str, str] = {}
        for spec in specs:
            other = prefixes.setdefault(spec.config.frame_prefix, spec.name)
            if other != spec.name:
                raise ConfigError(f'robots {other} and {spec.name} both prefix their frames '
                                  f'{spec.config.frame_prefix!r} on the shared /tf: give '
                                  f'{spec.name}.frame_prefix another')
    return config, specs
