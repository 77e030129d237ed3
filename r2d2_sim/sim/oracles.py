"""
What a scenario's verdict needs to know about a robot's run, measured by the physics each step.

No ROS here. :class:`RunWatch` follows one robot (or any entity) of a
:class:`~r2d2_sim.sim.simulation.Simulation` from the step it starts, in
simulated time:

- **contacts**: every body the robot touched (its own links and the ground
  plane aside), when it started, where on the robot, with which links, and
  how hard (the largest normal force seen while it lasted);
- **clearance**: the smallest distance between the robot and any other body
  (the ground aside) along the run, from the physics' closest points of the
  collision shapes, not from the laser, within a range (farther counts as the
  range);
- **regions**: when the robot's base first stood inside each region given
  (a box, circle or polygon on the ground, see :mod:`r2d2_sim.model.regions`),
  or inside a named pose's bounds seen from above (:func:`ground_region`);
- **tipping**: when the base first leaned further than the angle given;
- **trajectory**: with ``trajectory_period_s``, the base's x, y and yaw at
  that period of simulated time (a farm's map draws it).

:func:`touching` is the one contact reading: the watch keeps contacts from
it, and a robot with ``publish_contacts`` measures its ``contacts`` topic
with it.

It costs nothing unless made (the simulation calls its watches after each
step); made, one pose query a step (the base's centre of mass: the body
frame is worked out only near a region, near the tipping angle, or for a
trajectory sample), and the contacts and closest points of the bodies that
can be near. Only those are asked about: a body that stays where it is
put (static, no joints that move) is passed over while the robot's centre of
mass is outside its bounding box grown on every side by the robot's reach (a
radius that holds its links in any joint state, :meth:`Body.reach_m
<r2d2_sim.physics.body.Body.reach_m>`), :data:`NEAR_MARGIN_M` and the distance
that matters: for contacts, how far the centre of mass moved in the step
(Bullet finds a step's contacts before it moves the bodies; every body is
asked on a step after the robot was put somewhere), for closest points the
clearance so far.
No point PyBullet would have given can come from a body passed over, so the
watch reads the same as one that asks about every body (``prune=False``, what
the tests compare it with, bit for bit). A body is seen to move when it is
moved through the simulation or its :class:`~r2d2_sim.physics.body.Body` (a
spawn, a state set, a reset, a restore); one moved through the PyBullet client
directly is not: watch such a world with ``prune=False``.
"""

import math
from types import MappingProxyType
from typing import (
    Callable, Dict, List, Mapping, NamedTuple, Optional, Protocol, Sequence, Tuple,
    Union)

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.convex import box_corners
from r2d2_sim.model.regions import circle_region, polygon_region, Region
from r2d2_sim.model.transforms import apply, Transform, yaw_of
from r2d2_sim.physics.body import Body
from r2d2_sim.physics.records import ContactPoint, Quat, Vec3
from r2d2_sim.physics.world import GROUND_PLANE_NAME, SimWorld
from r2d2_sim.sim.settings.config import SimConfig
from r2d2_sim.sim.worlds.files import WorldFiles
from r2d2_sim.sim.worlds.world import NamedPose

__all__ = ['Contact', 'Clearance', 'Touch', 'RunWatch', 'TrajectoryPoint', 'touching',
           'ground_region',
           'DEFAULT_CLEARANCE_RANGE_M', 'DEFAULT_TIP_ANGLE_RAD']

# Closest points are looked for within this distance (m): farther bodies count as this.
DEFAULT_CLEARANCE_RANGE_M = 2.0
# Leaning more than this from upright (roll and pitch together) is tipping over.
DEFAULT_TIP_ANGLE_RAD = math.radians(45.0)
# Where a watched body's centre of mass must be for a rigid one to count: x0, y0, z0, x1, y1, z1.
Zone = Tuple[float, float, float, float, float, float]
# Slack on the bounds a watch passes bodies over by (m): their boxes and the reach hold
# the shapes already; this covers rounding and PyBullet's margins.
NEAR_MARGIN_M = 0.05
# Slack on the body frame's offset from the centre of mass, for rounding: a region is
# looked at closely when the centre of mass is within the offset, this (m) and the
# relative slack times the size of the coordinates of the region's box. PyBullet's
# multiplyTransforms rounds to float32 (2**-24 relative): 1.9e-6 m at x = 40 m.
FRAME_SLACK_M = 1e-6
FRAME_RELATIVE_SLACK = 2.0 ** -18
# Up to this many bodies, touching() asks PyBullet pair by pair (an empty pair is about 1
# us); more, it asks for every contact point of the body at once (about 8 us for R2D2,
# whose 16 wheel points on the ground come back too).
PAIRS_ASKED_ALONE = 4
# Slack on the leaning read from the centre of mass's orientation (a cosine), for rounding
# (the body frame's orientation comes from float32: up to 1.2e-6 apart, leaning 100-120
# degrees): within it of the limit, the body frame's own orientation decides.
TIP_SLACK = 1e-4


class Contact(NamedTuple):
    """The robot touching another body, from ``start_ns`` to ``end_ns`` (None: still)."""

    other: str                            # the other entity's name
    robot_link: str                       # the robot's link that touched first
    other_link: str                       # and the other body's
    start_ns: int                         # simulated time of the first step in contact
    end_ns: Optional[int]                 # of the first step out of contact again
    position: Tuple[float, float, float]  # where, on the robot, in the world, at the start
    max_normal_force_n: float             # the hardest push while it lasted


class Touch(NamedTuple):
    """A body touching another now: the strongest of their contact points after a step."""

    other: str                            # the other entity's name
    link: str                             # the touching body's link
    other_link: str                       # and the other body's
    position: Tuple[float, float, float]  # the point on the touching body, in the world
    normal_force_n: float


class TrajectoryPoint(NamedTuple):
    """Where the base was at ``time_ns``: x, y (m) and yaw (rad) in the world."""

    time_ns: int
    x_m: float
    y_m: float
    yaw_rad: float


def touching(world: SimWorld, body: Body, others: Optional[Sequence[Tuple[str, Body]]] = None
             ) -> List[Touch]:
    """
    Return what ``body`` touches after the last step of ``world`` (a SimWorld).

    One :class:`Touch` per other body, its own links and the ground plane
    aside: the contact point with the largest normal force. In the world's
    order of bodies, so that two runs list them alike. ``others`` (name,
    body) narrows the bodies looked at (those that can be near): none, no
    question; without the ground plane, each pair's points alone, the same
    as asking for every point of ``body`` (its wheels' on the ground too) and
    keeping those pairs', for less while they are few.
    """
    if others is not None and not others:
        return []
    bodies = world.bodies
    ground = bodies.get(GROUND_PLANE_NAME)
    strongest: Dict[int, ContactPoint] = {}
    points: Sequence[ContactPoint]
    if others is not None and len(others) <= PAIRS_ASKED_ALONE and all(
            other is not ground for _, other in others):
        points = body.contacts_with(*(other for _, other in others))
    else:
        points = body.contacts(ignoring=() if ground is None else (ground,))
    for point in points:
        best = strongest.get(point.body_b)
        if best is None or point.normal_force_n > best.normal_force_n:
            strongest[point.body_b] = point
    touches: List[Touch] = []
    if not strongest:
        return touches
    for name, other in bodies.items() if others is None else others:
        best = strongest.get(other.id) if other is not body else None
        if best is not None:
            touches.append(Touch(name, body.link_name(best.link_a),
                                 other.link_name(best.link_b), best.position_on_a,
                                 best.normal_force_n))
    return touches


class Clearance(NamedTuple):
    """The smallest distance between the robot and another body so far, and when and to what."""

    distance_m: float                     # negative: overlapping that much
    other: Optional[str]                  # None: nothing came within the range
    time_ns: Optional[int]


class _Robot(Protocol):
    @property
    def body(self) -> Body:
        """Return the robot's body."""


class WatchedSimulation(Protocol):
    """What a :class:`RunWatch` asks of the simulation it watches (a ``Simulation``)."""

    @property
    def config(self) -> SimConfig:
        """Return the simulation's settings (its physics rate)."""

    @property
    def world(self) -> SimWorld:
        """Return the physics world."""

    @property
    def robots(self) -> Sequence[_Robot]:
        """Return the robots, the first of them watched by default."""

    @property
    def worlds(self) -> WorldFiles:
        """Return the world files: the current world's named poses."""

    @property
    def time_ns(self) -> int:
        """Return the simulated time now (ns)."""

    def watch_steps(self, watcher: Callable[[int], None]) -> Callable[[], None]:
        """Call ``watcher`` with the time after every step; return what stops it."""


class RunWatch:
    """
    One robot's run as the physics saw it, from now on: contacts, clearance, regions, tipping.

    ``simulation`` is stepped by its owner as usual; the watch reads the
    world after each step until :meth:`close`. ``entity`` names what is
    watched: a robot (default: the first) or any other entity. ``regions``
    maps names to :class:`~r2d2_sim.model.regions.Region` s, or to the name
    of a named pose of the world (its bounds, :func:`ground_region`), whose
    first entry time is kept in :attr:`reached`; they are fixed when the watch
    is made (:attr:`regions` is read-only). ``trajectory_period_s`` (simulated
    seconds, rounded to whole steps; None: none kept) samples the base into
    :attr:`trajectory`: where it is now, then every period. ``clearance``
    False leaves the clearance out (it stays at the range): the closest
    points are most of what the watch costs, which a learning environment
    that ends an episode at the first contact does not need. ``prune`` False
    asks PyBullet about every other body at every step (the watch reads the
    same either way; see the module's docstring). ValueError for an unknown
    entity or a range, angle or period that is none.
    """

    def __init__(self, simulation: 'WatchedSimulation', entity: Optional[str] = None, *,
                 regions: Optional[Mapping[str, Union[Region, str]]] = None,
                 clearance_range_m: float = DEFAULT_CLEARANCE_RANGE_M,
                 tip_angle_rad: float = DEFAULT_TIP_ANGLE_RAD,
                 trajectory_period_s: Optional[float] = None,
                 clearance: bool = True, prune: bool = True) -> None:
        if not (math.isfinite(clearance_range_m) and clearance_range_m > 0.0):
            raise ValueError(f'clearance_range_m must be > 0, got {clearance_range_m}')
        if not (math.isfinite(tip_angle_rad) and 0.0 < tip_angle_rad < math.pi):
            raise ValueError(f'tip_angle_rad must be in (0, pi), got {tip_angle_rad}')
        self._sample_every = 0  # steps between trajectory samples; 0: none
        if trajectory_period_s is not None:
            if not (math.isfinite(trajectory_period_s) and trajectory_period_s > 0.0):
                raise ValueError(f'trajectory_period_s must be > 0, got {trajectory_period_s}')
            self._sample_every = max(1, round(trajectory_period_s * simulation.config
                                              .physics_rate_hz))
        self._simulation = simulation
        bodies = simulation.world.bodies
        if entity is None and not simulation.robots:
            raise ValueError('the world has no robot: name the entity to watch')
        body = simulation.robots[0].body if entity is None else bodies.get(entity)
        if body is None:
            raise ValueError(f'no entity named {entity!r}; the world has: {", ".join(bodies)}')
        self.body: Body = body
        self.name = body.name
        self.regions: Mapping[str, Region] = MappingProxyType({
            name: _named_region(simulation, region) if isinstance(region, str) else region
            for name, region in (regions or {}).items()})
        self.clearance_range_m = clearance_range_m
        self.tip_cos = math.cos(tip_angle_rad)
        self.contacts: List[Contact] = []
        self.clearance = Clearance(clearance_range_m, None, None)
        self._measure_clearance = clearance
        self.reached: Dict[str, int] = {}
        self.tipped_ns: Optional[int] = None
        self.trajectory: List[TrajectoryPoint] = []
        self.start_ns = simulation.time_ns
        self.steps = 0
        self._open: Dict[str, int] = {}  # other entity -> index of its contact still going
        # None: every body is asked about at every step (a reach without bound, or prune off).
        self._reach = body.reach_m() if prune else None
        # A rigid body's zone (_zone) as last read, by name: (the body, its moves then, zone).
        self._zones: Dict[str, Tuple[Body, int, Zone]] = {}
        # The other bodies (the ground aside), each with its zone (None: not rigid), and the
        # world's bodies and Body.any_moves they were listed at.
        self._around: List[Tuple[str, Body, Optional[Zone]]] = []
        self._around_key: Optional[Tuple[int, int, int]] = None
        # Where the centre of mass was after the last step, and the body's moves then: a
        # step's contacts are found where it stood before the step (see observe).
        self._last: Optional[Tuple[Tuple[float, ...], int]] = None
        # How far outside every rigid body's zone the centre of mass was when they were last
        # looked at one by one, less how far it has moved since (see _near).
        self._free_m = -math.inf
        # The body frame's origin is this far from the centre of mass (and rounding): the
        # regions are looked at closely only when the centre of mass is this near.
        com_to_body = body.com_to_body
        offset_m = math.hypot(*com_to_body[0])
        # The body frame's z axis in the centre of mass's frame: tipping from its pose.
        self._up_in_com = _z_axis(com_to_body[1])
        # Each region not reached yet, with its box on the ground grown by the offset.
        self._pending: List[Tuple[str, Region, Tuple[float, float, float, float]]] = [
            (name, region, _grown_box(region, offset_m)) for name, region in self.regions.items()]
        if self._sample_every:
            base = self.body.world_state()
            self.trajectory.append(TrajectoryPoint(self.start_ns, base.position[0],
                                                   base.position[1], yaw_of(base.orientation)))
        self._unwatch = simulation.watch_steps(self.observe)

    def observe(self, time_ns: int) -> None:
        """Read the world after a step at ``time_ns`` (the simulation calls this)."""
        body = self.body
        if not body.alive:
            return  # it left the world: nothing more to see
        self.steps += 1
        com, com_orientation = body.com_pose()
        if self._reach is None:
            others = [(name, other) for name, other, _ in self._others()]
            self._contacts(body, time_ns, others)
            if self._measure_clearance:
                self._clearance(body, time_ns, others)
        else:
            near, in_range = self._near(body, com)
            self._contacts(body, time_ns, near)
            if self._measure_clearance:
                self._clearance(body, time_ns, in_range)
        # The body frame's pose is worked out only when a reading needs it exactly: from
        # the centre of mass, PyBullet's multiplyTransforms as world_pose does.
        pose: Optional[Tuple[Vec3, Quat]] = None
        if self._pending:
            cx, cy = com[0], com[1]
            for entry in self._pending:
                name, region, (x0, y0, x1, y1) = entry
                if x0 <= cx <= x1 and y0 <= cy <= y1:
                    if pose is None:
                        pose = body.pose_of_com(com, com_orientation)
                    if region.contains(pose[0][0], pose[0][1]):
                        self.reached[name] = time_ns
                        self._pending = [p for p in self._pending if p is not entry]
        if self.tipped_ns is None and (_up_cos_of(com_orientation, self._up_in_com)
                                       < self.tip_cos + TIP_SLACK):
            if pose is None:
                pose = body.pose_of_com(com, com_orientation)
            if _up_cos(pose[1]) < self.tip_cos:
                self.tipped_ns = time_ns
        if self._sample_every and self.steps % self._sample_every == 0:
            if pose is None:
                pose = body.pose_of_com(com, com_orientation)
            (x, y, _), orientation = pose
            self.trajectory.append(TrajectoryPoint(time_ns, x, y, yaw_of(orientation)))

    def _others(self) -> List[Tuple[str, Body, Optional[Zone]]]:
        """Return every other body but the ground, with its zone (None: it is not rigid)."""
        bodies = self._simulation.world.bodies
        key = (Body.any_moves, id(bodies), len(bodies))
        if key != self._around_key:
            body, reach = self.body, self._reach
            self._around = [
                (name, other, self._zone(name, other, reach)
                 if other.rigid and reach is not None else None)
                for name, other in bodies.items()
                if other is not body and name != GROUND_PLANE_NAME]
            self._around_key = key
            self._free_m = -math.inf
        return self._around

    def _near(self, body: Body, com: Vec3) -> Tuple[List[Tuple[str, Body]],
                                                    List[Tuple[str, Body]]]:
        """
        Return the bodies that may touch the robot, and those nearer than its clearance.

        Bullet finds a step's contacts where the bodies stood before it, and
        then moves them: the centre of mass was at most its travel in the step
        from where it is now. Unknown (the first step watched, or the body put
        somewhere since the last): every body is asked about. Closest points
        are asked where the bodies stand: no travel, the clearance so far.
        """
        around = self._others()
        last, moves = self._last, body.moves
        travel = math.dist(com, last[0]) if last is not None and last[1] == moves else math.inf
        self._last = (com, moves)
        slack = max(self.clearance.distance_m, 0.0) if self._measure_clearance else -1.0
        # The centre of mass was _free_m outside every zone (Chebyshev distance), and has
        # moved at most travel since: if that is more than both distances, no rigid body
        # is near, and there are no others.
        free = self._free_m - travel
        if free > travel and free > slack:
            self._free_m = free
            return [], []
        x, y, z = com
        near: List[Tuple[str, Body]] = []      # those that may touch the robot
        in_range: List[Tuple[str, Body]] = []  # those that may be nearer than the clearance
        free = math.inf
        for name, other, zone in around:
            if zone is None:
                near.append((name, other))
                in_range.append((name, other))
                free = -math.inf
                continue
            x0, y0, z0, x1, y1, z1 = zone
            outside = max(x0 - x, x - x1, y0 - y, y - y1, z0 - z, z - z1)
            if outside <= travel:
                near.append((name, other))
            if outside <= slack:
                in_range.append((name, other))
            free = min(free, outside)
        self._free_m = free
        return near, in_range

    def _zone(self, name: str, other: Body, reach: float) -> Zone:
        """
        Return where the robot's centre of mass must be for ``other`` (rigid) to touch it.

        Its bounding box grown by the reach and the margin on every side: a
        centre of mass outside is farther than that from the box, so no shape
        of the robot meets one of ``other``; grown by a distance more, the
        same holds for the closest points within that distance.
        """
        known = self._zones.get(name)
        if known is None or known[0] is not other or known[1] != other.moves:
            (x0, y0, z0), (x1, y1, z1) = other.bounds()
            grow = reach + NEAR_MARGIN_M
            known = self._zones[name] = (other, other.moves, (
                x0 - grow, y0 - grow, z0 - grow, x1 + grow, y1 + grow, z1 + grow))
        return known[2]

    def _contacts(self, body: Body, time_ns: int, others: List[Tuple[str, Body]]) -> None:
        touches = {touch.other: touch
                   for touch in touching(self._simulation.world, body, others)}
        if not touches and not self._open:
            return
        for name in [n for n in self._open if n not in touches]:
            ended = self._open.pop(name)
            self.contacts[ended] = self.contacts[ended]._replace(end_ns=time_ns)
        for name, touch in touches.items():
            index = self._open.get(name)
            if index is None:
                self._open[name] = len(self.contacts)
                self.contacts.append(Contact(name, touch.link, touch.other_link, time_ns, None,
                                             touch.position, touch.normal_force_n))
            elif touch.normal_force_n > self.contacts[index].max_normal_force_n:
                self.contacts[index] = self.contacts[index]._replace(
                    max_normal_force_n=touch.normal_force_n)

    def _clearance(self, body: Body, time_ns: int, others: List[Tuple[str, Body]]) -> None:
        # Only what is nearer than the smallest distance so far can change it:
        # asking for points within that (not the whole range) is as exact and
        # much cheaper (PyBullet returns a point per pair of links in range).
        best = self.clearance
        for name, other in others:
            nearest = body.closest_points(other, max(best.distance_m, 0.0))
            if nearest is not None and nearest.distance_m < best.distance_m:
                best = Clearance(nearest.distance_m, name, time_ns)
        self.clearance = best

    def touched(self) -> List[str]:
        """Return the names of the bodies the robot touched, in the order it first did."""
        seen: List[str] = []
        for contact in self.contacts:
            if contact.other not in seen:
                seen.append(contact.other)
        return seen

    def close(self) -> None:
        """Stop watching (the simulation no longer calls it); safe to call twice."""
        self._unwatch()

    def __enter__(self) -> 'RunWatch':
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _up_cos(orientation: Sequence[float]) -> float:
    """Return the cosine of the angle between the body's z axis and the world's up."""
    x, y, _, _ = orientation
    return 1.0 - 2.0 * (x * x + y * y)


def _z_axis(orientation: Sequence[float]) -> Tuple[float, float, float]:
    """Return the z axis of a frame turned by ``orientation`` (x, y, z, w), in the outer frame."""
    x, y, z, w = orientation
    return (2.0 * (x * z + y * w), 2.0 * (y * z - x * w), 1.0 - 2.0 * (x * x + y * y))


def _up_cos_of(orientation: Sequence[float], axis: Tuple[float, float, float]) -> float:
    """
    Return the world's up component of ``axis`` (given in a frame turned by ``orientation``).

    With :func:`_z_axis` of the centre of mass -> body frame rotation, the
    leaning of the body frame (:func:`_up_cos` of its orientation), but for
    rounding.
    """
    x, y, z, w = orientation
    ax, ay, az = axis
    return (2.0 * (x * z - y * w) * ax + 2.0 * (y * z + x * w) * ay
            + (1.0 - 2.0 * (x * x + y * y)) * az)


def _grown_box(region: Region, offset_m: float) -> Tuple[float, float, float, float]:
    """
    Return where a centre of mass ``offset_m`` from the body frame may see it in ``region``.

    A box on the ground around it, x0, y0, x1, y1: grown by the offset and
    the rounding of the body frame's pose (:data:`FRAME_SLACK_M`,
    :data:`FRAME_RELATIVE_SLACK`).
    """
    values = region.values
    if region.kind == 'box':
        x0, y0, x1, y1 = values
    elif region.kind == 'polygon':
        xs, ys = values[0::2], values[1::2]
        x0, y0, x1, y1 = min(xs), min(ys), max(xs), max(ys)
    else:
        cx, cy, radius = values[:3]
        x0, y0, x1, y1 = cx - radius, cy - radius, cx + radius, cy + radius
    grow_m = offset_m + FRAME_SLACK_M + FRAME_RELATIVE_SLACK * (
        max(abs(x0), abs(y0), abs(x1), abs(y1)) + offset_m)
    return x0 - grow_m, y0 - grow_m, x1 + grow_m, y1 + grow_m


def ground_region(pose: NamedPose) -> Region:
    """
    Return a named pose's bounds seen from above, in the world frame: where "at the pose" is.

    ``pose``: a :class:`~r2d2_sim.sim.worlds.world.NamedPose` with bounds
    (relative to the pose). A sphere is the circle of its radius around its
    centre; a box or a convex hull the convex polygon of its corners.
    ValueError (one line) for a pose without bounds: it has no area to reach.
    """
    bounds = pose.bounds
    frame = Transform(pose.position, pose.orientation)
    if bounds.kind == 'sphere':
        centre = apply(frame, bounds.points[0])
        return circle_region(centre[0], centre[1], bounds.points[1][0])
    points = (box_corners(bounds.points[1], bounds.points[0]) if bounds.kind == 'box'
              else bounds.points if bounds.kind == 'convex_hull' else None)
    if points is not None:
        try:
            return polygon_region([apply(frame, point) for point in points])
        except ValueError:
            raise ValueError(f'the named pose {pose.name!r}: its bounds seen from above cover '
                             'no area (turned on their side?)') from None
    x, y = pose.position[0], pose.position[1]
    raise ValueError(f'the named pose {pose.name!r} has no bounds to reach; give a region '
                     f'around it instead, e.g. circle_region({x:g}, {y:g}, 0.2)')


def _named_region(simulation: 'WatchedSimulation', name: str) -> Region:
    """Return the ground region of the current world's named pose ``name``; ValueError if none."""
    world = simulation.worlds.current
    if world is None:
        raise ValueError(f'no world is loaded: no named pose {name!r}')
    try:
        return ground_region(world.named_pose(name))
    except RefusedError as exc:
        raise ValueError(exc.message) from None
