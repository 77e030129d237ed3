"""
What SetEntityInfo set survives every reset but the full one (docs/changing-the-world.md).

A start-up model (the world's shelf), the robot and a spawned box are
relabelled; each partial reset (TIME, STATE, SPAWNED alone and in pairs)
must leave the labels of those still there, and only the full reset gives
the start-up entities the info they started with.
"""

import pytest

from r2d2_sim.sim.entities import Category
from r2d2_sim.sim.simulation import SpawnRequest

SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'scan_rate': 0.0, 'imu_rate': 0.0}
WORLD = '''
r2d2_sim_world: 1
name: shelved
models:
  - {uri: cube_small.urdf, name: shelf, position: [3.0, 0.0, 0.025], tags: [shelf, small]}
'''
RELABELLED = {'shelf': (Category.HUMAN, 'a person now', ('person',)),
              'r2d2': (Category.OBJECT, 'a prop now', ('prop',)),
              'box': (Category.STATIC_OBJECT, 'a wall now', ('wall',))}
# (time, state, spawned), the standard's scopes other than ALL.
PARTIAL = [(True, False, False), (False, True, False), (False, False, True),
           (True, True, False), (True, False, True), (False, True, True)]


def relabelled(make):
    """Return a simulation whose shelf, robot and spawned box were relabelled, run a little."""
    simulation = make()
    simulation.load_world('', WORLD)
    simulation.spawn(SpawnRequest('box', uri='cube_small.urdf', position=(1.0, 1.0, 0.025)))
    for name, (category, description, tags) in RELABELLED.items():
        simulation.set_entity_info(name, category, description, list(tags))
    for _ in range(24):
        simulation.step()
    return simulation


@pytest.mark.parametrize('time, state, spawned', PARTIAL,
                         ids=lambda flag: 'T' if flag is True else 'F' if flag is False else '')
def test_a_partial_reset_keeps_what_set_entity_info_set(make, time, state, spawned):
    """Every entity still there after the reset still reads as it was set."""
    simulation = relabelled(make)
    simulation.reset(time=time, state=state, spawned=spawned)
    expected = {name: info for name, info in RELABELLED.items()
                if not (spawned and name == 'box')}
    assert sorted(n for n in simulation.entities.names() if n in RELABELLED) == sorted(expected)
    for name, info in expected.items():
        assert tuple(simulation.entities.info(name)) == info, (name, time, state, spawned)


@pytest.mark.parametrize('keywords', [{'time': True}, {'spawned': True}],
                         ids=['time', 'spawned'])
def test_reset_with_its_defaults_keeps_what_set_entity_info_set(make, keywords):
    """reset(time=True) and reset(spawned=True), as a caller writes them (state by default)."""
    simulation = relabelled(make)
    simulation.reset(**keywords)
    assert tuple(simulation.entities.info('shelf')) == RELABELLED['shelf']
    assert tuple(simulation.entities.info('r2d2')) == RELABELLED['r2d2']


def test_only_the_full_reset_gives_the_start_up_entities_their_info_back(make):
    """ALL: the shelf reads as its world made it, the robot as a robot; the box is gone."""
    simulation = relabelled(make)
    simulation.reset(time=True, state=True, spawned=True)
    shelf = simulation.entities.info('shelf')
    assert (shelf.category, shelf.tags) == (Category.DYNAMIC_OBJECT, ('shelf', 'small'))
    assert simulation.entities.info('r2d2').category == Category.ROBOT
    assert 'box' not in simulation.entities.names()
