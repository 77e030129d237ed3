"""
What the ROS services use of the simulator, typed: the seams between translation and the core.

The services get these at construction and reach nothing else. Reads and
changes are apart, as the core keeps them: the standard's entity services
read an :class:`EntityReads` (the core's
:class:`~r2d2_sim.sim.entities.Entities`) and change an
:class:`EntityChanges` (the core's :class:`~r2d2_sim.sim.simulation.Simulation`);
its world services read a :class:`WorldReads` (the core's
:class:`~r2d2_sim.sim.worlds.files.WorldFiles`) and change a
:class:`WorldChanges` (the :class:`~r2d2_sim.ros.node.SimNode`: loading a
world pauses it and tells ``/clock``); the control services and the
standard's simulation services a :class:`SimulatorControl` (the node); a
robot's ``cmd_vel`` a :class:`Commandable` (its
:class:`~r2d2_sim.sim.robots.robot.Robot`). They are used under the
simulator's lock, one thread in PyBullet at a time, except the reads of
files that change nothing (:meth:`WorldReads.read`, :meth:`EntityReads.read`),
which a service does before it takes the lock. The core's types are imported
for the checker only, so that ``cmd_vel`` does not load the world reader.
"""

import threading
from typing import List, Optional, Protocol, Sequence, Tuple, TYPE_CHECKING

from r2d2_sim.model.drive_controller import CommandVerdict

if TYPE_CHECKING:
    from r2d2_sim.model.transforms import BaseState
    from r2d2_sim.sim.bounds import Region
    from r2d2_sim.sim.entities import EntityInfo, SpawnRequest
    from r2d2_sim.sim.settings.config import SimConfig
    from r2d2_sim.sim.spawnables import Spawnable
    from r2d2_sim.sim.tags import TagsFilter
    from r2d2_sim.sim.worlds import LoadOptions, NamedPose, World, WorldEntry

__all__ = ['EntityReads', 'EntityChanges', 'SimulatorControl', 'WorldReads', 'WorldChanges',
           'Commandable']


class EntityReads(Protocol):
    """The world's entities as the standard reads them: list, state, info, bounds; no change."""

    world_frame_id: str

    def names(self) -> List[str]:
        """Return every entity's name."""

    def category(self, name: str) -> int:
        """Return the standard's EntityCategory of an entity."""

    def info(self, name: str) -> 'EntityInfo':
        """Return an entity's category, description and tags."""

    def tags(self, name: str) -> Tuple[str, ...]:
        """Return an entity's tags."""

    def bounds(self, name: str) -> 'Region':
        """Return the box around an entity's collision shape, in its base link's frame."""

    def state(self, name: str) -> 'BaseState':
        """Return an entity's pose and twist in the world frame."""

    def overlapping(self, region: 'Region') -> List[str]:
        """Return the entities whose collision shape meets a region (box, hull, sphere)."""

    def read(self, request: 'SpawnRequest') -> 'Spawnable':
        """Read what a spawn loads (files, SDF, meshes) without touching the physics."""

    def listed(self, source: str) -> Optional[List[str]]:
        """Return the model files of a directory a spawn takes by path; None: no directory."""


class EntityChanges(Protocol):
    """The changes of the world's entities: place, describe, spawn, delete; and time now."""

    @property
    def time_ns(self) -> int:
        """Return the simulated time now (ns): the stamp of the states read."""

    def set_entity_info(self, name: str, category: int, description: str,
                        tags: Sequence[str]) -> None:
        """Set an entity's category, description and tags."""

    def set_entity_state(self, name: str, frame_id: str, position: Sequence[float],
                         orientation: Sequence[float], linear: Sequence[float],
                         angular: Sequence[float], acceleration: Sequence[float] = ()) -> None:
        """Place an entity at a pose in ``frame_id`` with a twist; check an acceleration."""

    def spawn(self, request: 'SpawnRequest', spawnable: 'Optional[Spawnable]' = None) -> str:
        """Spawn an entity (a driven robot with a namespace), read beforehand; return its name."""

    def delete_entity(self, name: str) -> None:
        """Delete an entity, and the robot it is if it is one."""


class SimulatorControl(Protocol):
    """Pausing, stepping and resetting the simulation, under ``lock``."""

    lock: threading.RLock
    config: 'SimConfig'

    @property
    def paused(self) -> bool:
        """Return True while physics is stopped."""

    @property
    def unrun_since_launch(self) -> bool:
        """Return True while nothing ran since start-up, a full reset or a world load."""

    @property
    def world_is_loaded(self) -> bool:
        """Return False after UnloadWorld until a world is loaded (the standard's NO_WORLD)."""

    @property
    def step_count(self) -> int:
        """Return the physics steps taken since start (or the last time reset)."""

    @property
    def reset_count(self) -> int:
        """Return how often the world was reset, restored, loaded or unloaded since start."""

    @property
    def sim_time_ns(self) -> int:
        """Return the simulated time now (ns)."""

    @property
    def last_publication_ns(self) -> int:
        """Return the simulated time (ns) of the latest state publication: its stamps."""

    def set_paused(self, paused: bool) -> None:
        """Pause (landing on a publication) or resume physics."""

    def advance(self, steps: int = 1) -> None:
        """Step physics ``steps`` times, publishing on schedule."""

    def advance_to_next_publish(self) -> int:
        """Advance to and including the next publication; return the steps taken."""

    def reset_simulation(self, *, time: bool = False, state: bool = True,
                         spawned: bool = False) -> None:
        """Reset what is asked (the standard's scopes)."""


class WorldReads(Protocol):
    """The world files: which is loaded, which can be, named poses; reading one changes nothing."""

    @property
    def current(self) -> 'Optional[World]':
        """Return the world loaded now; None after UnloadWorld."""

    def available(self, additional_sources: Sequence[str], tags: 'TagsFilter',
                  offline_only: bool, continue_on_error: bool
                  ) -> 'Tuple[List[WorldEntry], str]':
        """Return the worlds that can be loaded and a note of what was left out."""

    def named_poses(self, tags: 'TagsFilter') -> 'List[NamedPose]':
        """Return the world's named poses whose tags pass the filter."""

    def named_pose(self, name: str) -> 'NamedPose':
        """Return one named pose (RefusedError NOT_FOUND)."""

    def read(self, uri: str, resource_string: str, options: 'LoadOptions') -> 'World':
        """Read and check a world LoadWorld names, without changing anything."""


class WorldChanges(Protocol):
    """Loading and unloading the world around the robots, under ``lock``."""

    lock: threading.RLock

    def load_world(self, world: 'World') -> 'World':
        """
        Load a world read beforehand in place of the current one, stopped at time 0.

        Takes ``lock`` itself, as often as it likes: the physics may step
        between while the new world is built, never once it is swapped in.
        """

    def unload_world(self) -> None:
        """Unload the world (NO_WORLD until another is loaded)."""


class Commandable(Protocol):
    """What takes a robot's ``cmd_vel``: a Twist's fields in, the controller's verdict out."""

    def command(self, linear_x: float, angular_z: float, **other_axes: float) -> CommandVerdict:
        """Hand a command to the robot; NO_WHEELS when it has no drive."""
