"""
Moving bodies a request puts into one another, in the core: refused in one line, not simulated.

No ROS. A 30 kB LoadWorld of one model with 200 unjoined links at one point
passed every budget, and the next step ran for minutes (180 bodies: 25 s):
Bullet resolves every contact between moving bodies put together at once.
The same pile is refused through each way in: LoadWorld, SpawnEntity (one
body at a time while nothing steps) and SetEntityState (bodies moved onto one
another); what was there stays as it was. The same links set apart load.
How long the refused step would have taken is measured in
``r2d2_sim/physics/crowding.py``'s docstring, never here.
"""

import pytest

from r2d2_sim.errors import RefusedError
from r2d2_sim.physics.crowding import MAX_TOUCHING_PAIRS
from r2d2_sim.sim.simulation import SpawnRequest
from sdf_files import sdf

SIMULATION_DEFAULTS = {'scan_rate': 0.0, 'imu_rate': 0.0, 'cmd_vel_timeout': 0.0}
BOX = ('<robot name="box"><link name="box"><inertial><mass value="1"/><inertia ixx="0.01" '
       'iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial><collision><geometry>'
       '<box size="0.3 0.3 0.3"/></geometry></collision></link></robot>')
# The smallest pile at one point whose pairs, all touching, pass the bound.
PILE = next(n for n in range(2, 100) if n * (n - 1) // 2 > MAX_TOUCHING_PAIRS)


def links_world(count, spacing_m):
    """Return an SDF world of one model of ``count`` unjoined 0.3 m box links in a row."""
    links = ''.join(
        f'<link name="l{i}"><pose>{spacing_m * i} 0 0.5 0 0 0</pose><inertial><mass>1</mass>'
        '<inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz></inertia></inertial>'
        '<collision name="c"><geometry><box><size>0.3 0.3 0.3</size></box></geometry>'
        '</collision></link>' for i in range(count))
    return sdf(f'<world name="pile"><model name="m">{links}</model></world>')


@pytest.mark.parametrize('count', [PILE, 200], ids=['just past the bound', '200 links'])
def test_a_world_of_links_at_one_point_is_refused_in_one_line(make, count, tmp_path,
                                                              monkeypatch):
    monkeypatch.setenv('R2D2_SIM_CACHE_DIR', str(tmp_path / 'cache'))
    simulation = make()
    text = links_world(count, 0.0)
    assert len(text) < 60_000  # a request any peer can send
    with pytest.raises(RefusedError) as refused:
        simulation.load_world('', text)
    assert refused.value.code == 'RESOURCE_PARSE_ERROR' and '\n' not in str(refused.value)
    assert refused.value.message.startswith('the world')
    assert simulation.worlds.current.name == 'empty'
    assert simulation.entities.names() == ['ground_plane', 'r2d2']


def test_the_same_links_set_apart_load_and_a_pile_at_the_bound_too(make, tmp_path,
                                                                   monkeypatch):
    monkeypatch.setenv('R2D2_SIM_CACHE_DIR', str(tmp_path / 'cache'))
    simulation = make()
    assert len(simulation.load_world('', links_world(200, 0.6)).models) == 200
    assert len(simulation.load_world('', links_world(PILE - 1, 0.0)).models) == PILE - 1


def test_spawns_piled_at_one_point_are_refused_once_the_pile_passes_the_bound(make):
    simulation = make()
    for i in range(PILE - 1):  # nothing steps between them: a pile Bullet meets at once
        simulation.spawn(SpawnRequest(f'box{i}', resource_string=BOX, position=(1.0, 1.0, 1.0)))
    with pytest.raises(RefusedError) as refused:
        simulation.spawn(SpawnRequest('last', resource_string=BOX, position=(1.0, 1.0, 1.0)))
    assert refused.value.code == 'INVALID_POSE'
    assert refused.value.message.startswith('last at that pose puts moving bodies into one')
    assert 'last' not in simulation.entities.names()
    simulation.spawn(SpawnRequest('apart', resource_string=BOX, position=(-1.0, -1.0, 1.0)))


def test_bodies_moved_onto_one_another_are_refused_and_put_back(make):
    simulation = make()
    names = [simulation.spawn(SpawnRequest(f'box{i}', resource_string=BOX,
                                           position=(0.5 * i - 10.0, 3.0, 0.15)))
             for i in range(PILE)]
    for name in names[:-1]:
        simulation.set_entity_state(name, '', (5.0, 5.0, 1.0), (0.0, 0.0, 0.0, 1.0),
                                    (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    before = simulation.entities.state(names[-1])
    with pytest.raises(RefusedError) as refused:
        simulation.set_entity_state(names[-1], '', (5.0, 5.0, 1.0), (0.0, 0.0, 0.0, 1.0),
                                    (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert refused.value.code == 'INVALID_POSE' and 'into one another' in refused.value.message
    assert simulation.entities.state(names[-1]) == before
