"""
A world's named poses for scenarios: start and goal by name, and where a run places the robot.

No ROS, no physics: the world file is read as the simulator reads its
``world`` parameter (:func:`r2d2_sim.sim.worlds.read_world`, trusted, the
default search paths), once per world and process. A scenario keeps the
numbers a name stood for, so its JSON replays without the world file's
help; the name is kept beside them for the report.

The simulator reads ``initial_pose`` relative to the world's start pose
when the world names one (a manifest's ``start_pose``, an SDF world's
``start`` frame); a scenario's start is in the world frame, so
:func:`initial_pose` turns it into what the simulator expects.
"""

import functools
import math
from typing import Dict, List, Optional, Tuple

from r2d2_sim.errors import RefusedError, ScenarioError
from r2d2_sim.model.transforms import yaw_of
from r2d2_sim.sim.worlds import NamedPose, Places, read_world, World

__all__ = ['WorldPoses', 'world_poses', 'initial_pose', 'read']


class WorldPoses:
    """A world's named poses (by name) and its start pose, as plain numbers."""

    def __init__(self, world: str, poses: Dict[str, NamedPose],
                 start: Optional[NamedPose]) -> None:
        self.world = world
        self.poses = poses
        self.start = start

    def pose(self, name: str) -> Tuple[float, float, float]:
        """Return the named pose ``name`` as (x, y, yaw); ScenarioError (one line) if none."""
        pose = self.poses.get(name)
        if pose is None:
            known = ', '.join(sorted(self.poses)) or 'none'
            where = self.world or "no world (world '')"
            raise ScenarioError(f'no named pose {name!r} in {where}; it has: {known}')
        return pose.position[0], pose.position[1], yaw_of(pose.orientation)

    def names(self) -> List[str]:
        """Return the names of the world's named poses, sorted."""
        return sorted(self.poses)


@functools.lru_cache(maxsize=16)
def world_poses(world: str) -> WorldPoses:
    """
    Return the named poses of ``world`` (a scenario's ``world``: '' for none).

    ScenarioError (one line) when the world cannot be read: the simulator
    would refuse it too.
    """
    if not world:
        return WorldPoses(world, {}, None)
    read_back = read(world)
    read_back.close()
    return WorldPoses(world, {pose.name: pose for pose in read_back.named_poses},
                      read_back.start_pose)


def read(world: str) -> World:
    """
    Read ``world`` as the simulator reads its ``world`` parameter; close what it returns.

    ScenarioError (one line, naming the file) when the simulator would refuse it.
    """
    try:
        return read_world(world, '', Places(), trusted=True)
    except RefusedError as exc:
        raise ScenarioError(f'world {exc.message}') from None  # the message names the file


def initial_pose(world: str, x: float, y: float, yaw: float) -> List[float]:
    """
    Return the simulator's ``initial_pose`` that stands the robot at (x, y, yaw) in the world.

    Relative to the world's start pose when it names one, as the simulator
    reads it; the world frame's own numbers otherwise.
    """
    start = world_poses(world).start
    if start is None:
        return [x, y, yaw]
    yaw0 = yaw_of(start.orientation)
    dx, dy = x - start.position[0], y - start.position[1]
    c, s = math.cos(yaw0), math.sin(yaw0)
    return [c * dx + s * dy, -s * dx + c * dy, math.remainder(yaw - yaw0, 2.0 * math.pi)]
