"""
What a world is, as read: a :class:`World`, its :class:`WorldModel` entries, its named poses.

Plain data: no ROS, no PyBullet. Every world format's reader returns a World
(:mod:`~r2d2_sim.sim.worlds.reading` for URDF and the manifest,
:mod:`~r2d2_sim.sim.worlds.sdf_format` for SDF), and the Simulation and its
start-up build from one.
"""

from typing import NamedTuple, Optional, Tuple, TYPE_CHECKING

from r2d2_sim.errors import RefusedError
from r2d2_sim.sim.bounds import EMPTY, Region

if TYPE_CHECKING:  # typing only: a world is plain data
    from r2d2_sim.sim.spawnables import Closable

__all__ = ['World', 'WorldModel', 'NamedPose']

Vec3 = Tuple[float, float, float]
Quat = Tuple[float, float, float, float]


class NamedPose(NamedTuple):
    """
    A pose with a name, as the standard's NamedPose, and its bounds.

    The pose is in the world frame; ``bounds`` (a checked
    :class:`~r2d2_sim.sim.bounds.Region`, or empty) are relative to
    the pose, as an entity's bounds are relative to the entity.
    """

    name: str
    description: str
    tags: Tuple[str, ...]
    position: Tuple[float, float, float]
    orientation: Tuple[float, float, float, float]
    bounds: Region = EMPTY


class WorldModel(NamedTuple):
    """
    One model of a world: a URDF file to load at a pose, and what the standard says of it.

    ``sdf``: made from SDF, so loaded as Gazebo would simulate it (the file's
    inertias, true cylinders, joints free but for their friction); ``static``:
    made from SDF and nothing of it moves (the checks of a load skip it).
    """

    name: Optional[str]      # None: the URDF's robot name, made unique
    path: str                # the file PyBullet loads
    source: str              # the URI as written ('resource_string' for text)
    position: Vec3
    orientation: Quat
    description: str
    tags: Tuple[str, ...]
    sdf: bool = False
    static: bool = False
    given_as: Optional[str] = None  # a URDF given as text: where ('the resource_string')

    @property
    def made_from(self) -> Optional[str]:
        """Return what errors name for a model made from SDF, whose URDF is made; else None."""
        return f'SDF model {self.name} of {self.source}' if self.sdf else None


class World(NamedTuple):
    """
    A world as read: its models, named poses and what GetCurrentWorld tells of it.

    ``uri`` and ``resource_string`` are the request's (or the ``world``
    parameter's); ``start_pose`` is the named pose the start-up robots stand
    at (None: the world's origin); ``notes`` say what was left out or
    ignored; ``resources`` are temporary files to close with the world.
    """

    name: str
    uri: str
    resource_string: str
    description: str
    tags: Tuple[str, ...]
    models: Tuple[WorldModel, ...]
    named_poses: Tuple[NamedPose, ...]
    start_pose: Optional[NamedPose]
    notes: Tuple[str, ...] = ()
    resources: Tuple['Closable', ...] = ()

    def named_pose(self, name: str) -> NamedPose:
        """Return the named pose ``name``; RefusedError NOT_FOUND listing the others."""
        for pose in self.named_poses:
            if pose.name == name:
                return pose
        known = ', '.join(p.name for p in self.named_poses) or 'none'
        raise RefusedError('NOT_FOUND', f'no named pose {name[:100]!r} in the world '
                                        f'{self.name}; it has: {known}')

    def close(self) -> None:
        """Delete the temporary files of a world given as text; safe to call twice."""
        for resource in self.resources:
            resource.close()
