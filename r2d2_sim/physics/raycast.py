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

The mask is one per ``rayTestBatch`` call, so each robot's rays go in a call
of their own (:func:`cast_requests`: the simulation casts every robot's rays
of a step there, a robot's laser and 3D lidar together). Measured on
PyBullet 3.2.7's wheel, the calls are not what a scan costs: a call costs
2.3 us, a ray 0.2-3 us, most of it testing every shape whose bounding box
it crosses, the caster's own robot included (PyBullet applies the mask
after the test; R2D2's laser sits inside its body: 0.3 ms of a 0.5 ms
scan). Putting robots out of each other's reach into one call (exact, with
a mask through both) was tried: finding them cost more than the calls
saved. Starting rays where they leave the robot's own shapes made a scan
slower (0.7 ms: rays that start on a surface cost more), starting them
outside its bounding boxes would hide what lies within.

**Hidden links.** Bullet asks each shape a ray's box crosses whether the ray
"needs" it before testing it: ``(group of the ray & mask of the link) != 0``,
and PyBullet casts every ray in group 1. A link whose mask lacks bit 1
(:data:`HIDDEN_MASK`) is therefore never tested by any ray, which costs
nothing and answers exactly what masking its hits did, as long as no ray
should see it: while a robot is the only one casting rays in its world,
:func:`exclude_from_rays` with ``hidden`` takes R2D2's own links out of its
scans (a 360-beam scan: 510 -> 159 us in the empty world, 935 -> 581 us in
the room, bit for bit the same ranges). Collisions stay as they were: under
PyBullet's pair filter ((group A & mask B) or (group B & mask A)) a link in
a group of its own above 2 meets every body whose mask holds its group,
which every default mask and every ray group's does. Putting a link back
in sight re-inserts it into the broadphase, which can change the order of
later contacts, so :class:`~r2d2_sim.physics.world.SimWorld` hides only
where that will not be needed (see :meth:`SimWorld.exclude_from_rays`).

``rayTestBatch``'s ``numThreads`` casts a call's rays on that many threads,
each ray alone: the answers are the same bit for bit (compared), and the
wall time falls while the CPU time stays (16 R2D2 scans of 360 beams in a
row of robots: 20.3 ms on one thread, 11.7 ms wall and 21.9 ms CPU on two;
one batch of 16,383 rays 59.7 ms, then 33.4 ms). Waking the threads costs
~50 us a call (8 rays: 9 us on one thread, 49 us on two), so only a call of
:data:`THREADED_RAYS_MIN` rays or more is threaded (``threads`` below; the
simulation's is the ``ray_threads`` parameter).
"""

from typing import Dict, List, NamedTuple, Optional, Sequence, Tuple

import numpy
from numpy.typing import ArrayLike

from r2d2_sim.physics.stdio import silenced_output

with silenced_output():  # PyBullet prints its build time on import (bullet_client imports it)
    import pybullet
from pybullet_utils.bullet_client import BulletClient  # noqa: I100 (after the quiet import)

__all__ = ['RAY_EXCLUDED_GROUP', 'RAY_MASK', 'HIDDEN_MASK', 'SHOWN_MASK', 'ray_mask',
           'exclude_from_rays', 'cast_rays',
           'RayRequest', 'plan_calls', 'cast_requests', 'THREADED_RAYS_MIN']

RAY_EXCLUDED_GROUP = 4
# PyBullet 3.2.7 names 16,384 its limit, but a batch of exactly that many
# returns no results at all (and one more raises): 16,383 is the most a call takes.
MAX_BATCH_SIZE = pybullet.MAX_RAY_INTERSECTION_BATCH_SIZE - 1


def ray_mask(group: int) -> int:
    """Return the mask of rays that pass through ``group`` and hit every other group."""
    return -1 ^ group  # as the C int rayTestBatch takes: ~group in two's complement


# All bits but 4 (-5).
RAY_MASK = ray_mask(RAY_EXCLUDED_GROUP)
# The collision filter group PyBullet casts every ray in (Bullet's DefaultFilter).
BULLET_RAY_GROUP = 1
# A link's mask with rays, as PyBullet leaves it: every ray tests the link's shapes.
SHOWN_MASK = -1
# A link's mask that no ray tests: every bit but the rays' group (see Hidden links above).
HIDDEN_MASK = -1 ^ BULLET_RAY_GROUP
# The fewest rays a call casts on more than one thread: below about 100 (R2D2's scan,
# measured), waking the threads costs more than they save.
THREADED_RAYS_MIN = 128


def exclude_from_rays(client: BulletClient, body_id: int,
                      links: Optional[Sequence[int]] = None,
                      group: int = RAY_EXCLUDED_GROUP, hidden: bool = False) -> None:
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
    0.4 ms of a 1 ms 360-beam scan in room.urdf. ``hidden``: with
    :data:`HIDDEN_MASK`, so that no ray tests them at all (see Hidden links).
    """
    mask = HIDDEN_MASK if hidden else SHOWN_MASK
    for link in range(-1, client.getNumJoints(body_id)) if links is None else links:
        client.setCollisionFilterGroupMask(body_id, link, group, mask)


def cast_rays(client: BulletClient, starts: ArrayLike, ends: ArrayLike, mask: int = RAY_MASK, *,
              batch_size: int = MAX_BATCH_SIZE, threads: int = 1) -> numpy.ndarray:
    """
    Cast rays from ``starts`` to ``ends`` (N x 3, world) and return the hit fractions.

    A fraction f means the first hit is at start + f * (end - start); 1.0
    means no hit. Batches of at most ``batch_size`` rays keep within PyBullet's
    limit (:data:`MAX_BATCH_SIZE`, one less than its MAX_RAY_INTERSECTION_BATCH_SIZE).
    A batch of :data:`THREADED_RAYS_MIN` rays or more is cast on ``threads``
    threads (the same answers, sooner when the cores are free).
    """
    starts_m = numpy.asarray(starts, dtype=float)
    ends_m = numpy.asarray(ends, dtype=float)
    if starts_m.ndim != 2 or starts_m.shape[1] != 3 or starts_m.shape != ends_m.shape:
        raise ValueError(f'starts and ends must both be N x 3, got shapes '
                         f'{starts_m.shape} and {ends_m.shape}')
    if not 1 <= batch_size <= MAX_BATCH_SIZE:
        raise ValueError(f'batch_size must be in [1, {MAX_BATCH_SIZE}], got {batch_size}')
    if threads < 1:
        raise ValueError(f'threads must be 1 or more, got {threads}')
    fractions: List[float] = []
    for first in range(0, len(starts_m), batch_size):
        batch = starts_m[first:first + batch_size]
        count = len(batch)
        hits = client.rayTestBatch(batch, ends_m[first:first + batch_size],
                                   collisionFilterMask=mask,
                                   numThreads=threads if count >= THREADED_RAYS_MIN else 1)
        if len(hits) != count:
            raise RuntimeError(f'rayTestBatch answered {len(hits)} of {count} rays')
        # Indexing beats unpacking each hit's five fields (14 against 20 us for 360 rays).
        fractions.extend([hit[2] if hit[0] != -1 else 1.0 for hit in hits])
    return numpy.array(fractions, dtype=float)


class RayRequest(NamedTuple):
    """One sensor's rays for one step, and the collision bit of the links they pass through."""

    starts: numpy.ndarray  # N x 3, world
    ends: numpy.ndarray    # N x 3, world
    group: int = 0         # the robot's ray group (0: none; the rays then hit everything)


def plan_calls(requests: Sequence[RayRequest]) -> List[Tuple[List[int], int]]:
    """
    Return the calls to cast ``requests`` in: (indices of the requests, mask), in order.

    One call per ray group (a robot's laser and 3D lidar share one), in the
    order the groups first appear; its mask passes through that group only.
    """
    calls: Dict[int, List[int]] = {}
    for i, request in enumerate(requests):
        calls.setdefault(request.group, []).append(i)
    return [(members, ray_mask(group)) for group, members in calls.items()]


def cast_requests(client: BulletClient, requests: Sequence[RayRequest],
                  threads: int = 1) -> List[numpy.ndarray]:
    """
    Cast every request's rays in the calls :func:`plan_calls` plans; return each one's fractions.

    Each ray's answer is the one a call of its own with ``ray_mask(group)``
    would give, bit for bit (``threads``: see :func:`cast_rays`).
    """
    results: Dict[int, numpy.ndarray] = {}  # by request: plan_calls puts each in one call
    for members, mask in plan_calls(requests):
        if len(members) == 1:
            starts, ends = requests[members[0]].starts, requests[members[0]].ends
        else:
            starts = numpy.concatenate([requests[j].starts for j in members])
            ends = numpy.concatenate([requests[j].ends for j in members])
        fractions = cast_rays(client, starts, ends, mask, threads=threads)
        first = 0
        for j in members:
            count = len(requests[j].starts)
            results[j] = fractions[first:first + count]
            first += count
    return [results[i] for i in range(len(requests))]
