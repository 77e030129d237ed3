"""
The simulation standard's entity services: list, read, place, describe, bound, spawn, delete.

They translate ``simulation_interfaces`` requests into the core's entity
operations, under the simulator's lock: reads of an
:class:`~r2d2_sim.ros.seams.EntityReads` (the core's
:class:`~r2d2_sim.sim.entities.Entities`), changes of an
:class:`~r2d2_sim.ros.seams.EntityChanges` (the core's
:class:`~r2d2_sim.sim.simulation.Simulation`). A spawn's files (an SDF
model's includes and meshes among them) are read before the lock is taken:
only the body's creation holds the physics. Every refusal becomes the
standard's result code with a one-line message.
:class:`~r2d2_sim.ros.standard.server.SimulationInterfaces` makes them beside
its simulation control, on the same node.
"""

from contextlib import contextmanager
import threading
from types import ModuleType
from typing import Any, Callable, Iterator, List, Optional

from geometry_msgs.msg import Vector3
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.timing import stamp_of
from r2d2_sim.ros.seams import EntityChanges, EntityReads
from r2d2_sim.sim.entities import name_filter, SpawnRequest
from r2d2_sim.sim.bounds import Region, REGION_KINDS
from r2d2_sim.sim.spawnables import spawnable_uris
from r2d2_sim.sim.tags import check_filter, tags_match

__all__ = ['Activity', 'EntityServices', 'Replies', 'SPAWNABLE_DIRECTORIES', 'region_of',
           'fill_bounds']

SPAWNABLE_DIRECTORIES = ('package://r2d2_sim/urdf',)


class Activity:
    """What runs now that excludes the rest: a step request, a world being loaded."""

    def __init__(self) -> None:
        self.stepping = threading.Lock()  # held by a step request, a load or an unload
        self.loading = threading.Event()  # set while a world loads or unloads

    def busy(self) -> str:
        """Return what the holder of ``stepping`` is doing, for a refusal's message."""
        return 'a world is loading' if self.loading.is_set() else 'a step request is running'


class Replies:
    """Setting a reply's result: OK on every success (a default Result reads as unsupported)."""

    _msg: Any = None  # simulation_interfaces.msg (no stubs), set by each service
    _log: Optional[RcutilsLogger] = None  # the node's, for what no request should cause

    def _guarded(self, callback: Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
        """
        Return ``callback`` answering OPERATION_FAILED for an error nobody foresaw.

        An exception that escapes a service callback ends the executor's spin,
        and with it the simulator: a request must never do that.
        """
        def guarded(request: Any, response: Any) -> Any:
            try:
                return callback(request, response)
            except Exception as exc:  # a defect here, answered and logged, not fatal
                what = f'{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ""}'
                if self._log is not None:
                    self._log.error(f'{callback.__name__} failed unexpectedly ({what})')
                if hasattr(response, 'result'):
                    return self._fail(response, 'OPERATION_FAILED', f'unexpected error: {what}')
                return response
        return guarded

    def _ok(self, response: Any, result_field: str = 'result') -> Any:
        getattr(response, result_field).result = self._msg.Result.RESULT_OK
        return response

    def _fail(self, response: Any, code: str, message: str, owner: Optional[type] = None) -> Any:
        """Set a generic result (NOT_FOUND...) or the service's own code (NAME_NOT_UNIQUE...)."""
        generic = getattr(self._msg.Result, f'RESULT_{code}', None)
        value = generic if generic is not None else getattr(owner or type(response), code)
        response.result.result = value
        response.result.error_message = message
        return response

    def _fail_entity(self, response: Any, error: RefusedError,
                     owner: Optional[type] = None) -> Any:
        return self._fail(response, error.code, error.message, owner)


def region_of(bounds: Any) -> Region:
    """Return a Bounds message as the core's Region (checked there); unknown types too."""
    kind = REGION_KINDS[bounds.type] if bounds.type < len(REGION_KINDS) else str(bounds.type)
    return Region(kind, tuple((p.x, p.y, p.z) for p in bounds.points))


def fill_bounds(msg: Any, region: Region) -> Any:
    """Fill a Bounds message from a Region; return it."""
    msg.type = REGION_KINDS.index(region.kind)
    msg.points = [Vector3(x=float(x), y=float(y), z=float(z)) for x, y, z in region.points]
    return msg


class EntityServices(Replies):
    """
    The standard's entity services: list, read, place, describe, spawn, delete.

    Served on ``server``: reads of ``reads``, changes of ``changes``, each
    under ``lock`` (the simulator's). A change while ``activity`` says a world
    loads is refused (INCORRECT_STATE): the load would drop it with the old world.
    """

    def __init__(self, reads: EntityReads, changes: EntityChanges, lock: threading.RLock,
                 activity: Activity, server: Node, msg: ModuleType, srv: ModuleType) -> None:
        self._reads = reads
        self._changes = changes
        self._lock = lock
        self._activity = activity
        self._msg = msg
        self._log = server.get_logger()
        services = (
            ('get_entities', srv.GetEntities, self._entities),
            ('get_entities_states', srv.GetEntitiesStates, self._entities_states),
            ('get_entity_state', srv.GetEntityState, self._entity_state),
            ('set_entity_state', srv.SetEntityState, self._set_entity_state),
            ('get_entity_info', srv.GetEntityInfo, self._entity_info),
            ('set_entity_info', srv.SetEntityInfo, self._set_entity_info),
            ('get_entity_bounds', srv.GetEntityBounds, self._entity_bounds),
            ('spawn_entity', srv.SpawnEntity, self._spawn),
            ('spawn_entities', srv.SpawnEntities, self._spawn_many),
            ('delete_entity', srv.DeleteEntity, self._delete),
            ('get_spawnables', srv.GetSpawnables, self._spawnables),
        )
        for name, srv_type, callback in services:
            server.create_service(srv_type, name, self._guarded(callback))

    @contextmanager
    def _changing(self) -> Iterator[None]:
        """Hold the lock for a change; RefusedError INCORRECT_STATE while a world loads."""
        with self._lock:  # checked under it: a load that began meanwhile is seen
            if self._activity.loading.is_set():
                raise RefusedError('INCORRECT_STATE', 'a world is loading: entities cannot '
                                                      'change until it is loaded')
            yield

    def _matching(self, filters: Any) -> List[str]:
        """Return the names the filters pick: regex (search), categories, tags, bounds (AND)."""
        reads = self._reads
        matches = name_filter(filters.filter)
        tags = check_filter(filters.tags.tags, filters.tags.filter_mode)
        bounds = filters.bounds
        if bounds.type >= len(REGION_KINDS):
            raise RefusedError('FEATURE_UNSUPPORTED', f'unknown bounds type {bounds.type}: '
                                                      'empty, box, convex hull or sphere')
        names = [n for n in reads.names() if matches(n)]
        if filters.categories:
            wanted = {c.category for c in filters.categories}
            names = [n for n in names if reads.category(n) in wanted]
        if tags.tags:
            names = [n for n in names if tags_match(reads.tags(n), tags)]
        if bounds.type != bounds.TYPE_EMPTY:
            inside = set(reads.overlapping(region_of(bounds)))
            names = [n for n in names if n in inside]
        return names

    def _entities(self, request: Any, response: Any) -> Any:
        try:
            with self._lock:
                response.entities = self._matching(request.filters)
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _entities_states(self, request: Any, response: Any) -> Any:
        try:
            with self._lock:
                names = self._matching(request.filters)
                response.states = [self._state_message(n) for n in names]
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        response.entities = names
        return self._ok(response)

    def _state_message(self, name: str) -> Any:
        state = self._reads.state(name)
        msg = self._msg.EntityState()
        msg.header.frame_id = self._reads.world_frame_id
        msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_of(self._changes.time_ns)
        p, q = msg.pose.position, msg.pose.orientation
        p.x, p.y, p.z = state.position
        q.x, q.y, q.z, q.w = state.orientation
        v, w = msg.twist.linear, msg.twist.angular
        v.x, v.y, v.z = state.linear_velocity
        w.x, w.y, w.z = state.angular_velocity
        # The acceleration stays 0 (documented): PyBullet gives none, and a finite
        # difference would read every body every step and be wrong across a teleport.
        return msg

    def _entity_state(self, request: Any, response: Any) -> Any:
        try:
            with self._lock:
                response.state = self._state_message(request.entity)
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _set_entity_state(self, request: Any, response: Any) -> Any:
        state = request.state
        p, q = state.pose.position, state.pose.orientation
        v, w = state.twist.linear, state.twist.angular
        a, b = state.acceleration.linear, state.acceleration.angular
        try:
            with self._changing():
                self._changes.set_entity_state(
                    request.entity, state.header.frame_id, (p.x, p.y, p.z),
                    (q.x, q.y, q.z, q.w), (v.x, v.y, v.z), (w.x, w.y, w.z),
                    (a.x, a.y, a.z, b.x, b.y, b.z))
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _entity_info(self, request: Any, response: Any) -> Any:
        try:
            with self._lock:
                info = self._reads.info(request.entity)
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        response.info.category.category = info.category
        response.info.description = info.description
        response.info.tags = list(info.tags)
        return self._ok(response)

    def _set_entity_info(self, request: Any, response: Any) -> Any:
        info = request.info
        try:
            with self._changing():
                self._changes.set_entity_info(request.entity, info.category.category,
                                              info.description, list(info.tags))
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _entity_bounds(self, request: Any, response: Any) -> Any:
        try:
            with self._lock:
                region = self._reads.bounds(request.entity)
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        fill_bounds(response.bounds, region)
        return self._ok(response)

    def _spawn_one(self, name: str, allow_renaming: bool, uri: str, resource_string: str,
                   namespace: str, pose: Any) -> str:
        """
        Spawn in the core (a driven robot with a namespace); return the entity name.

        The files are read first, outside the lock (the physics keeps its rate
        while an SDF model's meshes convert); the lock is held for the body.
        A spawn refused (a world loading, too) deletes the temporary files
        read for it (a resource_string's, an SDF model's converted URDF):
        the core closes them only on refusals of its own.
        """
        p, q = pose.pose.position, pose.pose.orientation
        request = SpawnRequest(name, allow_renaming, uri, resource_string, namespace,
                               pose.header.frame_id, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))
        spawnable = self._reads.read(request)
        try:
            with self._changing():
                return self._changes.spawn(request, spawnable)
        except BaseException:
            if spawnable.file is not None:
                spawnable.file.close()  # closing twice does nothing
            raise

    def _spawn(self, request: Any, response: Any) -> Any:
        try:
            response.entity_name = self._spawn_one(
                request.name, request.allow_renaming, request.uri, request.resource_string,
                request.entity_namespace, request.initial_pose)
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _spawn_many(self, request: Any, response: Any) -> Any:
        if self._activity.loading.is_set():  # each spawn checks again, under the lock
            return self._fail(response, 'INCORRECT_STATE', 'a world is loading: entities '
                                                           'cannot change until it is loaded')
        failed = False
        for spawn in request.spawn_requests:
            result = self._msg.SpawnResult()
            try:
                result.entity_name = self._spawn_one(
                    spawn.name, spawn.allow_renaming, spawn.entity_resource.uri,
                    spawn.entity_resource.resource_string, spawn.entity_namespace,
                    spawn.initial_pose)
                self._ok(result)
            except RefusedError as exc:
                failed = True
                self._fail(result, exc.code, exc.message, self._msg.SpawnResult)
            response.results.append(result)
        if failed:
            return self._fail(response, 'ENTITIES_SPAWN_FAILED', 'at least one entity was '
                                                                 'not spawned: see results')
        return self._ok(response)

    def _delete(self, request: Any, response: Any) -> Any:
        try:
            with self._changing():
                self._changes.delete_entity(request.entity)
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _spawnables(self, request: Any, response: Any) -> Any:
        """
        List the URDFs a spawn takes from this package and pybullet_data; and ``sources``'.

        Each source adds to those (the standard's "additional sources"): a
        directory (a path, ``file://``, ``package://``) its ``.urdf`` and ``.sdf``
        files a spawn takes, each once; one named above adds nothing; others
        are named in the reply's error_message, which stays OK.
        """
        known = SPAWNABLE_DIRECTORIES + ('pybullet_data',)
        for uri in spawnable_uris():
            source = known[0] if uri.startswith(known[0]) else 'pybullet_data'
            response.spawnables.append(self._msg.Spawnable(uri=uri,
                                                           description=f'URDF from {source}'))
        unknown = []
        listed = {spawnable.uri for spawnable in response.spawnables}
        for source in (source.rstrip('/') for source in request.sources):
            if source in known:
                continue
            files = self._reads.listed(source)
            if files is None:
                unknown.append(source)
                continue
            for path in files:
                if path not in listed:  # a directory named twice (a path, then file://)
                    listed.add(path)
                    response.spawnables.append(self._msg.Spawnable(
                        uri=path, description=f'{path.rpartition(".")[2].upper()} from '
                                              f'{source[:200]}'))
        self._ok(response)
        if unknown:
            response.result.error_message = ('unknown sources left out (not a directory): '
                                             f'{", ".join(s[:200] for s in unknown)}')
        return response
