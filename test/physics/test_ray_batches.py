"""
Rays beyond one rayTestBatch call: every ray gets its answer, however many there are.

PyBullet 3.2.7 says a call takes MAX_RAY_INTERSECTION_BATCH_SIZE (16,384)
rays, but a call of exactly that many returns nothing at all; a 16 x 1800
lidar (28,800 rays) then lost its first 16,384. Casts of 16,383 to 40,000
rays against a plane must answer each ray with the plane's distance.
"""

import numpy
import pytest

from r2d2_sim.physics.raycast import cast_rays, MAX_BATCH_SIZE
from r2d2_sim.physics.world import SimWorld


@pytest.mark.parametrize('count', [16_383, 16_384, 16_385, 28_800, 40_000])
def test_every_ray_of_a_large_cast_is_answered(count):
    with SimWorld() as world:
        starts = numpy.zeros((count, 3)) + [0.0, 0.0, 2.0]
        starts[:, 0] = numpy.arange(count) * 0.001  # not one ray repeated
        ends = starts - [0.0, 0.0, 4.0]
        fractions = cast_rays(world.client, starts, ends)
    assert fractions.shape == (count,)
    assert fractions == pytest.approx(numpy.full(count, 0.5), abs=1e-6)


def test_the_batch_size_is_what_pybullet_answers():
    with SimWorld() as world:
        starts = numpy.zeros((MAX_BATCH_SIZE, 3)) + [0.0, 0.0, 1.0]
        hits = world.client.rayTestBatch(starts, starts - [0.0, 0.0, 2.0])
    assert len(hits) == MAX_BATCH_SIZE
