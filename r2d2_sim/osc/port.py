"""
What the OpenSCENARIO actions ask of a simulation: one seam, two sides.

:class:`SimulatorPort` is every call the actions of :mod:`.actions` make;
:class:`~.in_process.R2D2Simulation` answers it from the core in the
scenario's process, :class:`~.over_ros.StandardSimulation` over ROS from any
simulator of the simulation standard. :class:`Watched` is what a check reads
of one entity after each step, from the moment the check began. Also here,
pure and shared by both sides so that they decide alike: the box ahead of a
robot (:func:`box_ahead`), the hull of an entity's bounds at its pose
(:func:`hull_at`) and the go-to-goal law of ``drive_to`` (:func:`go_to`).
No ROS, no physics.
"""

import math
from typing import List, NamedTuple, Optional, Protocol, Sequence, Tuple

from r2d2_sim.model.regions import Region as GroundRegion
from r2d2_sim.model.transforms import apply, Transform, yaw_of
from r2d2_sim.sim.bounds import Region

__all__ = ['SimulatorPort', 'Watched', 'Pose3', 'box_ahead', 'hull_at', 'go_to',
           'FLOOR_CLEARANCE_M', 'STATES']

# (position, orientation as x, y, z, w) of an entity's base in the world.
Pose3 = Tuple[Tuple[float, float, float], Tuple[float, float, float, float]]
# What stands lower than this above the floor is the floor: never in the way, never touched.
FLOOR_CLEARANCE_M = 0.01
# set_simulation_state's states, as osc.sim's enum names them.
STATES = ('stopped', 'playing', 'paused')


class Watched(NamedTuple):
    """One entity's run since a check began watching it, as the check reads it after a step."""

    touched: Optional[str]         # the first entity it touched (None: none)
    touched_s: Optional[float]     # when (simulated s)
    within: Optional[str]          # an entity that came nearer than the clearance asked
    within_s: Optional[float]      # when
    clearance_m: Optional[float]   # the smallest distance measured (None: not measured)
    tipped_s: Optional[float]      # when it first leaned further than the tipping angle


class SimulatorPort(Protocol):
    """The simulation as the actions see it; every refusal is one line (a RefusedError)."""

    def spawn(self, name: str, uri: str, position: Sequence[float],
              orientation: Sequence[float], allow_renaming: bool, namespace: str) -> str:
        """Spawn an entity (SpawnEntity); return its name."""

    def delete(self, name: str) -> None:
        """Delete an entity (DeleteEntity)."""

    def set_entity_state(self, name: str, position: Sequence[float],
                         orientation: Sequence[float], linear: Sequence[float],
                         angular: Sequence[float]) -> None:
        """Place an entity moving with a world-frame twist (SetEntityState)."""

    def load_world(self, uri: str) -> None:
        """Load a world (LoadWorld)."""

    def unload_world(self) -> None:
        """Unload the world (UnloadWorld)."""

    def reset_simulation(self) -> None:
        """Reset everything (ResetSimulation, scope ALL)."""

    def step_physics(self, steps: int) -> None:
        """Step ``steps`` physics steps now, within one tick (StepSimulation)."""

    def set_state(self, state: str) -> None:
        """Set 'stopped', 'playing' or 'paused' (SetSimulationState, in lockstep)."""

    def command(self, entity: str, namespace: str, linear: float, angular: float) -> None:
        """
        Command a robot's velocity (m/s, rad/s) from now until the next command.

        Or until the robot's ``cmd_vel_timeout`` (0.5 s of simulated time by
        default) passes without one: then it brakes, as diff_drive_controller does.
        """

    def pose(self, entity: str) -> Pose3:
        """Return an entity's base pose in the world."""

    def region(self, name: str, tolerance_m: float) -> GroundRegion:
        """Return where "at the named pose" is: 'goal' is the scenario's goal."""

    def meeting(self, region: Region) -> List[str]:
        """Return the entities whose collision shape meets a world region (GetEntities bounds)."""

    def bounds(self, entity: str) -> Region:
        """Return the box around an entity's collision shape, in its base frame."""

    def watch(self, entity: str, tip_angle_rad: float, clearance_m: float, token: int
              ) -> 'Watched':
        """
        Return what the entity did since the watch ``token`` began, with these limits.

        ``token``: a number the check drew when it started, a watch of its
        own: begun when first asked (nothing before it counts), the same
        watch each time the check asks again.
        """

    def unwatch(self, token: int) -> None:
        """Stop the watch ``token`` (its check ended); nothing if there is none."""

    @property
    def time_s(self) -> float:
        """Return the simulated time (s)."""

    @property
    def error(self) -> Optional[str]:
        """Return the mistake found at reset (one line), None when the run could start."""


def _corners(region: Region) -> List[Tuple[float, float, float]]:
    """Return the eight corners of a box region."""
    (ux, uy, uz), (lx, ly, lz) = region.points
    return [(x, y, z) for x in (lx, ux) for y in (ly, uy) for z in (lz, uz)]


def hull_at(bounds: Region, pose: Pose3, margin_m: float = 0.0) -> Region:
    """
    Return an entity's bounds box, grown by ``margin_m``, at ``pose``, as a world convex hull.

    Its bottom is kept :data:`FLOOR_CLEARANCE_M` above the floor, so that the
    ground is never met. ValueError for bounds that are not a box.
    """
    if bounds.kind != 'box':
        raise ValueError(f'bounds of kind {bounds.kind!r}: a box was expected')
    (ux, uy, uz), (lx, ly, lz) = bounds.points
    frame = Transform(pose[0], pose[1])
    grown = Region.box((lx - margin_m, ly - margin_m, lz - margin_m),
                       (ux + margin_m, uy + margin_m, uz + margin_m))
    points = [apply(frame, corner) for corner in _corners(grown)]
    return Region('convex_hull', tuple((x, y, max(z, FLOOR_CLEARANCE_M)) for x, y, z in points))


def box_ahead(bounds: Region, pose: Pose3, length_m: float) -> Region:
    """
    Return the box ``length_m`` long in front of an entity (its +x), as wide and high as it is.

    As a world convex hull, above the floor: what meets it is in the way.
    """
    (ux, uy, uz), (_, ly, lz) = bounds.points
    ahead = Region.box((ux, ly, lz), (ux + length_m, uy, uz))
    return hull_at(ahead, pose)


def go_to(pose: Pose3, goal: Tuple[float, float], speed_m_s: float, blocked: bool
          ) -> Tuple[float, float]:
    """
    Return (linear m/s, angular rad/s) that head for ``goal``: turn first, no speed while blocked.

    The farm's stopper's law (docs/farm.md): turn at 1.5 times the heading
    error (at most 0.8 rad/s), drive only when facing within 0.4 rad, slowing
    within 2 * speed metres of the goal.
    """
    (x, y, _), orientation = pose
    distance = math.hypot(goal[0] - x, goal[1] - y)
    turn = math.atan2(goal[1] - y, goal[0] - x) - yaw_of(orientation)
    turn = math.atan2(math.sin(turn), math.cos(turn))
    angular = max(-0.8, min(0.8, 1.5 * turn))
    linear = 0.0 if blocked or abs(turn) >= 0.4 else min(speed_m_s, 0.5 * distance)
    return linear, angular
