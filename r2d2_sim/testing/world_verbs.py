"""
Changing the world from a test: spawn, place, read, delete, reset with a scope, step physics.

Both harnesses have these verbs: :class:`~r2d2_sim.testing.harness.SimHarness`
calls the simulation core in its own process (no interface package needed),
:class:`~r2d2_sim.testing.sim_process.SimProcess` the standard's services
(``simulation_interfaces``). A refusal is a :class:`~r2d2_sim.errors.RefusedError`
in both (a :class:`~r2d2_sim.testing.standard.StandardError` through the
services), its ``code`` the standard's result name (``NOT_FOUND``,
``NAME_NOT_UNIQUE``...).
"""

import math
from typing import List, Optional, Sequence

from r2d2_sim.model.transforms import BaseState
from r2d2_sim.sim.entities import SpawnRequest

__all__ = ['WorldVerbs', 'CoreWorld', 'StandardWorld']

IDENTITY = (0.0, 0.0, 0.0, 1.0)


def _orientation(yaw: float, orientation: Optional[Sequence[float]]) -> tuple:
    if orientation is not None:
        return tuple(orientation)
    return 0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)


def _resource(urdf: str) -> tuple:
    """Return (uri, resource_string): XML text goes as a resource string, anything else a uri."""
    return ('', urdf) if urdf.lstrip().startswith('<') else (urdf, '')


class CoreWorld:
    """The verbs on a SimNode in this process: its core's operations, under the node's lock."""

    def __init__(self, node) -> None:
        self._node = node

    def spawn(self, uri, resource_string, name, position, orientation, allow_renaming,
              namespace='') -> str:
        with self._node.lock:
            return self._node.simulation.spawn(SpawnRequest(
                name, allow_renaming, uri, resource_string, namespace, '', position,
                orientation))

    def entity_state(self, name: str) -> BaseState:
        with self._node.lock:
            return self._node.simulation.entity_state(name)

    def set_entity_state(self, name, position, orientation, linear, angular) -> None:
        with self._node.lock:
            self._node.simulation.set_entity_state(name, '', position, orientation, linear,
                                                   angular)

    def delete(self, name: str) -> None:
        with self._node.lock:
            self._node.simulation.delete_entity(name)

    def entities(self) -> List[str]:
        with self._node.lock:
            return self._node.simulation.entity_names()

    def reset(self, time: bool, state: bool, spawned: bool) -> None:
        self._node.reset_simulation(time=time, state=state, spawned=spawned)


class StandardWorld:
    """The verbs through a :class:`~r2d2_sim.testing.standard.StandardClient`."""

    def __init__(self, client) -> None:
        self._client = client

    def spawn(self, uri, resource_string, name, position, orientation, allow_renaming,
              namespace='') -> str:
        return self._client.spawn(uri, resource_string, name, position, orientation,
                                  allow_renaming, namespace)

    def entity_state(self, name: str) -> BaseState:
        msg = self._client.entity_state(name)
        p, q, v, w = msg.pose.position, msg.pose.orientation, msg.twist.linear, msg.twist.angular
        return BaseState((p.x, p.y, p.z), (q.x, q.y, q.z, q.w), (v.x, v.y, v.z),
                         (w.x, w.y, w.z))

    def set_entity_state(self, name, position, orientation, linear, angular) -> None:
        self._client.set_entity_state(name, position, orientation, linear, angular)

    def delete(self, name: str) -> None:
        self._client.delete(name)

    def entities(self) -> List[str]:
        return self._client.entities()

    def reset(self, time: bool, state: bool, spawned: bool) -> None:
        scope = (1 if time else 0) | (2 if state else 0) | (4 if spawned else 0)
        self._client.reset(scope or 255)


class WorldVerbs:
    """A harness's world verbs, on ``self._world_backend()`` (a CoreWorld or StandardWorld)."""

    def _world_backend(self):
        raise NotImplementedError

    def _before_reset(self) -> None:
        """Take what is still on its way before reset_world (a harness hook)."""

    def _after_reset(self) -> None:
        """Resync the state readers after reset_world (a harness hook)."""

    def _after_spawn(self, name: str, namespace: str) -> None:
        """Listen to a robot spawned with a namespace (a harness hook)."""

    def _after_delete(self, name: str) -> None:
        """Forget a deleted robot (a harness hook)."""

    def spawn(self, urdf: str, *, name: str = '', position: Sequence[float] = (0.0, 0.0, 0.0),
              yaw: float = 0.0, orientation: Optional[Sequence[float]] = None,
              allow_renaming: Optional[bool] = None, namespace: str = '') -> str:
        """
        Spawn a URDF and return the entity's name.

        ``urdf``: a pybullet_data name (``cube.urdf``), a path, a
        ``package://`` URI, or the XML text itself. Its base link is placed at
        ``position`` turned by ``yaw`` (or ``orientation``, x y z w), exactly.
        ``name``: the entity's name; a taken or invalid one is refused
        (NAME_NOT_UNIQUE, NAME_INVALID). Without one, the URDF's robot name,
        made unique (``cube``, ``cube_1``...). ``allow_renaming`` overrides
        either default. With a ``namespace`` it is a driven robot with every
        interface a robot has, there (``robot(name)`` is its handle); our
        R2D2's base link stands 0.47 m above the ground.
        """
        uri, text = _resource(urdf)
        renaming = not name if allow_renaming is None else allow_renaming
        spawned = self._world_backend().spawn(uri, text, name, tuple(position),
                                              _orientation(yaw, orientation), renaming,
                                              namespace)
        self._after_spawn(spawned, namespace)
        return spawned

    def entities(self) -> List[str]:
        """Return every entity's name: the robot, the ground plane, models, spawned ones."""
        return self._world_backend().entities()

    def entity_state(self, name: str) -> BaseState:
        """Return an entity's pose (of its base link) and twist, both in the world frame."""
        return self._world_backend().entity_state(name)

    def set_entity_state(self, name: str, position: Sequence[float], *, yaw: float = 0.0,
                         orientation: Optional[Sequence[float]] = None,
                         linear: Sequence[float] = (0.0, 0.0, 0.0),
                         angular: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        """Place an entity; its twist (world frame) is set too, so a pose alone stops it."""
        self._world_backend().set_entity_state(name, tuple(position),
                                               _orientation(yaw, orientation), tuple(linear),
                                               tuple(angular))

    def delete_entity(self, name: str) -> None:
        """Delete an entity, with a robot's interfaces; a full reset brings start-up ones back."""
        self._world_backend().delete(name)
        self._after_delete(name)

    def reset_world(self, *, time: bool = True, state: bool = True,
                    spawned: bool = True) -> None:
        """Reset with the standard's scopes (all by default: time back to 0, as at start-up)."""
        self._before_reset()
        self._world_backend().reset(time, state, spawned)
        self._after_reset()
