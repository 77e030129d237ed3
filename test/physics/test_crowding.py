"""
Moving bodies put into one another: which links move, which pairs touch, what is refused.

No ROS. Boxes loaded into a world of their own: piles at one point (every
pair of a pile of n touches: n (n - 1) / 2), rows that touch or stand 5 mm
apart, a fixed base with a hinge. The counts are exact; what the bounds cost
Bullet is measured in the module's docstring, not asserted here.
"""

import os

import pytest

from r2d2_sim.errors import RefusedError
from r2d2_sim.physics import crowding
from r2d2_sim.physics.crowding import (
    check_crowding, check_placements, moving_links, Placement, touching_pairs)
from r2d2_sim.physics.world import SimWorld

INERTIA = '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'
BOX = ('<robot name="box"><link name="box"><inertial><mass value="1"/>' + INERTIA +
       '</inertial><collision><geometry><box size="0.3 0.3 0.3"/></geometry></collision>'
       '</link></robot>')
MASSLESS = '<inertial><mass value="0"/>' + INERTIA + '</inertial>'
DOOR = ('<robot name="door"><link name="frame">' + MASSLESS + '</link><link name="panel">'
        '<inertial><mass value="1"/>' + INERTIA + '</inertial><collision><geometry><box '
        'size="0.3 0.3 0.3"/></geometry></collision></link><joint name="hinge" '
        'type="revolute"><parent link="frame"/><child link="panel"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')
WALL = ('<robot name="wall"><link name="wall">' + MASSLESS + '<collision><geometry><box '
        'size="0.3 0.3 0.3"/></geometry></collision></link></robot>')


@pytest.fixture
def files(tmp_path):
    """Write the three bodies; return their paths by name."""
    paths = {}
    for name, text in (('box', BOX), ('door', DOOR), ('wall', WALL)):
        paths[name] = str(tmp_path / f'{name}.urdf')
        with open(paths[name], 'w') as handle:
            handle.write(text)
    return paths


@pytest.fixture
def world():
    with SimWorld(ground_plane=False) as world:
        yield world


def pile(n):
    """Return the number of touching pairs in a pile of ``n`` at one point."""
    return n * (n - 1) // 2


def test_a_free_base_moves_all_its_links_a_fixed_one_those_below_a_joint(world, files):
    assert moving_links(world.load(files['box'])) == [-1]
    assert moving_links(world.load(files['door'])) == [0]
    assert moving_links(world.load(files['wall'])) == []


def test_touching_pairs_are_counted_exactly_and_bodies_apart_not_at_all(world, files):
    bodies = [world.load(files['box'], (0.0, 0.0, 1.0)) for _ in range(6)]
    bodies += [world.load(files['box'], (x, 5.0, 1.0)) for x in (0.0, 0.3, 0.6)]  # a row
    bodies += [world.load(files['box'], (x, 9.0, 1.0)) for x in (0.0, 0.305, 0.61)]  # 5 mm
    bodies.append(world.load(files['wall'], (0.0, 0.0, 1.0)))  # static: never counted
    links = [(body, link) for body in bodies for link in moving_links(body)]
    everything = [True] * len(links)
    assert touching_pairs(world.client, links, everything, 1000) == pile(6) + 2
    assert touching_pairs(world.client, links, everything, 3) == 4  # stops past its limit
    last_of_pile = [body is bodies[5] for body, _ in links]
    assert touching_pairs(world.client, links, last_of_pile, 1000) == 5


def test_a_pile_past_the_bound_is_refused_and_one_at_it_is_not(world, files, monkeypatch):
    monkeypatch.setattr(crowding, 'MAX_TOUCHING_PAIRS', pile(5))
    bodies = [world.load(files['box'], (0.0, 0.0, 1.0)) for _ in range(5)]
    check_crowding(world.client, bodies, bodies[-1:], 'INVALID_POSE', 'it')
    bodies.append(world.load(files['box'], (0.0, 0.0, 1.0)))
    with pytest.raises(RefusedError) as refused:
        check_crowding(world.client, bodies, bodies[-1:], 'INVALID_POSE', 'box_5 at that pose')
    assert refused.value.code == 'INVALID_POSE'
    assert refused.value.message.startswith('box_5 at that pose puts moving bodies into one '
                                            f'another: more than {pile(5)} pairs')
    apart = world.load(files['box'], (3.0, 0.0, 1.0))  # placed where it touches nothing
    check_crowding(world.client, bodies + [apart], [apart], 'INVALID_POSE', 'it')


def test_too_many_moving_links_or_pairs_to_ask_are_refused(world, files, monkeypatch):
    monkeypatch.setattr(crowding, 'MAX_MOVING_LINKS', 3)
    bodies = [world.load(files['box'], (3.0 * i, 0.0, 1.0)) for i in range(4)]
    with pytest.raises(RefusedError, match='^INVALID_POSE: it: the world would have 4 moving '
                                           'links, more than 3$'):
        check_crowding(world.client, bodies, bodies[-1:], 'INVALID_POSE', 'it')
    monkeypatch.setattr(crowding, 'MAX_MOVING_LINKS', 1000)
    monkeypatch.setattr(crowding, 'MAX_NEAR_PAIRS', pile(4) - 1)
    bodies = [world.load(files['box'], (0.0, 9.0, 1.0)) for _ in range(4)]
    with pytest.raises(RefusedError, match='more than 5 pairs of moving links lie within'):
        check_crowding(world.client, bodies, bodies, 'RESOURCE_PARSE_ERROR', 'the world')


def test_placements_are_loaded_apart_from_the_world_and_counted_as_they_come(
        files, monkeypatch):
    at_one_point = [Placement(files['box'], (0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0))] * 6
    monkeypatch.setattr(crowding, 'MAX_TOUCHING_PAIRS', pile(6))
    check_placements(at_one_point, 1.0 / 240.0, 'RESOURCE_PARSE_ERROR', 'the world')
    monkeypatch.setattr(crowding, 'MAX_TOUCHING_PAIRS', pile(6) - 1)
    with pytest.raises(RefusedError, match='^RESOURCE_PARSE_ERROR: the world puts moving'):
        check_placements(at_one_point, 1.0 / 240.0, 'RESOURCE_PARSE_ERROR', 'the world')
    monkeypatch.setattr(crowding, 'MAX_MOVING_LINKS', 2)
    loaded = []
    monkeypatch.setattr(SimWorld, 'load', lambda self, *args, _load=SimWorld.load, **kwargs:
                        loaded.append(args) or _load(self, *args, **kwargs))
    with pytest.raises(RefusedError, match='the world has more than 2 moving links'):
        check_placements(at_one_point, 1.0 / 240.0, 'RESOURCE_PARSE_ERROR', 'the world')
    assert len(loaded) == 3  # not all six: refused as soon as the count passed
    assert os.path.isfile(files['box'])
