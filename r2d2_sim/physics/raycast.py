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

The mask is one per ``rayTestBatch`` call, so rays that must pass through
different robots go in different calls, unless they cannot reach each
other's robot: :func:`cast_requests` casts every sensor's rays of a step in
as few calls as that allows, each ray exactly as a call of its own would
(PyBullet filters by mask after testing a shape, so a mask that also drops a
robot a ray cannot reach changes nothing). Two things measured on PyBullet
3.2.7's wheel bound what batching can save: rays still test every shape
whose bounding box they cross, the caster's own robot included (about 0.3
ms of a 360-beam scan: its laser sits inside its body), and
``rayTestBatch``'s ``numThreads`` does nothing in this build (16,383 rays:
29-31 ms of wall and CPU time alike at 1, 2, 4 or 0 threads).
"""

from typing import List, NamedTuple, Optional, Sequence, Tuple

import numpy

from r2d2_sim.physics.stdio import silenced_output

with silenced_output():  # PyBullet prints its build time on import (bullet_client imports it)
    import pybullet
from pybullet_utils.bullet_client import BulletClient  # noqa: I100 (after the quiet import)

__all__ = ['RAY_EXCLUDED_GROUP', 'RAY_MASK', 'ray_mask', 'exclude_from_rays', 'cast_rays',
           'RayRequest', 'plan_calls', 'cast_requests']

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


Box = Tuple[Tuple[float, float, float], Tuple[float, float, float]]  # (low, high) corners


class RayRequest(NamedTuple):
    """
    One sensor's rays for one step: where they go, and the robot they pass through.

    ``group`` is the collision bit of the links the rays pass through (the
    robot's ray group; 0: none), ``links_box`` those links' bounding box now
    (None without a group): another robot's rays that cannot reach that box
    may share a call with these. ``reach``: a box that holds every ray (None:
    computed from them; a sensor's rays from one origin, at most R long,
    give origin +- R for nothing).
    """

    starts: numpy.ndarray  # N x 3, world
    ends: numpy.ndarray    # N x 3, world
    group: int = 0
    links_box: Optional[Box] = None
    reach: Optional[Box] = None


def _reach(request: RayRequest) -> Box:
    """Return the box that holds every ray of a request (its segments lie within)."""
    if request.reach is not None:
        return request.reach
    starts, ends = request.starts, request.ends
    return (tuple(numpy.minimum(starts.min(axis=0), ends.min(axis=0)).tolist()),
            tuple(numpy.maximum(starts.max(axis=0), ends.max(axis=0)).tolist()))


def _meet(a: Optional[Box], b: Optional[Box], margin_m: float = 0.01) -> bool:
    """Return True when two boxes overlap, or come within ``margin_m`` of each other."""
    if a is None or b is None:
        return False
    return all(a[0][k] - margin_m <= b[1][k] and b[0][k] - margin_m <= a[1][k]
               for k in range(3))


def plan_calls(requests: Sequence[RayRequest]) -> List[Tuple[List[int], int]]:
    """
    Return the calls to cast ``requests`` in: (indices of the requests, mask), in order.

    A call's mask passes through every group in it. A request joins the
    first call where its rays cannot reach the links of any other group in
    it and no other group's rays can reach its own (boxes apart by more than
    a centimetre): there, passing through those links too changes nothing.
    Requests of one group always share a call. Greedy, in request order.
    """
    if len({request.group for request in requests}) == 1:
        return [(list(range(len(requests))), ray_mask(requests[0].group))] if requests else []
    reaches = [_reach(request) for request in requests]
    calls: List[Tuple[List[int], int]] = []
    for i, request in enumerate(requests):
        for members, groups in calls:
            if all(requests[j].group == request.group
                   or not (_meet(reaches[i], requests[j].links_box)
                           or _meet(reaches[j], request.links_box))
                   for j in members):
                members.append(i)
                break
        else:
            calls.append(([i], 0))
    result = []
    for members, _ in calls:
        groups = 0
        for j in members:
            groups |= requests[j].group
        result.append((members, -1 ^ groups))
    return result


def cast_requests(client: BulletClient, requests: Sequence[RayRequest]) -> List[numpy.ndarray]:
    """
    Cast every request's rays in the calls :func:`plan_calls` plans; return each one's fractions.

    Each ray's answer is the one a call of its own with ``ray_mask(group)``
    would give, bit for bit.
    """
    results: List[Optional[numpy.ndarray]] = [None] * len(requests)
    for members, mask in plan_calls(requests):
        if len(members) == 1:
            starts, ends = requests[members[0]].starts, requests[members[0]].ends
        else:
            starts = numpy.concatenate([requests[j].starts for j in members])
            ends = numpy.concatenate([requests[j].ends for j in members])
        fractions = cast_rays(client, starts, ends, mask)
        first = 0
        for j in members:
            count = len(requests[j].starts)
            results[j] = fractions[first:first + count]
            first += count
    return results
