"""
The node's parameters on the ROS side: typed declarations from the one table.

:mod:`r2d2_sim.sim.settings.table` holds the table and the validation without ROS;
this declares every entry on a node with its type, description and range, so
``ros2 param describe`` shows them, and names overrides that nothing reads.
Each robot listed in ``robots`` has the parameters it sets as
``NAME.parameter`` (and ``NAME.namespace``), declared the same way.
"""

import dataclasses
import os
import re
from typing import Any, Callable, Dict, Iterable, List, Sequence, Tuple

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from r2d2_sim.sim.settings.table import Parameter as ParameterSpec, PARAMETERS, PARAMETERS_BY_NAME
from r2d2_sim.sim.settings.config import SimConfig
from r2d2_sim.sim.settings.given import unknown_parameters
from r2d2_sim.sim.settings.robots import parse_world, RobotSpec

NAMESPACE_SPEC = ParameterSpec(
    'namespace', 'string', '', 'The robot\'s namespace: absolute, or relative to the '
    'simulator\'s; empty for its name.', 'namespace', lambda name, value: value)

ROS_TYPES = {'double': Parameter.Type.DOUBLE, 'integer': Parameter.Type.INTEGER,
             'bool': Parameter.Type.BOOL, 'string': Parameter.Type.STRING,
             'double_array': Parameter.Type.DOUBLE_ARRAY,
             'string_array': Parameter.Type.STRING_ARRAY}


def declare_parameters(node: Node) -> Tuple[SimConfig, List[RobotSpec]]:
    """
    Validate the node's overrides, then declare every parameter with its type and that value.

    Validation comes first so a wrong value or type is one ConfigError line
    (rclpy would raise its own exception for a type mismatch). The values
    are declared converted to the table's type (an integer given for a
    double becomes a double). Returns the world's settings and each robot's.
    """
    overrides = getattr(node, '_parameter_overrides', {})
    raw = {spec.name: overrides[spec.name].value if spec.name in overrides else spec.default
           for spec in PARAMETERS}
    robots = raw['robots'] or []
    if not isinstance(robots, (list, tuple)):
        robots = []  # parse_world says what is wrong with it
    own = {name: value.value for name, value in overrides.items()
           if name.partition('.')[0] in robots and '.' in name}
    config, specs = parse_world({**raw, **own})
    for spec in PARAMETERS:
        _declare_typed(node, spec, raw[spec.name])
    for name, value in own.items():
        parameter = name.partition('.')[2]
        spec = NAMESPACE_SPEC if parameter == 'namespace' else PARAMETERS_BY_NAME[parameter]
        _declare_typed(node, spec._replace(name=name), value)
    for problem in unknown_overrides(node, overrides, list(config.robots)):
        node.get_logger().warning(f'ignoring {problem}')
    return config, specs


def with_ray_threads(config: SimConfig) -> SimConfig:
    """
    Return ``config`` with ``ray_threads`` auto (0) made what a node takes: 2 on two cores.

    The node's physics thread casts its scans while the executor's thread
    mostly waits, so a second core is there to cast on; a process allowed one
    core (``taskset``, a container's CPU set) casts on one.
    """
    if config.ray_threads:
        return config
    affinity = getattr(os, 'sched_getaffinity', None)  # Linux; elsewhere the machine's cores
    cores = len(affinity(0)) if affinity is not None else (os.cpu_count() or 1)
    return dataclasses.replace(config, ray_threads=min(2, cores))


def _declare_typed(node: Node, spec: ParameterSpec, value: Any) -> None:
    descriptor = ParameterDescriptor(description=spec.description, read_only=True)
    bounds = spec.bounds
    if bounds is not None and bounds.zero is None:
        if spec.ros_type == 'double':
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(bounds.low), to_value=float(bounds.high))]
        elif spec.ros_type == 'integer':
            descriptor.integer_range = [IntegerRange(
                from_value=int(bounds.low), to_value=int(bounds.high))]
    # The raw value passed validation: only its Python type may differ.
    conversions: Dict[str, Callable[[Any], Any]] = {
        'double': float, 'integer': int,
        'double_array': lambda v: [float(x) for x in v or []],  # ROS gives [] as None
        'string_array': lambda v: list(v or [])}
    convert = conversions.get(spec.ros_type)
    if convert is not None:
        value = convert(value)
    if isinstance(value, list) and not value:
        _declare_empty_list(node, spec.name, ROS_TYPES[spec.ros_type], descriptor)
    else:
        node.declare_parameter(spec.name, value, descriptor, ignore_override=True)


def _declare_empty_list(node: Node, name: str, ros_type: Parameter.Type,
                        descriptor: ParameterDescriptor) -> None:
    """
    Declare ``name`` read-only with an empty list of ``ros_type`` as its value.

    rclpy infers a type from the value, and an empty list reads as a byte
    array. Declared with only its type, the parameter has no value, and
    rclpy's GetParameters service then answers any request naming it with no
    values at all: ``ros2 param dump`` and rqt, which ask for every listed
    name at once, got nothing. So: declare the type writable, set the typed
    empty value, then make it read-only (all through rclpy's public API).
    """
    writable = ParameterDescriptor(description=descriptor.description)
    node.declare_parameter(name, ros_type, writable, ignore_override=True)
    (result,) = node.set_parameters([Parameter(name, ros_type, [])])
    if not result.successful:
        raise RuntimeError(f'cannot set parameter {name} to []: {result.reason}')
    descriptor.type = ros_type.value
    node.set_descriptor(name, descriptor)


def unknown_overrides(node: Node, overrides: Iterable[str], robots: Sequence[str]) -> List[str]:
    """Return :func:`unknown_parameters` of the overrides ``node`` declares no parameter for."""
    return unknown_parameters([name for name in overrides if not node.has_parameter(name)],
                              robots)


# How rclpy 7.1 words a parameter override of the wrong type (InvalidParameterTypeException).
_RCLPY_WRONG_TYPE = re.compile(r"Trying to set parameter '(?P<name>[^']*)' to '(?P<value>.*)' "
                               r"of type '(?P<got>\w+)', expecting type '(?P<want>\w+)'")


def rclpy_parameter_problem(exc: Exception) -> str:
    """
    Return one line for rclpy's refusal of one of its own parameters (``use_sim_time:=1``).

    rclpy checks the types of the parameters every node declares while the
    node is built, before anything of ours could: its exception would be a
    traceback. Any other text is returned on one line as it is.
    """
    text = ' '.join(str(exc).split())
    found = _RCLPY_WRONG_TYPE.match(text)
    if found is None:
        return text

    def kind(type_name: str) -> str:
        words = type_name.lower().replace('_', ' ')
        return ('an ' if words[0] in 'aeiou' else 'a ') + words
    wanted = 'true or false' if found['want'] == 'BOOL' else kind(found['want'])
    return (f"parameter {found['name']} must be {wanted}, got {found['value']} "
            f"({kind(found['got'])})")
