"""
Changing the world from a test: spawn, place, read, delete, reset, load worlds, named poses.

Both harnesses have these verbs: :class:`~r2d2_sim.testing.harness.SimHarness`
calls the simulation core in its own process (no interface package needed),
:class:`~r2d2_sim.testing.sim_process.SimProcess` the standard's services
(``simulation_interfaces``). A refusal is a :class:`~r2d2_sim.errors.RefusedError`
in both (a :class:`~r2d2_sim.testing.standard.StandardError` through the
services), its ``code`` the standard's result name (``NOT_FOUND``,
``NAME_NOT_UNIQUE``...). Both return the same plain records:
:class:`~r2d2_sim.sim.worlds.manifest.NamedPose`,
:class:`~r2d2_sim.sim.worlds.WorldEntry`, :class:`~r2d2_sim.sim.entities.EntityInfo`
and :class:`~r2d2_sim.sim.bounds.Region`.
"""

import math
import os
from typing import Any, List, Optional, Sequence, Tuple, TYPE_CHECKING, Union

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.transforms import BaseState
from r2d2_sim.sim.entities import EntityInfo, SpawnRequest
from r2d2_sim.sim.bounds import Region, REGION_KINDS
from r2d2_sim.sim.tags import FILTER_MODE_ALL, FILTER_MODE_ANY, TagsFilter
from r2d2_sim.sim.worlds import NamedPose
from r2d2_sim.sim.worlds import WorldEntry
from r2d2_sim.testing.standard import StandardClient

if TYPE_CHECKING:  # PyBullet is imported only when a simulator is made
    from r2d2_sim.ros.node import SimNode

__all__ = ['WorldVerbs', 'CoreWorld', 'StandardWorld', 'NamedPose', 'WorldEntry',
           'EntityInfo', 'Region']

IDENTITY = (0.0, 0.0, 0.0, 1.0)


def _numbers(value: Any, count: int, what: str) -> Tuple[float, ...]:
    """Return ``value`` as ``count`` floats; TypeError (one line) for anything else."""
    try:
        numbers = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        numbers = ()
    if len(numbers) != count or isinstance(value, str):
        raise TypeError(f'{what} must be {count} numbers, got {value!r}')
    return numbers


def _orientation(yaw: float, orientation: Optional[Sequence[float]]) -> Tuple[float, ...]:
    if orientation is not None:
        return _numbers(orientation, 4, 'orientation (x, y, z, w)')
    return 0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)


# A file by its path (a pathlib.Path too), a URI, or the file's text.
PathOrText = Union[str, 'os.PathLike[str]']


def _text(value: Any, what: str) -> str:
    if isinstance(value, os.PathLike):
        return os.fspath(value)  # a pathlib.Path is a path
    if not isinstance(value, str):
        raise TypeError(f'{what}, got {type(value).__name__}')
    return value


def _resource(urdf: PathOrText) -> Tuple[str, str]:
    """Return (uri, resource_string): XML text goes as a resource string, anything else a uri."""
    urdf = _text(urdf, 'spawn takes a URDF or SDF: a path, a package:// or model:// URI, a '
                       'pybullet_data name or the XML text')
    return ('', urdf) if urdf.lstrip().startswith('<') else (urdf, '')


def _world_resource(world: PathOrText) -> Tuple[str, str]:
    """Return (uri, resource_string): a text of several lines or XML is the file's text."""
    world = _text(world, 'load_world takes a world file, a package:// URI or the world\'s '
                         'text')
    text = world.lstrip()
    return ('', world) if text.startswith('<') or '\n' in text else (world, '')


def _region(bounds: Any) -> Region:
    kind = REGION_KINDS[bounds.type] if bounds.type < len(REGION_KINDS) else str(bounds.type)
    return Region(kind, tuple((p.x, p.y, p.z) for p in bounds.points))


def _entry(world: Any) -> WorldEntry:
    resource = world.world_resource
    return WorldEntry(world.name, resource.uri or resource.resource_string, world.description,
                      tuple(world.tags))


class CoreWorld:
    """The verbs on a SimNode in this process: its core's operations, under the node's lock."""

    def __init__(self, node: 'SimNode') -> None:
        self._node = node

    def spawn(self, uri: str, resource_string: str, name: str, position: Sequence[float],
              orientation: Sequence[float], allow_renaming: bool, namespace: str = '',
              frame_id: str = '') -> str:
        simulation = self._node.simulation
        request = SpawnRequest(name, allow_renaming, uri, resource_string, namespace, frame_id,
                               position, orientation)
        spawnable = simulation.entities.read(request)  # files first, without the lock
        with self._node.lock:
            return simulation.spawn(request, spawnable)

    def entity_state(self, name: str) -> BaseState:
        with self._node.lock:
            return self._node.simulation.entities.state(name)

    def set_entity_state(self, name: str, position: Sequence[float],
                         orientation: Sequence[float], linear: Sequence[float],
                         angular: Sequence[float], frame_id: str = '') -> None:
        with self._node.lock:
            self._node.simulation.set_entity_state(name, frame_id, position, orientation,
                                                   linear, angular)

    def entity_info(self, name: str) -> EntityInfo:
        with self._node.lock:
            return self._node.simulation.entities.info(name)

    def set_entity_info(self, name: str, category: int, description: str,
                        tags: Sequence[str]) -> None:
        with self._node.lock:
            self._node.simulation.set_entity_info(name, category, description, tags)

    def entity_bounds(self, name: str) -> Region:
        with self._node.lock:
            return self._node.simulation.entities.bounds(name)

    def load_world(self, uri: str, resource_string: str) -> WorldEntry:
        world = self._node.load_world(uri, resource_string)
        return WorldEntry(world.name, world.uri or world.resource_string, world.description,
                          world.tags)

    def unload_world(self) -> None:
        self._node.unload_world()

    def current_world(self) -> Optional[WorldEntry]:
        world = self._node.simulation.worlds.current
        if world is None:
            return None
        return WorldEntry(world.name, world.uri or world.resource_string, world.description,
                          world.tags)

    def available_worlds(self, tags: TagsFilter, continue_on_error: bool) -> List[WorldEntry]:
        with self._node.lock:
            return self._node.simulation.worlds.available(
                tags=tags, continue_on_error=continue_on_error)[0]

    def named_poses(self, tags: TagsFilter) -> List[NamedPose]:
        with self._node.lock:
            return self._node.simulation.worlds.named_poses(tags)

    def delete(self, name: str) -> None:
        with self._node.lock:
            self._node.simulation.delete_entity(name)

    def entities(self) -> List[str]:
        with self._node.lock:
            return self._node.simulation.entities.names()

    def reset(self, time: bool, state: bool, spawned: bool) -> None:
        if not self._node.world_is_loaded:  # as the standard's reset_simulation answers
            raise RefusedError('INCORRECT_STATE', 'no world is loaded (unload_world): '
                                                  'load_world first')
        self._node.reset_simulation(time=time, state=state, spawned=spawned)


class StandardWorld:
    """The verbs through a :class:`~r2d2_sim.testing.standard.StandardClient`."""

    def __init__(self, client: StandardClient) -> None:
        self._client = client

    def spawn(self, uri: str, resource_string: str, name: str, position: Sequence[float],
              orientation: Sequence[float], allow_renaming: bool, namespace: str = '',
              frame_id: str = '') -> str:
        return self._client.spawn(uri, resource_string, name, position, orientation,
                                  allow_renaming, namespace, frame_id)

    def entity_state(self, name: str) -> BaseState:
        msg = self._client.entity_state(name)
        p, q, v, w = msg.pose.position, msg.pose.orientation, msg.twist.linear, msg.twist.angular
        return BaseState((p.x, p.y, p.z), (q.x, q.y, q.z, q.w), (v.x, v.y, v.z),
                         (w.x, w.y, w.z))

    def set_entity_state(self, name: str, position: Sequence[float],
                         orientation: Sequence[float], linear: Sequence[float],
                         angular: Sequence[float], frame_id: str = '') -> None:
        self._client.set_entity_state(name, position, orientation, linear, angular, frame_id)

    def delete(self, name: str) -> None:
        self._client.delete(name)

    def entity_info(self, name: str) -> EntityInfo:
        info = self._client.entity_info(name)
        return EntityInfo(info.category.category, info.description, tuple(info.tags))

    def set_entity_info(self, name: str, category: int, description: str,
                        tags: Sequence[str]) -> None:
        self._client.set_entity_info(name, category, description, tags)

    def entity_bounds(self, name: str) -> Region:
        return _region(self._client.entity_bounds(name))

    def load_world(self, uri: str, resource_string: str) -> WorldEntry:
        return _entry(self._client.load_world(uri, resource_string).world)

    def unload_world(self) -> None:
        self._client.unload_world()

    def current_world(self) -> Optional[WorldEntry]:
        world = self._client.current_world()
        return None if world is None else _entry(world)

    def available_worlds(self, tags: TagsFilter, continue_on_error: bool) -> List[WorldEntry]:
        return [_entry(w) for w in self._client.available_worlds(
            tags.tags, tags.mode == FILTER_MODE_ALL, continue_on_error=continue_on_error)]

    def named_poses(self, tags: TagsFilter) -> List[NamedPose]:
        poses = []
        for msg in self._client.named_poses(tags.tags, tags.mode == FILTER_MODE_ALL):
            p, q = msg.pose.position, msg.pose.orientation
            poses.append(NamedPose(msg.name, msg.description, tuple(msg.tags), (p.x, p.y, p.z),
                                   (q.x, q.y, q.z, q.w),
                                   _region(self._client.named_pose_bounds(msg.name))))
        return poses

    def entities(self) -> List[str]:
        return self._client.entities()

    def reset(self, time: bool, state: bool, spawned: bool) -> None:
        # Never 0 (reset_world refuses no scope): 0 means a full reset to the standard.
        self._client.reset((1 if time else 0) | (2 if state else 0) | (4 if spawned else 0))


class WorldVerbs:
    """A harness's world verbs, on ``self._world_backend()`` (a CoreWorld or StandardWorld)."""

    def _world_backend(self) -> Union[CoreWorld, StandardWorld]:
        raise NotImplementedError

    def _before_reset(self) -> None:
        """Take what is still on its way before reset_world (a harness hook)."""

    def _after_reset(self) -> None:
        """Resync the state readers after reset_world (a harness hook)."""

    def _before_world_change(self) -> None:
        """Note what is there before a spawn or load_world (a harness hook)."""

    def _after_spawn(self, name: str, namespace: str) -> None:
        """Listen to a robot spawned with a namespace (a harness hook)."""

    def _after_delete(self, name: str) -> None:
        """Forget a deleted robot (a harness hook)."""

    def _after_world(self, loaded: bool) -> None:
        """Resync the state readers after load_world (True) or unload_world (a harness hook)."""
        self._after_reset()

    def _after_time_back(self) -> None:
        """
        Forget the transforms of the time before (a harness hook): time went back to 0.

        As tf2 clears its buffer when time jumps back: else a lookup of the
        latest transform would answer with the old run's.
        """

    def spawn(self, urdf: PathOrText, *, name: str = '',
              position: Sequence[float] = (0.0, 0.0, 0.0),
              yaw: float = 0.0, orientation: Optional[Sequence[float]] = None,
              allow_renaming: Optional[bool] = None, namespace: str = '',
              at: str = '') -> str:
        """
        Spawn a URDF or an SDF model and return the entity's name.

        ``urdf``: a pybullet_data name (``cube.urdf``), a path (``.urdf`` or
        ``.sdf``), a ``package://`` or ``model://`` URI, or the XML text itself
        (a ``<robot>`` or an ``<sdf>``). Its base link (an SDF model: its
        frame) is placed at ``position`` turned by ``yaw`` (or ``orientation``,
        x y z w), exactly. ``name``: the entity's name; a taken or invalid one is refused
        (NAME_NOT_UNIQUE, NAME_INVALID). Without one, the URDF's robot name,
        made unique (``cube``, ``cube_1``...). ``allow_renaming`` overrides
        either default. With a ``namespace`` it is a driven robot with every
        interface a robot has, there (``robot(name)`` is its handle); our
        R2D2's base link stands 0.47 m above the ground. ``at``: a named pose
        of the world (or an entity): ``position`` and ``yaw`` are then in its
        frame, so ``at='spawn_area'`` alone is exactly that pose.
        """
        uri, text = _resource(urdf)
        renaming = not name if allow_renaming is None else allow_renaming
        self._before_world_change()
        spawned = self._world_backend().spawn(uri, text, name,
                                              _numbers(position, 3, 'position (x, y, z)'),
                                              _orientation(yaw, orientation), renaming,
                                              namespace, at)
        self._after_spawn(spawned, namespace)
        return spawned

    def entities(self) -> List[str]:
        """Return every entity's name: the robot, the ground plane, models, spawned ones."""
        return self._world_backend().entities()

    def entity_state(self, name: str) -> BaseState:
        """Return an entity's pose (of its base link) and twist, both in the world frame."""
        return self._world_backend().entity_state(name)

    def set_entity_state(self, name: str, position: Sequence[float] = (0.0, 0.0, 0.0), *,
                         yaw: float = 0.0, orientation: Optional[Sequence[float]] = None,
                         linear: Sequence[float] = (0.0, 0.0, 0.0),
                         angular: Sequence[float] = (0.0, 0.0, 0.0), at: str = '') -> None:
        """
        Place an entity; its twist is set too, so a pose alone stops it.

        In the world frame, or with ``at`` in a named pose's (or an entity's)
        frame: ``set_entity_state('r2d2', (0, 0, 0.471), at='goal')`` stands
        R2D2 at the goal, facing the way the pose does.
        """
        self._world_backend().set_entity_state(
            name, _numbers(position, 3, 'position (x, y, z)'), _orientation(yaw, orientation),
            _numbers(linear, 3, 'linear (m/s)'), _numbers(angular, 3, 'angular (rad/s)'), at)

    def entity_info(self, name: str) -> EntityInfo:
        """Return an entity's ``EntityInfo(category, description, tags)``."""
        return self._world_backend().entity_info(name)

    def set_entity_info(self, name: str, *, category: Optional[int] = None,
                        description: Optional[str] = None,
                        tags: Optional[Sequence[str]] = None) -> None:
        """Change an entity's category (a label), description or tags; the rest stays."""
        now = self.entity_info(name)
        # An entity's info as read is whole: a category and a description (what the entity
        # is, where it came from) even where none was set.
        assert now.category is not None and now.description is not None
        self._world_backend().set_entity_info(
            name, now.category if category is None else category,
            now.description if description is None else description,
            list(now.tags if tags is None else tags))

    def entity_bounds(self, name: str) -> Region:
        """Return the box around an entity's collision shape, in its base link's frame."""
        return self._world_backend().entity_bounds(name)

    def load_world(self, world: PathOrText) -> WorldEntry:
        """
        Load a world in place of the current one (LoadWorld); return its name, URI, tags.

        ``world``: a URDF, an SDF world or a world manifest, as a path, a
        ``package://`` or ``file://`` URI, a name in the package's ``urdf/``
        (``room.world.yaml``), or the file's text itself. A file must lie in
        a place LoadWorld searches: a test's own world goes in a directory of
        the ``world_paths`` parameter (``SimHarness(world_paths=[dir])``).
        Spawned entities leave, the robots stand at the world's start pose,
        time goes back to 0; the harness then moves one control period on,
        to publish the new world (as ``reset_world``).
        """
        self._before_world_change()
        entry = self._world_backend().load_world(*_world_resource(world))
        self._after_world(True)
        self._after_time_back()
        return entry

    def unload_world(self) -> None:
        """Unload the world (UnloadWorld): nothing steps until a world is loaded again."""
        self._world_backend().unload_world()
        self._after_world(False)
        self._after_time_back()

    def current_world(self) -> Optional[WorldEntry]:
        """Return the world loaded now (None after unload_world)."""
        return self._world_backend().current_world()

    def available_worlds(self, tags: Sequence[str] = (), match_all: bool = False,
                         continue_on_error: bool = False) -> List[WorldEntry]:
        """
        Return the worlds load_world can load, with any (or all) of ``tags``.

        A source that fails (a ``world_paths`` directory gone, or a world
        file in it that does not read) fails the call, RefusedError
        DEFAULT_SOURCES_FAILED, as the standard's GetAvailableWorlds does by
        default. With ``continue_on_error`` that source is left out instead
        (all of its worlds: the standard lists by source) and the rest is
        listed; the call fails only when no source yields a world.
        """
        return self._world_backend().available_worlds(
            TagsFilter(tuple(tags), FILTER_MODE_ALL if match_all else FILTER_MODE_ANY),
            continue_on_error)

    def named_poses(self, tags: Sequence[str] = (), match_all: bool = False
                    ) -> List[NamedPose]:
        """Return the world's named poses with any (or all) of ``tags``, bounds included."""
        return self._world_backend().named_poses(
            TagsFilter(tuple(tags), FILTER_MODE_ALL if match_all else FILTER_MODE_ANY))

    def named_pose(self, name: str) -> NamedPose:
        """
        Return the named pose ``name``: its ``position``, ``orientation``, ``tags``, ``bounds``.

        ``bounds`` are relative to the pose. RefusedError NOT_FOUND when the
        world has no such pose.
        """
        for pose in self.named_poses():
            if pose.name == name:
                return pose
        raise RefusedError('NOT_FOUND', f'no named pose {name[:100]!r} in the world')

    def delete_entity(self, name: str) -> None:
        """Delete an entity, with a robot's interfaces; a full reset brings start-up ones back."""
        self._world_backend().delete(name)
        self._after_delete(name)

    def reset_world(self, *, time: bool = True, state: bool = True,
                    spawned: bool = True) -> None:
        """
        Reset with the standard's scopes (all by default: time back to 0, as at start-up).

        ValueError (one line, nothing reset) with every scope False: the
        standard's empty scope (SCOPE_DEFAULT) means a full reset, which the
        defaults give, so both harnesses refuse a call that asks for none.
        With time back to 0, the transforms looked up before are forgotten,
        as tf2 clears its buffer when time jumps back (so do load_world and
        unload_world): a lookup answers with the new run's, never the old one's.
        """
        if not (time or state or spawned):
            raise ValueError('reset_world: time, state and spawned are all False, which '
                             'resets nothing; call reset_world() for a full reset')
        self._before_reset()
        self._world_backend().reset(time, state, spawned)
        self._after_reset()
        if time:
            self._after_time_back()
