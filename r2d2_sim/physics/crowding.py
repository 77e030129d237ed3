"""
How crowded the moving bodies of a world are: what one request may hand Bullet to resolve.

No ROS. Bullet resolves every contact between moving bodies (multibodies,
as PyBullet loads URDFs) in the step after they were put into one another,
all at once, and the cost of that step grows steeply with their number
(measured on 2 busy cores, 0.3 m boxes, first step after loading): a pile of
8 at one point 3 ms, 16 (120 touching pairs) 30-45 ms, 23 (253 pairs)
130-150 ms, 40 (780 pairs) 1.3-4 s, 80 18 s; 80 stacked 10 high (466 pairs)
0.1 s, 1,000 stacked 27 s. A world of 200 links at one point held the node
(and SIGINT) for minutes. Bodies 5 mm apart cost nothing; resting contacts
cost little after that first step (1,000 stacked: 65 ms a step). So a
request (LoadWorld, SpawnEntity, SetEntityState) may leave at most
MAX_TOUCHING_PAIRS pairs of moving links touching or overlapping (links of
two different bodies: PyBullet loads URDFs without self-collision), and a
world holds at most MAX_MOVING_LINKS moving links, which also bounds the
count itself.

:func:`check_crowding` is the check: the links of the bodies a request
placed against every moving link of the world, by their bounding boxes and
then by Bullet's own closest-point query (which changes nothing in the
world), within a bounded number of queries. A RefusedError (one line, the
caller's code) says what was found.
"""

from functools import partial
from typing import Dict, List, NamedTuple, Optional, Sequence, Tuple

import numpy

from r2d2_sim.errors import RefusedError
from r2d2_sim.physics.body import Body
from r2d2_sim.physics.records import Quat, Vec3
from r2d2_sim.physics.stdio import silenced_output
from r2d2_sim.physics.world import SimWorld

with silenced_output():  # PyBullet prints its build time on import
    import pybullet
from pybullet_utils.bullet_client import BulletClient  # noqa: I100 (after the quiet import)

__all__ = ['check_crowding', 'check_placements', 'Placement', 'moving_links', 'touching_pairs',
           'MAX_MOVING_LINKS', 'MAX_TOUCHING_PAIRS', 'MAX_NEAR_PAIRS', 'TOUCH_DISTANCE_M']

# Links that move, in one world (each body's base counted when it moves): the
# warehouse of bench/sdf_world.py has 22; 32 robots of 15 links, 480.
MAX_MOVING_LINKS = 2000
# Pairs of moving links of different bodies touching or overlapping at once after a
# request placed bodies (first step at this bound, as measured above: 0.15 s or less).
MAX_TOUCHING_PAIRS = 256
# Pairs of moving links whose bounding boxes meet, each then asked of Bullet (about
# 10 us each); a world with more is refused before it is asked.
MAX_NEAR_PAIRS = 8192
# Closer than this counts as touching (Bullet makes no contact for boxes 5 mm apart).
TOUCH_DISTANCE_M = 0.001

Link = Tuple[Body, int]


def moving_links(body: Body) -> List[int]:
    """
    Return the link indices of ``body`` that can move (-1 for its base).

    A free base moves every link with it; under a fixed base, the links
    below a joint with a degree of freedom.
    """
    joints = sorted(body.joints.values(), key=lambda joint: joint.index)
    if not body.fixed_base:
        return [-1] + [joint.index for joint in joints]
    moving: List[int] = []
    for joint in joints:  # PyBullet numbers a parent before its children
        if joint.movable or joint.parent_index in moving:
            moving.append(joint.index)
    return moving


def _boxes(client: BulletClient, links: Sequence[Link]) -> numpy.ndarray:
    """Return the links' bounding boxes, grown by TOUCH_DISTANCE_M: (N, 2, 3)."""
    # pybullet's function itself: BulletClient's attribute lookup costs twice the call.
    aabb = partial(pybullet.getAABB, physicsClientId=client._client)
    boxes = numpy.array([aabb(body.id, link) for body, link in links], dtype=float)
    boxes[:, 0] -= TOUCH_DISTANCE_M
    boxes[:, 1] += TOUCH_DISTANCE_M
    return boxes.reshape(-1, 2, 3)


def _near_pairs(boxes: numpy.ndarray, owners: numpy.ndarray, placed: numpy.ndarray
                ) -> numpy.ndarray:
    """Return index pairs (i < j) of different bodies whose boxes meet, one of them placed."""
    low, high = boxes[:, 0], boxes[:, 1]
    rows = numpy.flatnonzero(placed)
    meet = numpy.all((low[rows, None, :] <= high[None, :, :]) &
                     (low[None, :, :] <= high[rows, None, :]), axis=2)
    meet &= owners[rows, None] != owners[None, :]
    first, second = numpy.nonzero(meet)
    first = rows[first]
    pairs = numpy.stack([numpy.minimum(first, second), numpy.maximum(first, second)], axis=1)
    return numpy.unique(pairs, axis=0) if len(pairs) else pairs.reshape(0, 2)


def touching_pairs(client: BulletClient, links: Sequence[Link], placed: Sequence[bool],
                   limit: int) -> int:
    """
    Count pairs of ``links`` (of different bodies, one of them ``placed``) that touch.

    Stops counting past ``limit``. RefusedError-free: a caller decides;
    ValueError when more than MAX_NEAR_PAIRS pairs would have to be asked.
    """
    if not links or not any(placed):
        return 0
    boxes = _boxes(client, links)
    owners = numpy.array([id(body) for body, _ in links])
    pairs = _near_pairs(boxes, owners, numpy.array(placed, dtype=bool))
    if len(pairs) > MAX_NEAR_PAIRS:
        raise ValueError(f'more than {MAX_NEAR_PAIRS} pairs of moving links lie within each '
                         'other\'s bounding boxes')
    count = 0
    for i, j in pairs.tolist():
        (body_a, link_a), (body_b, link_b) = links[i], links[j]
        if client.getClosestPoints(body_a.id, body_b.id, TOUCH_DISTANCE_M, linkIndexA=link_a,
                                   linkIndexB=link_b):
            count += 1
            if count > limit:
                break
    return count


def check_crowding(client: BulletClient, bodies: Sequence[Body], placed: Sequence[Body], code: str,
                   what: str) -> None:
    """
    Refuse (RefusedError ``code``, naming ``what``) a placing that crowds the moving bodies.

    ``bodies`` are all of the world's, ``placed`` those the request put where
    they are (loaded, spawned or moved). Refused: more than MAX_MOVING_LINKS
    moving links in ``bodies``; or, when a placed body's moving link touches
    another body's, more than MAX_TOUCHING_PAIRS pairs touching in the world.
    """
    moving: Dict[int, List[int]] = {id(body): moving_links(body) for body in bodies}
    count = sum(len(links) for links in moving.values())
    if count > MAX_MOVING_LINKS:
        raise RefusedError(code, f'{what}: the world would have {count} moving links, more '
                                 f'than {MAX_MOVING_LINKS}')
    placed_ids = {id(body) for body in placed}
    links = [(body, link) for body in bodies for link in moving[id(body)]]
    if not any(id(body) in placed_ids for body, _ in links):
        return
    try:
        if not touching_pairs(client, links, [id(body) in placed_ids for body, _ in links], 0):
            return  # what was placed touches no other moving link
        touching = touching_pairs(client, links, [True] * len(links), MAX_TOUCHING_PAIRS)
    except ValueError as exc:
        raise RefusedError(code, f'{what}: {exc}') from None
    if touching > MAX_TOUCHING_PAIRS:
        raise RefusedError(code, f'{what} puts moving bodies into one another: more than '
                                 f'{MAX_TOUCHING_PAIRS} pairs of their links touch at once '
                                 '(Bullet would resolve them all in one step, for seconds or '
                                 'minutes); set them apart')


class Placement(NamedTuple):
    """A body a world will load: its URDF file, pose, loadURDF flags, what it is made from."""

    path: str
    position: Vec3
    orientation: Quat
    flags: int = 0
    made_from: Optional[str] = None   # as SimWorld.load takes it
    given_as: Optional[str] = None    # as SimWorld.load takes it


def check_placements(placements: Sequence[Placement], time_step_s: float, code: str,
                     what: str) -> None:
    """
    Refuse (RefusedError ``code``) bodies a world would load that crowd one another.

    Each is loaded into a scratch world of its own (no ground: resting on it
    costs nothing), the moving links counted as they come, so a world of too
    many is refused before all are loaded; then :func:`check_crowding`.
    WorldError if one cannot be loaded.
    """
    if not placements:
        return
    with SimWorld(ground_plane=False, time_step_s=time_step_s) as scratch:
        bodies, count = [], 0
        for placement in placements:
            body = scratch.load(placement.path, placement.position, placement.orientation,
                                flags=placement.flags, made_from=placement.made_from,
                                given_as=placement.given_as)
            bodies.append(body)
            count += len(moving_links(body))
            if count > MAX_MOVING_LINKS:
                raise RefusedError(code, f'{what} has more than {MAX_MOVING_LINKS} moving links')
        check_crowding(scratch.client, bodies, bodies, code, what)
