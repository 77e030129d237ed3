"""
Any entity can be deleted, start-up ones too, and a full reset brings those back as launched.

The standard's DeleteEntity takes any entity "as returned by SpawnEntity or
GetEntities", and its full reset is "as if it was closed and launched
again". Only that reset (time, state and spawned together: ALL, DEFAULT,
STOPPED) brings deleted start-up entities back; a state reset or the
spawned scope alone leaves them deleted.
"""

import math

from r2d2_sim.physics.world import RAY_GROUPS
from r2d2_sim.sim.simulation import SpawnRequest

BOX = 'cube_small.urdf 0.8 0.05 0.025'
STEPS = 480  # 2 s at 240 Hz


SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0}  # commands hold


def run(simulation):
    """Drive every robot into the box for 2 s; return every body's name and state at each step."""
    for robot in simulation.robots:
        robot.command(0.5, 0.1)
    states = []
    for _ in range(STEPS):
        simulation.step()
        states.append(tuple((body.name, body.world_state())
                            for body in simulation.world.bodies.values()))
    return states


def test_the_ground_a_model_and_the_robot_are_deleted_and_a_full_reset_brings_them_back(make):
    """Deleted: nothing left but what was spawned; reset: as launched, the same run bit for bit."""
    simulation = make(extra_models=[BOX])
    fresh = run(make(extra_models=[BOX]))
    seen = []
    simulation.watch_robots(lambda robots: seen.append([robot.name for robot in robots]))
    start_up = simulation.entities.names()
    box = simulation.models[0].name
    assert start_up == ['ground_plane', 'r2d2', box]
    run(simulation)
    for name in ('ground_plane', box, 'r2d2'):
        simulation.delete_entity(name)
    assert simulation.entities.names() == [] and simulation.robots == []
    assert simulation.models == [] and seen[-1] == []  # the robot's watchers were told
    simulation.spawn(SpawnRequest('r2d2', uri='cube_small.urdf', position=(3.0, 0.0, 0.5)))
    simulation.step()  # falls: no ground under it
    simulation.reset(time=True, state=True, spawned=True)
    assert simulation.entities.names() == start_up
    assert [robot.name for robot in simulation.robots] == ['r2d2'] and seen[-1] == ['r2d2']
    assert [model.name for model in simulation.models] == [box]
    assert simulation.unrun_since_launch and simulation.step_count == 0
    assert run(simulation) == fresh


def test_only_a_full_reset_brings_deleted_start_up_entities_back(make):
    """The state and spawned scopes, alone or together, leave them deleted."""
    simulation = make(extra_models=[BOX])
    box = simulation.models[0].name
    simulation.delete_entity(box)
    simulation.delete_entity('r2d2')
    for scope in ({'state': True}, {'spawned': True}, {'state': True, 'spawned': True},
                  {'time': True, 'state': True}):
        simulation.reset(**scope)
        assert simulation.entities.names() == ['ground_plane'], scope
    simulation.reset(time=True, state=True, spawned=True)
    assert simulation.entities.names() == ['ground_plane', 'r2d2', box]


def test_a_deleted_listed_robot_comes_back_in_its_place_with_its_own_settings(make):
    """Robot a is built again (a new robot, its ray group, its pose); b stays the same object."""
    simulation = make(robots=['a', 'b'], **{'b.initial_pose': [2.0, 0.0, math.pi],
                                            'a.max_linear_velocity': 0.2})
    a, b = simulation.robots
    fresh = run(make(robots=['a', 'b'], **{'b.initial_pose': [2.0, 0.0, math.pi],
                                           'a.max_linear_velocity': 0.2}))
    simulation.delete_entity('a')
    assert [robot.name for robot in simulation.robots] == ['b']
    simulation.spawn(SpawnRequest('c', uri='package://r2d2_sim/urdf/r2d2.urdf', namespace='c',
                                  position=(0.0, 2.0, 0.48)))
    assert simulation.robots[-1].laser._group == RAY_GROUPS[0]  # a's, given back
    simulation.reset(time=True, state=True, spawned=True)
    new_a, same_b = simulation.robots
    assert (new_a.name, new_a is not a, same_b is b) == ('a', True, True)
    assert new_a.config.max_linear_velocity_m_s == 0.2
    assert (new_a.laser._group, b.laser._group) == RAY_GROUPS[:2]
    assert simulation.entities.names() == ['ground_plane', 'a', 'b']
    assert run(simulation) == fresh
