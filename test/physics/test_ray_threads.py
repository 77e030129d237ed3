"""
Rays cast on two threads: the same answers bit for bit, and threads only where they pay.

``rayTestBatch(numThreads=n)`` casts a call's rays on n threads, each ray on
its own, so a scan's ranges cannot depend on them: compared here bit for bit
in a cluttered world, from inside a robot (its own links masked out) and
from outside. Waking threads costs ~50 us a call, more than a small batch
takes on one: only calls of ``THREADED_RAYS_MIN`` rays or more are threaded.
"""

import math

import numpy
import pybullet
import pytest

from r2d2_sim.physics.raycast import (
    cast_rays, cast_requests, exclude_from_rays, ray_mask, RayRequest, THREADED_RAYS_MIN)
from r2d2_sim.physics.world import SimWorld


def circle(centre, count, radius_m=8.0):
    """Return ``count`` rays from ``centre`` to a circle around it (N x 3 starts and ends)."""
    angles = numpy.linspace(-math.pi, math.pi, count, endpoint=False)
    starts = numpy.tile(numpy.array(centre, dtype=float), (count, 1))
    ends = starts + numpy.stack([numpy.cos(angles), numpy.sin(angles),
                                 numpy.zeros(count)], axis=1) * radius_m
    return starts, ends


@pytest.fixture(scope='module')
def cluttered():
    """Provide a world of R2D2s, cubes and a duck around the origin, the first R2D2 in group 8."""
    with SimWorld() as world:
        robots = [world.load('r2d2.urdf', (1.5 * i - 3.0, 0.0, 0.5)) for i in range(5)]
        for i in range(12):
            angle = i * math.pi / 6.0
            world.load('cube_small.urdf', (3.0 * math.cos(angle), 3.0 * math.sin(angle), 0.3))
        world.load('duck_vhacd.urdf', (0.0, 2.0, 0.2))
        exclude_from_rays(world.client, robots[0].id, group=8)
        world.step(10)
        yield world, robots


@pytest.mark.parametrize('threads', [2, 4])
def test_a_scan_on_threads_is_the_scan_on_one_bit_for_bit(cluttered, threads):
    world, robots = cluttered
    inside, _ = world.client.getBasePositionAndOrientation(robots[0].id)
    for centre, mask in ((inside, ray_mask(8)), ((0.0, -1.0, 0.3), -1)):
        starts, ends = circle(centre, 720)
        one = cast_rays(world.client, starts, ends, mask)
        many = cast_rays(world.client, starts, ends, mask, threads=threads)
        assert 0 < numpy.count_nonzero(one < 1.0) < len(one)  # hits and misses both
        assert numpy.array_equal(one, many)


def test_several_robots_requests_on_threads_are_the_same(cluttered):
    world, robots = cluttered
    requests = []
    for robot, group in zip(robots[:2], (8, 0)):
        position, _ = world.client.getBasePositionAndOrientation(robot.id)
        requests.append(RayRequest(*circle(position, 360), group))
    one = cast_requests(world.client, requests)
    world.ray_threads = 2
    try:
        two = world.cast_requests(requests)
    finally:
        world.ray_threads = 1
    assert all(numpy.array_equal(a, b) for a, b in zip(one, two))


def test_the_world_casts_on_its_ray_threads(cluttered, monkeypatch):
    """SimWorld.cast_rays and cast_requests ask PyBullet for ray_threads threads."""
    world, _ = cluttered
    calls = []
    cast = world.client.rayTestBatch

    def noted(starts, ends, **kwargs):
        calls.append(kwargs.get('numThreads', 1))
        return cast(starts, ends, **kwargs)
    monkeypatch.setattr(world.client, 'rayTestBatch', noted)
    starts, ends = circle((0.0, -1.0, 0.3), 360)
    monkeypatch.setattr(world, 'ray_threads', 2)
    world.cast_rays(starts, ends)
    world.cast_requests([RayRequest(starts, ends, 8)])
    monkeypatch.setattr(world, 'ray_threads', 1)
    world.cast_rays(starts, ends)
    assert calls == [2, 2, 1]


class _Recorder:
    """A client that answers every ray with a miss and notes each call's ray count and threads."""

    error = pybullet.error

    def __init__(self):
        self.calls = []

    def rayTestBatch(self, starts, ends, collisionFilterMask, numThreads):  # noqa: N802,N803
        self.calls.append((len(starts), numThreads))
        return [(-1, -1, 1.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))] * len(starts)


def test_only_a_call_of_enough_rays_is_threaded():
    client = _Recorder()
    for count in (1, THREADED_RAYS_MIN - 1, THREADED_RAYS_MIN, 360):
        cast_rays(client, *circle((0.0, 0.0, 0.0), count), threads=2)
    assert client.calls == [(1, 1), (THREADED_RAYS_MIN - 1, 1), (THREADED_RAYS_MIN, 2),
                            (360, 2)]
    # A cast split into batches threads each batch by its own size.
    cast_rays(client, *circle((0.0, 0.0, 0.0), 300), threads=2, batch_size=200)
    assert client.calls[-2:] == [(200, 2), (100, 1)]


def test_threads_below_one_are_refused():
    with pytest.raises(ValueError, match='threads must be 1 or more, got 0'):
        cast_rays(_Recorder(), *circle((0.0, 0.0, 0.0), 4), threads=0)
