"""
The battery's dock as a named pose of the world (``battery_dock``), in the core.

No ROS. The room's manifest names a ``dock`` (x 1.4, y 0, facing +x): a robot
with ``battery_dock: dock`` charges there, as with the same pose given as
numbers; a world without that pose at start-up is refused in one line, and
one loaded later leaves the robot without a dock (one warning) until a world
with it comes back. A robot spawned with a namespace takes the dock too.
"""

import pytest

from r2d2_sim.model.battery import CHARGING, DISCHARGING
from r2d2_sim.sim.entities import SpawnRequest
from r2d2_sim.sim.settings.table import ConfigError
from r2d2_sim.sim.settings.robots import parse_world
from r2d2_sim.sim.simulation import Simulation

ROOM = 'package://r2d2_sim/urdf/room.world.yaml'
EMPTY = 'package://r2d2_sim/urdf/empty.world.yaml'
DOCK = (1.4, 0.0, 0.0)  # the room's named pose 'dock': x, y, yaw
SIMULATION_DEFAULTS = {'battery_rate': 10.0, 'cmd_vel_timeout': 0.0, 'world': ROOM,
                       'battery_initial_charge': 0.5}


def simulation_with(warnings, **parameters):
    """Return a Simulation of the defaults and ``parameters``; warnings go to the list."""
    config, robots = parse_world({**SIMULATION_DEFAULTS, **parameters})
    return Simulation(config, robots, warn=warnings.append)


def last_reading(simulation, steps=240):
    """Step ``steps`` times; return the last battery reading of the first robot."""
    readings = []
    for _ in range(steps):
        battery = simulation.step().measurements[0].battery
        if battery is not None:
            readings.append(battery)
    return readings[-1]


def docked_at(robot):
    dock = robot.battery.dock
    return None if dock is None else (dock.x_m, dock.y_m, dock.yaw_rad)


def test_the_named_dock_is_the_worlds_pose_and_a_robot_resting_there_charges(make):
    # initial_pose is relative to the room's start pose (the origin, facing +x).
    simulation = make(battery_dock='dock', initial_pose=list(DOCK))
    assert docked_at(simulation.robot) == pytest.approx(DOCK, abs=1e-12)
    assert last_reading(simulation).status == CHARGING


def test_the_named_dock_charges_exactly_as_the_same_pose_given_in_numbers(make):
    by_name = last_reading(make(battery_dock='dock', initial_pose=list(DOCK)))
    by_numbers = last_reading(make(battery_dock_pose=list(DOCK), initial_pose=list(DOCK)))
    assert by_name == by_numbers


def test_away_from_the_named_dock_the_robot_discharges(make):
    simulation = make(battery_dock='dock')  # at the start pose, 1.4 m from the dock
    assert last_reading(simulation).status == DISCHARGING


@pytest.mark.parametrize('parameters, words', [
    ({'battery_dock': 'kitchen'}, "battery_dock 'kitchen' is not a named pose of the world room"),
    ({'battery_dock': 'dock', 'world': EMPTY}, "battery_dock 'dock' is not a named pose of the "
                                               'world empty'),
    ({'battery_dock': 'dock', 'battery_dock_pose': [0.0, 0.0, 0.0]},
     'parameters battery_dock and battery_dock_pose both give the dock'),
])
def test_a_dock_that_cannot_be_is_refused_at_start_up_in_one_line(make, parameters, words):
    with pytest.raises(ConfigError) as raised:
        make(**parameters)
    assert words in str(raised.value) and '\n' not in str(raised.value)


def test_a_listed_robots_refusal_names_the_robot(make):
    with pytest.raises(ConfigError, match=r"^robot b: battery_dock 'nowhere'"):
        make(robots=['a', 'b'], **{'a.initial_pose': [0.0, 1.0, 0.0],
                                   'b.initial_pose': [0.0, -1.0, 0.0],
                                   'b.battery_dock': 'nowhere'})


def test_a_world_without_the_dock_leaves_no_dock_until_one_with_it_loads():
    warnings = []
    simulation = simulation_with(warnings, battery_dock='dock')
    try:
        simulation.load_world(EMPTY)
        assert docked_at(simulation.robot) is None
        assert [w for w in warnings if 'no dock to charge on' in w] == [
            "battery_dock 'dock' is not a named pose of the world empty: no dock to charge on"]
        simulation.load_world(ROOM)
        assert docked_at(simulation.robot) == pytest.approx(DOCK, abs=1e-12)
    finally:
        simulation.close()


def test_a_robot_spawned_in_a_namespace_takes_the_worlds_dock(make):
    simulation = make(battery_dock='dock')
    simulation.spawn(SpawnRequest('c', uri='package://r2d2_sim/urdf/r2d2.urdf', namespace='c',
                                  position=(-1.0, 1.5, 0.5)))
    spawned = next(robot for robot in simulation.robots if robot.name == 'c')
    assert docked_at(spawned) == pytest.approx(DOCK, abs=1e-12)
