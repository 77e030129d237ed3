"""
The simulation standard's world services: list, load, unload, tell the world; its named poses.

They translate ``simulation_interfaces`` requests into reads of a
:class:`~r2d2_sim.ros.seams.WorldReads` (the core's
:class:`~r2d2_sim.sim.worlds.files.WorldFiles`) and changes of a
:class:`~r2d2_sim.ros.seams.WorldChanges` (the simulator node, which loads
through its core and pauses at time 0), and every refusal into the
standard's result code with a one-line message.
:class:`~r2d2_sim.ros.standard.server.SimulationInterfaces` makes them beside
its simulation control, on the same node. A load or an unload waits for no
step: while a step request runs it is refused (INCORRECT_STATE), and while it
runs the simulation state is LOADING_WORLD and step requests are refused. A
load reads its world (the files, an SDF world's includes, its meshes
converted) before it takes the simulator's lock, so the physics keeps its
rate meanwhile; then the simulator builds the bodies beside the old world,
taking the lock a few bodies at a time, and swaps the new world in at once.
"""

from types import ModuleType
from typing import Any, Callable

from rclpy.callback_groups import CallbackGroup
from rclpy.node import Node

from r2d2_sim.errors import RefusedError
from r2d2_sim.ros.seams import WorldChanges, WorldReads
from r2d2_sim.ros.standard.entities import Activity, fill_bounds, Replies
from r2d2_sim.sim.tags import check_filter
from r2d2_sim.sim.worlds import LoadOptions, World

__all__ = ['WorldServices']


class WorldServices(Replies):
    """
    The standard's world and named pose services, served on ``server``.

    ``reads`` answers what changes nothing (and reads a world to load),
    ``changes`` loads and unloads under its ``lock``; ``activity`` is shared
    with the step requests; ``group`` is the callback group the load and
    unload run in (beside the other requests).
    """

    def __init__(self, reads: WorldReads, changes: WorldChanges, activity: Activity,
                 server: Node, msg: ModuleType, srv: ModuleType, group: CallbackGroup) -> None:
        self._reads = reads
        self._changes = changes
        self._lock = changes.lock
        self._activity = activity
        self._msg = msg
        self._log = server.get_logger()
        services = (
            ('get_available_worlds', srv.GetAvailableWorlds, self._available, None),
            ('load_world', srv.LoadWorld, self._load, group),
            ('unload_world', srv.UnloadWorld, self._unload, group),
            ('get_current_world', srv.GetCurrentWorld, self._current, None),
            ('get_named_poses', srv.GetNamedPoses, self._named_poses, None),
            ('get_named_pose_bounds', srv.GetNamedPoseBounds, self._named_pose_bounds, None),
        )
        for name, srv_type, callback, callback_group in services:
            server.create_service(srv_type, name, self._guarded(callback),
                                  callback_group=callback_group)

    def _world_resource(self, msg: Any, world: World) -> None:
        msg.name = world.name
        msg.world_resource.uri = world.uri
        msg.world_resource.resource_string = world.resource_string
        msg.description = world.description
        msg.tags = list(world.tags)

    def _available(self, request: Any, response: Any) -> Any:
        try:
            tags = check_filter(request.filter.tags, request.filter.filter_mode)
            with self._lock:
                worlds, note = self._reads.available(
                    list(request.additional_sources), tags, request.offline_only,
                    request.continue_on_error)
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        for world in worlds:
            resource = self._msg.WorldResource(name=world.name, description=world.description,
                                               tags=list(world.tags))
            resource.world_resource.uri = world.uri
            response.worlds.append(resource)
        self._ok(response)
        response.result.error_message = note
        return response

    def _exclusive(self, response: Any, what: Callable[[], Any]) -> Any:
        """
        Run ``what()`` with no step or load running; refuse (INCORRECT_STATE) if one is.

        LOADING_WORLD from here on: ``what`` reads first, then takes the lock.
        """
        activity = self._activity
        if not activity.stepping.acquire(blocking=False):
            return self._fail(response, 'INCORRECT_STATE', f'{activity.busy()}: try again once '
                                                           'it has ended')
        try:
            activity.loading.set()
            try:
                return what()
            finally:
                activity.loading.clear()
        finally:
            activity.stepping.release()

    def _load(self, request: Any, response: Any) -> Any:
        options = LoadOptions(request.fail_on_unsupported_element,
                              request.ignore_missing_or_unsupported_assets)

        def load() -> Any:
            try:
                # No lock: the files, SDF and meshes touch no physics; the load
                # takes the lock itself, a few bodies at a time.
                world = self._reads.read(request.uri, request.resource_string, options)
                self._changes.load_world(world)
            except RefusedError as exc:
                return self._fail_entity(response, exc)
            self._world_resource(response.world, world)
            self._ok(response)
            response.result.error_message = '; '.join(world.notes)
            return response
        return self._exclusive(response, load)

    def _unload(self, request: Any, response: Any) -> Any:
        def unload() -> Any:
            try:
                with self._lock:
                    self._changes.unload_world()
            except RefusedError as exc:
                return self._fail_entity(response, exc)
            return self._ok(response)
        return self._exclusive(response, unload)

    def _current(self, request: Any, response: Any) -> Any:
        with self._lock:
            world = self._reads.current
        if world is None:
            return self._fail(response, 'NO_WORLD_LOADED', 'no world is loaded (UnloadWorld)')
        self._world_resource(response.world, world)
        return self._ok(response)

    def _named_poses(self, request: Any, response: Any) -> Any:
        try:
            tags = check_filter(request.tags.tags, request.tags.filter_mode)
            with self._lock:
                poses = self._reads.named_poses(tags)
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        for pose in poses:
            msg = self._msg.NamedPose(name=pose.name, description=pose.description,
                                      tags=list(pose.tags))
            p, q = msg.pose.position, msg.pose.orientation
            p.x, p.y, p.z = pose.position
            q.x, q.y, q.z, q.w = pose.orientation
            response.poses.append(msg)
        return self._ok(response)

    def _named_pose_bounds(self, request: Any, response: Any) -> Any:
        try:
            with self._lock:
                pose = self._reads.named_pose(request.name)
        except RefusedError as exc:
            return self._fail_entity(response, exc)
        fill_bounds(response.bounds, pose.bounds)
        return self._ok(response)
