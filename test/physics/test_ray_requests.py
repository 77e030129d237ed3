"""
Several sensors' rays cast together (raycast.cast_requests), each as a call of its own gives it.

A call has one collision mask: a call per robot (ray group), a robot's
sensors sharing theirs. Every ray's answer must be, bit for bit, what a
call of its own with its robot's mask gives, and every robot within reach
must be seen: checked on R2D2s near and far from each other, with rays
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
    return RayRequest(starts, ends, group)


@pytest.mark.parametrize('positions, seen', [
    ([(0.0, 0.0), (2.0, 0.0), (0.0, 3.0)], 6),          # all within 12 m of each other
    ([(0.0, 0.0), (30.0, 0.0), (0.0, 40.0)], 0),        # far apart
    ([(0.0, 0.0), (2.0, 0.0), (40.0, 0.0)], 2),         # two near, one far
])
def test_batched_answers_are_bit_for_bit_those_of_a_call_each(positions, seen):
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
        assert len(plan_calls(requests)) == len(positions)
        batched = cast_requests(world.client, requests)
        hits_on_robots = 0
        for r, answer in zip(requests, batched):
            alone = cast_rays(world.client, r.starts, r.ends, ray_mask(r.group))
            assert answer.tobytes() == alone.tobytes()
            aimed = answer[500:]
            assert (aimed < 1.0).all()  # every robot within reach is seen
            hits_on_robots += len(aimed)
        assert hits_on_robots == seen


def test_a_robots_sensors_share_its_call_and_its_mask():
    rays = numpy.array([[0.0, 0.0, 0.25], [10.0, 0.0, 0.25]])
    laser_a = RayRequest(rays[:1], rays[1:], RAY_GROUPS[0])
    laser_b = RayRequest(rays[:1] + 5.0, rays[1:] + 5.0, RAY_GROUPS[1])
    lidar_a = RayRequest(rays[:1], rays[1:] * -1.0, RAY_GROUPS[0])
    assert plan_calls([laser_a, laser_b, lidar_a]) == [([0, 2], ray_mask(RAY_GROUPS[0])),
                                                       ([1], ray_mask(RAY_GROUPS[1]))]
