"""
Several sensors' rays cast together (raycast.cast_requests): as few calls as exactness allows.

A call has one collision mask. Robots whose rays can reach each other's own
(ray-group) links need calls of their own; robots out of each other's reach
share one, with a mask that passes through both. Either way every ray's
answer must be, bit for bit, what a call of its own with its robot's mask
gives: checked on R2D2s within and out of reach of each other, with rays
aimed at the other robots.
"""

import numpy
import pytest

from r2d2_sim.physics.raycast import (
    cast_rays, cast_requests, plan_calls, ray_mask, RayRequest)
from r2d2_sim.physics.world import RAY_GROUPS, SimWorld

from common import PACKAGE_URDF


def robots_at(world, positions):
    """Load R2D2s at ``positions``, each with its body in a ray group; return (body, group)."""
    loaded = []
    for i, (x, y) in enumerate(positions):
        body = world.load_robot(PACKAGE_URDF, (x, y, 0.0), name=f'r{i}')
        group = world.take_ray_group()
        body.exclude_from_rays(None, group)
        loaded.append((body, group))
    return loaded


def request(body, group, rng, count=500):
    """Rays from inside the robot's body to random points up to 12 m away, some at robots."""
    origin = numpy.array(body.world_state().position)
    ends = origin + rng.uniform(-12.0, 12.0, (count, 3)) * [1.0, 1.0, 0.05]
    starts = numpy.broadcast_to(origin, ends.shape).copy()
    box = body.bounding_box()
    return RayRequest(starts, ends, group, (box.low, box.high))


@pytest.mark.parametrize('positions, calls', [
    ([(0.0, 0.0), (2.0, 0.0), (0.0, 3.0)], 3),          # all within 12 m: a call each
    ([(0.0, 0.0), (30.0, 0.0), (0.0, 40.0)], 1),        # far apart: one call
    ([(0.0, 0.0), (2.0, 0.0), (40.0, 0.0)], 2),         # the far one joins the first
])
def test_batched_answers_are_bit_for_bit_those_of_a_call_each(positions, calls):
    rng = numpy.random.default_rng(5)
    with SimWorld() as world:
        loaded = robots_at(world, positions)
        requests = [request(body, group, rng) for body, group in loaded]
        # Also aim at each other robot within 12 m: those rays must hit it.
        for i, (body, group) in enumerate(loaded):
            origin = requests[i].starts[0]
            ends = numpy.array([[x, y, 0.5] for x, y in positions
                                if 0.1 < numpy.hypot(x - origin[0], y - origin[1]) < 12.0])
            if len(ends):
                requests[i] = requests[i]._replace(
                    starts=numpy.concatenate([requests[i].starts,
                                              numpy.broadcast_to(origin, ends.shape)]),
                    ends=numpy.concatenate([requests[i].ends, ends]))
        assert len(plan_calls(requests)) == calls
        batched = cast_requests(world.client, requests)
        hits_on_robots = 0
        for r, answer in zip(requests, batched):
            alone = cast_rays(world.client, r.starts, r.ends, ray_mask(r.group))
            assert answer.tobytes() == alone.tobytes()
            aimed = answer[500:]
            assert (aimed < 1.0).all()  # every robot within reach is seen
            hits_on_robots += len(aimed)
        assert hits_on_robots == {3: 6, 1: 0, 2: 2}[calls]


def test_plan_keeps_a_robots_rays_together_and_masks_every_group_in_a_call():
    box = ((-0.3, -0.3, 0.0), (0.3, 0.3, 1.0))
    far = ((50.0, -0.3, 0.0), (50.6, 0.3, 1.0))
    rays = numpy.array([[0.0, 0.0, 0.25], [10.0, 0.0, 0.25]])
    a1 = RayRequest(rays[:1], rays[1:], RAY_GROUPS[0], box)
    a2 = RayRequest(rays[:1], rays[1:] * [1, -1, 1], RAY_GROUPS[0], box)
    b = RayRequest(rays[:1] + [50.3, 0, 0], rays[1:] + [50.3, 0, 0], RAY_GROUPS[1], far)
    assert plan_calls([a1, b, a2]) == [([0, 1, 2], -1 ^ (RAY_GROUPS[0] | RAY_GROUPS[1]))]
    near = RayRequest(b.starts - [42.0, 0, 0], b.ends - [42.0, 0, 0], RAY_GROUPS[1],
                      ((8.0, -0.3, 0.0), (8.6, 0.3, 1.0)))
    assert plan_calls([a1, near]) == [([0], ray_mask(RAY_GROUPS[0])),
                                      ([1], ray_mask(RAY_GROUPS[1]))]
