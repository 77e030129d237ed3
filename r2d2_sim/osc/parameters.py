"""
A scenario's parameters (OpenSCENARIO's, one parameter file's document) as the farm's Scenario.

No ROS, no scenario_execution: plain values in, a
:class:`~r2d2_sim.farm.scenario.Scenario` and the run's settings out, or one
:class:`~r2d2_sim.errors.ScenarioError` line naming what is wrong. Both
simulations (:mod:`.in_process` and :mod:`.over_ros`) take the same
parameters, so that a scenario means the same thing in either.

scenario_execution hands ``reset()`` the scenario's parameters whose names
its signature has; :data:`DEFAULTS` is that signature's single source (each
``reset`` is checked against it by a test).
"""

from dataclasses import replace
import json
import math
from typing import Any, Dict, List, Mapping, NamedTuple, Tuple

from r2d2_sim.errors import ScenarioError
from r2d2_sim.farm.places import world_poses
from r2d2_sim.farm.scenario import Box, LIMITS, Pose, Scenario
from r2d2_sim.model.regions import circle_region

__all__ = ['DEFAULTS', 'RunSettings', 'read_parameters', 'ROBOT']

# The robot a run follows unless the scenario names another: R2D2's URDF names it so.
ROBOT = 'r2d2'

# Every parameter reset() takes, with its default: what a scenario may set.
DEFAULTS: Mapping[str, Any] = {
    'world': '',                  # the simulator's world ('' none): a URDF, manifest or SDF world
    'robot': ROBOT,               # the entity the run is about (its watch, the farm report)
    'start_x': 0.0, 'start_y': 0.0, 'start_yaw': 0.0,  # where it starts (m, rad, world frame)
    'start_pose': '',             # or a named pose of the world to start at
    'goal_x': 1.0, 'goal_y': 0.0, 'goal_tolerance': 0.2,  # the goal: a circle (m)
    'goal_pose': '',              # or a named pose of the world, with goal_tolerance
    'obstacles': '',              # fixed boxes: JSON [[x, y, yaw, size_x, size_y, height], ...]
    'seed': 0,                    # the simulator's noise_seed; one per variation
    'scan_noise_std': 0.0,        # the laser's range noise (m)
    'limits': '',                 # robot limits: JSON {"max_linear_velocity": 0.5, ...}
    'parameters': '',             # more simulator parameters, JSON (in process only)
    'simulator_namespace': '/',   # where the standard's services are found (over ROS only)
}


class RunSettings(NamedTuple):
    """What a run needs beyond the farm's Scenario: the robot followed, extra parameters."""

    scenario: Scenario
    robot: str
    parameters: Dict[str, Any]
    simulator_namespace: str


def _json(name: str, text: str, kind: type) -> Any:
    if not text:
        return kind()
    try:
        value = json.loads(text)
    except ValueError as exc:
        raise ScenarioError(f'parameter {name}: not JSON ({exc})') from None
    if not isinstance(value, kind):
        raise ScenarioError(f'parameter {name}: a JSON {kind.__name__} expected, got '
                            f'{type(value).__name__}')
    return value


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value):
        raise ScenarioError(f'parameter {name}: a finite number expected, got {value!r}')
    return float(value)


def _boxes(text: str) -> Tuple[Box, ...]:
    boxes: List[Box] = []
    for index, item in enumerate(_json('obstacles', text, list)):
        if isinstance(item, dict):
            size = item.get('size', [])
            if not isinstance(size, list):
                raise ScenarioError(f'parameter obstacles: box {index}\'s size is '
                                    f'[size_x, size_y, height], got {size!r}')
            values = [item.get('x'), item.get('y'), item.get('yaw', 0.0), *size]
        else:
            values = list(item) if isinstance(item, (list, tuple)) else [item]
        if len(values) != 6:
            raise ScenarioError(f'parameter obstacles: box {index} needs [x, y, yaw, size_x, '
                                f'size_y, height], got {item!r}')
        x, y, yaw, size_x, size_y, height = (_number(f'obstacles[{index}]', v) for v in values)
        boxes.append(Box(x, y, yaw, (size_x, size_y, height)))
    return tuple(boxes)


def read_parameters(values: Mapping[str, Any]) -> RunSettings:
    """
    Return the run the parameters describe; ScenarioError (one line) for any that cannot be.

    ``values``: names of :data:`DEFAULTS` (others are a mistake named in the
    error); missing ones take their defaults. A named start or goal is read
    from the world file, as the farm does: a world or a name that does not
    exist is one line listing what does.
    """
    unknown = sorted(set(values) - set(DEFAULTS))
    if unknown:
        raise ScenarioError(f'unknown scenario parameter(s) {", ".join(unknown)}; the '
                            f'simulation takes: {", ".join(DEFAULTS)}')
    merged = {**DEFAULTS, **values}
    for name in ('world', 'robot', 'start_pose', 'goal_pose', 'obstacles', 'limits',
                 'parameters', 'simulator_namespace'):
        if not isinstance(merged[name], str):
            raise ScenarioError(f'parameter {name}: a string expected, got {merged[name]!r}')
    seed = merged['seed']
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise ScenarioError(f'parameter seed: an integer expected, got {seed!r}')
    limits = _json('limits', merged['limits'], dict)
    for name, value in limits.items():
        if name not in LIMITS:
            raise ScenarioError(f'parameter limits: {name!r} is not one of {", ".join(LIMITS)}')
        _number(f'limits.{name}', value)
    tolerance = _number('goal_tolerance', merged['goal_tolerance'])
    if tolerance < 0.0:
        raise ScenarioError(f'parameter goal_tolerance: a radius >= 0 (m) expected, got '
                            f'{tolerance:g}')
    if merged['world']:
        world_poses(merged['world'])  # a world the simulator would refuse: one line, here
    others: Dict[str, Any] = {
        'obstacles': _boxes(merged['obstacles']), 'seed': seed,
        'limits': tuple(limits.items()),
        'scan_noise_std': _number('scan_noise_std', merged['scan_noise_std'])}
    names: Dict[str, str] = {}  # the world's named poses standing for start and goal
    if merged['start_pose']:
        names['start'] = merged['start_pose']
    else:
        others['start'] = Pose(_number('start_x', merged['start_x']),
                               _number('start_y', merged['start_y']),
                               _number('start_yaw', merged['start_yaw']))
    if merged['goal_pose']:
        names['goal'] = merged['goal_pose']
    else:
        others['goal'] = circle_region(_number('goal_x', merged['goal_x']),
                                       _number('goal_y', merged['goal_y']), tolerance)
    numbers = {key: others.pop(key) for key in ('start', 'goal') if key in others}
    scenario = replace(Scenario.named(merged['world'], goal_tolerance=tolerance, **names,
                                      **others), **numbers)
    return RunSettings(scenario, merged['robot'] or ROBOT,
                       _json('parameters', merged['parameters'], dict),
                       merged['simulator_namespace'] or '/')
