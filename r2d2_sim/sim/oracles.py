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
  (a box or a circle on the ground, see :mod:`r2d2_sim.model.regions`);
- **tipping**: when the base first leaned further than the angle given.

It costs nothing unless made (the simulation calls its watches after each
step), and about 10 us per other body per step when made (closest points).
"""

import math
from typing import Dict, List, Mapping, NamedTuple, Optional, Tuple

from r2d2_sim.model.regions import Region
from r2d2_sim.physics.body import Body
from r2d2_sim.physics.world import GROUND_PLANE_NAME

__all__ = ['Contact', 'Clearance', 'RunWatch', 'DEFAULT_CLEARANCE_RANGE_M',
           'DEFAULT_TIP_ANGLE_RAD']

# Closest points are looked for within this distance (m): farther bodies count as this.
DEFAULT_CLEARANCE_RANGE_M = 2.0
# Leaning more than this from upright (roll and pitch together) is tipping over.
DEFAULT_TIP_ANGLE_RAD = math.radians(45.0)


class Contact(NamedTuple):
    """The robot touching another body, from ``start_ns`` to ``end_ns`` (None: still)."""

    other: str                            # the other entity's name
    robot_link: str                       # the robot's link that touched first
    other_link: str                       # and the other body's
    start_ns: int                         # simulated time of the first step in contact
    end_ns: Optional[int]                 # of the first step out of contact again
    position: Tuple[float, float, float]  # where, on the robot, in the world, at the start
    max_normal_force_n: float             # the hardest push while it lasted


class Clearance(NamedTuple):
    """The smallest distance between the robot and another body so far, and when and to what."""

    distance_m: float                     # negative: overlapping that much
    other: Optional[str]                  # None: nothing came within the range
    time_ns: Optional[int]


class RunWatch:
    """
    One robot's run as the physics saw it, from now on: contacts, clearance, regions, tipping.

    ``simulation`` is stepped by its owner as usual; the watch reads the
    world after each step until :meth:`close`. ``entity`` names what is
    watched: a robot (default: the first) or any other entity. ``regions``
    maps names to :class:`~r2d2_sim.model.regions.Region` s whose first entry
    time is kept in :attr:`reached`. ValueError for an unknown entity or a
    range or angle that is no range or angle.
    """

    def __init__(self, simulation, entity: Optional[str] = None, *,
                 regions: Optional[Mapping[str, Region]] = None,
                 clearance_range_m: float = DEFAULT_CLEARANCE_RANGE_M,
                 tip_angle_rad: float = DEFAULT_TIP_ANGLE_RAD) -> None:
        if not (math.isfinite(clearance_range_m) and clearance_range_m > 0.0):
            raise ValueError(f'clearance_range_m must be > 0, got {clearance_range_m}')
        if not (math.isfinite(tip_angle_rad) and 0.0 < tip_angle_rad < math.pi):
            raise ValueError(f'tip_angle_rad must be in (0, pi), got {tip_angle_rad}')
        self._simulation = simulation
        bodies = simulation.world.bodies
        if entity is None and not simulation.robots:
            raise ValueError('the world has no robot: name the entity to watch')
        self.body: Body = simulation.robots[0].body if entity is None else bodies.get(entity)
        if self.body is None:
            raise ValueError(f'no entity named {entity!r}; the world has: {", ".join(bodies)}')
        self.name = self.body.name
        self.regions: Dict[str, Region] = dict(regions or {})
        self.clearance_range_m = clearance_range_m
        self.tip_cos = math.cos(tip_angle_rad)
        self.contacts: List[Contact] = []
        self.clearance = Clearance(clearance_range_m, None, None)
        self.reached: Dict[str, int] = {}
        self.tipped_ns: Optional[int] = None
        self.start_ns = simulation.time_ns
        self.steps = 0
        self._open: Dict[str, int] = {}  # other entity -> index of its contact still going
        self._unwatch = simulation.watch_steps(self.observe)

    def observe(self, time_ns: int) -> None:
        """Read the world after a step at ``time_ns`` (the simulation calls this)."""
        body = self.body
        if not body.alive:
            return  # it left the world: nothing more to see
        self.steps += 1
        self._contacts(body, time_ns)
        self._clearance(body, time_ns)
        base = body.world_state()
        x, y = base.position[0], base.position[1]
        for name, region in self.regions.items():
            if name not in self.reached and region.contains(x, y):
                self.reached[name] = time_ns
        if self.tipped_ns is None and _up_cos(base.orientation) < self.tip_cos:
            self.tipped_ns = time_ns

    def _others(self, body: Body):
        """Every body but the robot's and the ground plane, by name."""
        for name, other in self._simulation.world.bodies.items():
            if other is not body and name != GROUND_PLANE_NAME:
                yield name, other

    def _contacts(self, body: Body, time_ns: int) -> None:
        touching: Dict[str, Tuple] = {}
        bodies = {other.id: (name, other) for name, other in self._others(body)}
        for point in body.contacts():
            found = bodies.get(point.body_b)
            if found is None:
                continue
            name, other = found
            strongest = touching.get(name)
            if strongest is None or point.normal_force_n > strongest[0].normal_force_n:
                touching[name] = (point, other)
        for name in [n for n in self._open if n not in touching]:
            index = self._open.pop(name)
            self.contacts[index] = self.contacts[index]._replace(end_ns=time_ns)
        for name, (point, other) in touching.items():
            index = self._open.get(name)
            if index is None:
                self._open[name] = len(self.contacts)
                self.contacts.append(Contact(
                    name, body.link_name(point.link_a), other.link_name(point.link_b),
                    time_ns, None, point.position_on_a, point.normal_force_n))
            elif point.normal_force_n > self.contacts[index].max_normal_force_n:
                self.contacts[index] = self.contacts[index]._replace(
                    max_normal_force_n=point.normal_force_n)

    def _clearance(self, body: Body, time_ns: int) -> None:
        best = self.clearance
        for name, other in self._others(body):
            nearest = body.closest_points(other, self.clearance_range_m)
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

    def __exit__(self, *exc) -> None:
        self.close()


def _up_cos(orientation) -> float:
    """Return the cosine of the angle between the body's z axis and the world's up."""
    x, y, _, _ = orientation
    return 1.0 - 2.0 * (x * x + y * y)
