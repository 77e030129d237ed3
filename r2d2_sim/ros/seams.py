"""
What the ROS services use of the simulator, typed: the seams between translation and the core.

The services get these at construction and reach nothing else: the
standard's entity services an :class:`EntityWorld` (the core's
:class:`~r2d2_sim.sim.simulation.Simulation` is one), the control services
and the standard's simulation services a :class:`SimulatorControl`, the
standard's world services a :class:`WorldControl` (the
:class:`~r2d2_sim.ros.node.SimNode` is both: loading a world pauses it and
tells ``/clock``), a robot's ``cmd_vel`` a :class:`Commandable` (its
:class:`~r2d2_sim.sim.robot.Robot`). They are used under the simulator's
lock, one thread in PyBullet at a time.
"""

import threading
from typing import List, Optional, Protocol, Sequence, Tuple

from r2d2_sim.model.drive_controller import CommandVerdict
from r2d2_sim.model.transforms import BaseState
from r2d2_sim.sim.entities import EntityInfo, SpawnRequest
from r2d2_sim.sim.entity_bounds import Region
from r2d2_sim.sim.parameters import SimConfig
from r2d2_sim.sim.tags import TagsFilter
from r2d2_sim.sim.world_manifest import NamedPose
from r2d2_sim.sim.worlds import LoadOptions, World, WorldEntry

__all__ = ['EntityWorld', 'SimulatorControl', 'WorldControl', 'Commandable']


class EntityWorld(Protocol):
    """The world's entities as the standard sees them: list, read, place, spawn, delete."""

    @property
    def world_frame_id(self) -> str:
        """Return the frame entity poses are given in."""

    @property
    def time_ns(self) -> int:
        """Return the simulated time now (ns): the stamp of the states read."""

    def entity_names(self) -> List[str]:
        """Return every entity's name."""

    def entity_category(self, name: str) -> int:
        """Return the standard's EntityCategory of an entity."""

    def entity_source(self, name: str) -> str:
        """Return where an entity's description came from."""

    def entity_info(self, name: str) -> EntityInfo:
        """Return an entity's category, description and tags."""

    def set_entity_info(self, name: str, category: int, description: str,
                        tags: Sequence[str]) -> None:
        """Set an entity's category, description and tags."""

    def entity_tags(self, name: str) -> Tuple[str, ...]:
        """Return an entity's tags."""

    def entity_bounds(self, name: str) -> Region:
        """Return the box around an entity's collision shape, in its base link's frame."""

    def entity_state(self, name: str) -> BaseState:
        """Return an entity's pose and twist in the world frame."""

    def set_entity_state(self, name: str, frame_id: str, position: Sequence[float],
                         orientation: Sequence[float], linear: Sequence[float],
                         angular: Sequence[float]) -> None:
        """Place an entity at a pose in ``frame_id`` with a world-frame twist."""

    def entities_overlapping(self, region: Region) -> List[str]:
        """Return the entities whose collision shape meets a region (box, hull, sphere)."""

    def spawn(self, request: SpawnRequest) -> str:
        """Spawn an entity (a driven robot with a namespace); return its name."""

    def delete_entity(self, name: str) -> None:
        """Delete an entity, and the robot it is if it is one."""


class SimulatorControl(Protocol):
    """Pausing, stepping and resetting the simulation, under ``lock``."""

    lock: threading.RLock
    config: SimConfig

    @property
    def paused(self) -> bool:
        """Return True while physics is stopped."""

    @property
    def pristine(self) -> bool:
        """Return True when nothing changed since start-up or a full reset."""

    @property
    def world_is_loaded(self) -> bool:
        """Return False after UnloadWorld until a world is loaded (the standard's NO_WORLD)."""

    @property
    def step_count(self) -> int:
        """Return the physics steps taken since start (or the last time reset)."""

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


class WorldControl(Protocol):
    """The world around the robots: listed, loaded, unloaded; its named poses. Under ``lock``."""

    lock: threading.RLock

    def available_worlds(self, additional_sources: Sequence[str], tags: TagsFilter,
                         offline_only: bool, continue_on_error: bool
                         ) -> Tuple[List[WorldEntry], str]:
        """Return the worlds that can be loaded and a note of what was left out."""

    def load_world(self, uri: str, resource_string: str, options: LoadOptions) -> World:
        """Load a world in place of the current one, stopped at time 0; return it."""

    def unload_world(self) -> None:
        """Unload the world (NO_WORLD until another is loaded)."""

    def current_world(self) -> Optional[World]:
        """Return the world loaded now; None after UnloadWorld."""

    def named_poses(self, tags: TagsFilter) -> List[NamedPose]:
        """Return the world's named poses whose tags pass the filter."""

    def named_pose(self, name: str) -> NamedPose:
        """Return one named pose (RefusedError NOT_FOUND)."""


class Commandable(Protocol):
    """What takes a robot's ``cmd_vel``: a Twist's fields in, the controller's verdict out."""

    def command(self, linear_x: float, angular_z: float, **other_axes: float) -> CommandVerdict:
        """Hand a command to the robot; NO_WHEELS when it has no drive."""
