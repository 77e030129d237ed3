"""
SDF models joined to the world by a moving joint: loaded with a world, spawned, and moving.

A pendulum whose bob hangs 1 m from a joint to ``world`` (sdf-worlds.md: "any
other [joint] turns about a massless anchor there"). The entity's base is
that anchor, so ``entity_state`` is the pivot and the middle of
``entity_bounds`` (a sphere's exact box, in the base's frame) is where the bob
is from it. A hinge and a ball joint swing the bob down from level, keeping
it 1 m from the pivot; a prismatic joint slides it down a 45-degree rail as
gravity along the rail would, never off the rail.
"""

import math

import pytest

from sdf_files import sdf

RAIL = (0.0, -math.sqrt(0.5), -math.sqrt(0.5))  # the prismatic joint's axis: down at 45 degrees
GRAVITY = 9.8  # m/s^2, the simulator's default


def pendulum(name: str, kind: str, pose: str = '0 0 0 0 0 0') -> str:
    """Return a model whose bob is 1 m (+y) from its joint to the world, 3 m up."""
    axis = '0 -0.7071067811865476 -0.7071067811865476' if kind == 'prismatic' else '1 0 0'
    return (f'<model name="{name}"><pose>{pose}</pose><link name="bob"><pose>0 1 3 0 0 0</pose>'
            '<inertial><mass>1</mass><inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz>'
            '</inertia></inertial><collision name="c"><geometry><sphere><radius>0.1</radius>'
            '</sphere></geometry></collision></link>'
            f'<joint name="j" type="{kind}"><parent>world</parent><child>bob</child>'
            f'<pose>0 -1 0 0 0 0</pose><axis><xyz>{axis}</xyz></axis></joint></model>')


def bob_from_pivot(harness, name):
    """Return the bob's centre in the anchor's frame: the middle of the entity's box."""
    upper, lower = harness.entity_bounds(name).points
    return tuple((high + low) / 2.0 for high, low in zip(upper, lower))


@pytest.mark.parametrize('kind', ['revolute', 'ball', 'prismatic'])
def test_a_model_on_a_moving_joint_to_the_world_loads_spawns_and_moves(
        r2d2_sim_factory, tmp_path, kind):
    world = tmp_path / 'pendulums.sdf'
    world.write_text(sdf('<world name="pendulums">'
                         f'{pendulum("in_world", kind, "3 5 0 0 0 0")}</world>'))
    harness = r2d2_sim_factory(world=str(world))
    spawned = harness.spawn(sdf(pendulum('spawned', kind)), position=(-3.0, 5.0, 0.0))
    pivots = {'in_world': (3.0, 5.0, 3.0), spawned: (-3.0, 5.0, 3.0)}
    for name, pivot in pivots.items():
        assert harness.entity_state(name).position == pytest.approx(pivot, abs=1e-9)
        assert bob_from_pivot(harness, name) == pytest.approx((0.0, 1.0, 0.0), abs=1e-9)
    lowest = {name: 0.0 for name in pivots}
    dt = 1.0 / harness.physics_rate_hz
    for tenth in range(1, 9):  # 0.8 s: a hinge's bob passes the bottom at about 0.6 s
        harness.advance(seconds=0.1)
        t = tenth * 0.1
        for name, pivot in pivots.items():
            assert harness.entity_state(name).position == pytest.approx(pivot, abs=1e-6)
            x, y, z = bob = bob_from_pivot(harness, name)
            lowest[name] = min(lowest[name], z)
            if kind == 'prismatic':
                along = sum(b * a for b, a in zip((x, y - 1.0, z), RAIL))
                off_rail = math.dist((x, y - 1.0, z), [along * a for a in RAIL])
                assert off_rail < 1e-3, (name, t, bob)
                # From rest, frictionless, a = g sin(45 deg): after n steps of dt, Bullet's
                # semi-implicit Euler has gone a dt^2 n (n + 1) / 2 (a t^2 / 2, and a bit).
                n = round(t / dt)
                assert along == pytest.approx(GRAVITY * math.sqrt(0.5) * dt * dt * n * (n + 1)
                                              / 2.0, rel=1e-3), (name, t, bob)
            else:
                assert math.dist(bob, (0.0, 0.0, 0.0)) == pytest.approx(1.0, abs=1e-3), \
                    (name, t, bob)
                assert abs(x) < 1e-3, (name, t, bob)  # it swings about x only
    for name in pivots:
        assert lowest[name] < (-1.5 if kind == 'prismatic' else -0.99), name
