"""
Rays in a PyBullet world, with the robot left out of its own sensor's rays.

No ROS here. ``rayTestBatch(..., collisionFilterMask=mask)`` reports an object
only if (its collision filter group & mask) != 0. Bullet's default groups are
1 for dynamic links and 2 for static bodies, whose masks are all bits and all
but 2. :func:`exclude_from_rays` moves a body into group 4 with a full mask,
and rays cast with :data:`RAY_MASK` (every bit but 4) pass through it: a laser
inside the robot sees the world, not the robot. With several robots each
takes a bit of its own (4, 8, 16...): its rays pass through its own links and
hit every other robot's. Its contacts are kept under
either pair filter PyBullet offers (``collisionFilterMode``): the default
(group A & mask B) or (group B & mask A), and the stricter "and", since
the group & every other body's mask and their groups & -1 are all non-zero.
"""

from typing import Optional, Sequence

import numpy

from r2d2_sim.physics.stdio import silenced_output

with silenced_output():  # PyBullet prints its build time on import (bullet_client imports it)
    import pybullet
from pybullet_utils.bullet_client import BulletClient  # noqa: I100 (after the quiet import)

__all__ = ['RAY_EXCLUDED_GROUP', 'RAY_MASK', 'ray_mask', 'exclude_from_rays', 'cast_rays']

RAY_EXCLUDED_GROUP = 4
# PyBullet 3.2.7 names 16,384 its limit, but a batch of exactly that many
# returns no results at all (and one more raises): 16,383 is the most a call takes.
MAX_BATCH_SIZE = pybullet.MAX_RAY_INTERSECTION_BATCH_SIZE - 1


def ray_mask(group: int) -> int:
    """Return the mask of rays that pass through ``group`` and hit every other group."""
    return -1 ^ group  # as the C int rayTestBatch takes: ~group in two's complement


# All bits but 4 (-5).
RAY_MASK = ray_mask(RAY_EXCLUDED_GROUP)


def exclude_from_rays(client: BulletClient, body_id: int,
                      links: Optional[Sequence[int]] = None,
                      group: int = RAY_EXCLUDED_GROUP) -> None:
    """
    Make links of a body (default: all, -1 being the base) invisible to rays of ``group``.

    Rays cast with ``ray_mask(group)`` (RAY_MASK for the default group) pass through them.
    Several robots each take a group bit of their own (SimWorld.take_ray_group),
    so one robot's rays pass through its own links and hit the others'.

    Their collisions are kept: the full mask lets them meet every group. Bullet
    re-inserts the links into its broadphase, which can change the order in
    which simultaneous contacts are solved, not whether they happen: for
    R2D2's wheels that changed arc slip from 8.8 to 10.4 %, so callers exclude
    only the links a sensor's rays can meet. Rays still test the shapes
    (PyBullet drops masked hits after computing them): R2D2 costs about
    0.4 ms of a 1 ms 360-beam scan in room.urdf.
    """
    for link in range(-1, client.getNumJoints(body_id)) if links is None else links:
        client.setCollisionFilterGroupMask(body_id, link, group, -1)


def cast_rays(client: BulletClient, starts: Sequence[Sequence[float]],
              ends: Sequence[Sequence[float]], mask: int = RAY_MASK, *,
              batch_size: int = MAX_BATCH_SIZE) -> numpy.ndarray:
    """
    Cast rays from ``starts`` to ``ends`` (N x 3, world) and return the hit fractions.

    A fraction f means the first hit is at start + f * (end - start); 1.0
    means no hit. Batches of at most ``batch_size`` rays keep within PyBullet's
    limit (:data:`MAX_BATCH_SIZE`, one less than its MAX_RAY_INTERSECTION_BATCH_SIZE).
    """
    starts = numpy.asarray(starts, dtype=float)
    ends = numpy.asarray(ends, dtype=float)
    if starts.ndim != 2 or starts.shape[1] != 3 or starts.shape != ends.shape:
        raise ValueError(f'starts and ends must both be N x 3, got shapes '
                         f'{starts.shape} and {ends.shape}')
    if not 1 <= batch_size <= MAX_BATCH_SIZE:
        raise ValueError(f'batch_size must be in [1, {MAX_BATCH_SIZE}], got {batch_size}')
    fractions = []
    for first in range(0, len(starts), batch_size):
        hits = client.rayTestBatch(starts[first:first + batch_size],
                                   ends[first:first + batch_size],
                                   collisionFilterMask=mask)
        if len(hits) != len(starts[first:first + batch_size]):
            raise RuntimeError(f'rayTestBatch answered {len(hits)} of '
                               f'{len(starts[first:first + batch_size])} rays')
        fractions.extend(fraction if object_id != -1 else 1.0
                         for object_id, _, fraction, _, _ in hits)
    return numpy.array(fractions, dtype=float)
