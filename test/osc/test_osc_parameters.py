"""
A scenario's parameters as the farm's Scenario: defaults, boxes, named poses, a line per mistake.

No ROS, no physics, no scenario_execution (the simulations' ``reset`` signatures are
read with ``inspect`` and checked against the one table of parameters).
"""

import inspect

import pytest

from r2d2_sim.errors import ScenarioError
from r2d2_sim.farm.scenario import Box, Pose
from r2d2_sim.model.regions import circle_region
from r2d2_sim.osc.parameters import DEFAULTS, read_parameters

ROOM = 'package://r2d2_sim/urdf/room.world.yaml'


def test_no_parameters_is_the_farms_default_scenario():
    """Start at the origin, the goal a 0.2 m circle at (1, 0), seed 0, no box, no world."""
    settings = read_parameters({})
    scenario = settings.scenario
    assert scenario.start == Pose(0.0, 0.0, 0.0)
    assert scenario.goal == circle_region(1.0, 0.0, 0.2)
    assert (scenario.seed, scenario.world, scenario.obstacles) == (0, '', ())
    assert (settings.robot, settings.parameters, settings.simulator_namespace) == \
        ('r2d2', {}, '/')


def test_boxes_goal_seed_and_limits_map_onto_the_scenario():
    """Boxes as lists or the farm's JSON objects, in order; a goal circle; limits by name."""
    settings = read_parameters({
        'obstacles': '[[1, 2, 0.5, 0.3, 0.4, 0.5], {"x": -1, "y": 0, "size": [1, 1, 1]}]',
        'goal_x': 2.0, 'goal_y': -1.0, 'goal_tolerance': 0.3, 'seed': 7,
        'start_x': 0.5, 'start_yaw': 1.0, 'limits': '{"max_linear_velocity": 0.3}',
        'parameters': '{"publish_rate": 50.0}'})
    scenario = settings.scenario
    assert scenario.obstacles == (Box(1.0, 2.0, 0.5, (0.3, 0.4, 0.5)),
                                  Box(-1.0, 0.0, 0.0, (1.0, 1.0, 1.0)))
    assert scenario.goal == circle_region(2.0, -1.0, 0.3)
    assert scenario.start == Pose(0.5, 0.0, 1.0)
    assert scenario.seed == 7 and scenario.limits == (('max_linear_velocity', 0.3),)
    assert scenario.parameters()['noise_seed'] == 7
    assert settings.parameters == {'publish_rate': 50.0}


def test_named_start_and_goal_come_from_the_world():
    """The room's 'start' and 'dock': their numbers, and the names kept for the report."""
    scenario = read_parameters({'world': ROOM, 'start_pose': 'start', 'goal_pose': 'dock',
                                'goal_tolerance': 0.25}).scenario
    assert (scenario.start_name, scenario.goal_name) == ('start', 'dock')
    assert scenario.goal == circle_region(1.4, 0.0, 0.25)
    assert scenario.start == Pose(0.0, 0.0, 0.0)


@pytest.mark.parametrize('values, says', [
    ({'world': 'nothere.world.yaml'}, 'world nothere.world.yaml: no such world file'),
    ({'world': ROOM, 'goal_pose': 'nowhere'}, "no named pose 'nowhere' in"),
    ({'goal_pose': 'dock'}, "no named pose 'dock' in no world"),
    ({'goal_xx': 1.0}, 'unknown scenario parameter(s) goal_xx'),
    ({'obstacles': '[[1, 2]]'}, 'box 0 needs [x, y, yaw, size_x, size_y, height]'),
    ({'obstacles': '[[1, 2, 0, 0.3, 0.3'}, 'parameter obstacles: not JSON'),
    ({'limits': '{"top_speed": 2}'}, "parameter limits: 'top_speed' is not one of"),
    ({'seed': 1.5}, 'parameter seed: an integer expected'),
    ({'goal_x': float('nan')}, 'parameter goal_x: a finite number expected'),
    ({'goal_tolerance': -0.5}, 'parameter goal_tolerance: a radius >= 0 (m) expected, got -0.5'),
    ({'obstacles': '[{"x": 1, "y": 0, "size": 5}]'},
     "parameter obstacles: box 0's size is [size_x, size_y, height], got 5"),
    ({'obstacles': '[{"x": 1, "y": 0, "size": {"x": 1}}]'}, "box 0's size is [size_x, size_y,"),
])
def test_a_mistake_is_one_line(values, says):
    """Each mistake raises ScenarioError in one line saying what is wrong."""
    with pytest.raises(ScenarioError) as raised:
        read_parameters(values)
    assert says in str(raised.value)
    assert '\n' not in str(raised.value)


def test_both_simulations_take_exactly_the_parameters_of_the_table():
    """reset() of each simulation names DEFAULTS' parameters, with their defaults, in order."""
    from r2d2_sim.osc.in_process import R2D2Simulation
    from r2d2_sim.osc.over_ros import StandardSimulation
    for simulation in (R2D2Simulation, StandardSimulation):
        parameters = list(inspect.signature(simulation.reset).parameters.values())[1:]
        assert [(p.name, p.default) for p in parameters] == list(DEFAULTS.items()), simulation
