"""
ROS 2's simulation standard on the simulator node: ``simulation_interfaces`` (Jazzy 1.x).

The services and the action have relative names on the node
(``get_simulator_features``, ``step_simulation``, ``simulate_steps``...), so
they resolve to the root as O3DE, Isaac Sim and the example clients expect,
and move with ``-r __ns:=``. Every reply sets its result: a default
``Result`` (0) means "unsupported". The operations themselves are the core's
(:mod:`r2d2_sim.entities`, :class:`~r2d2_sim.simulation.Simulation`); this
module only translates, under the simulator's lock, and a long step releases
the lock between chunks so other services, ``cmd_vel`` and cancel requests are
answered meanwhile.

The services live on a node of their own (``<simulator>_standard``, in the
simulator's namespace) for ``sim_node`` to serve from a multi-threaded
executor: a long step in one thread, the other requests in the other. The
simulator node itself stays on a single-threaded executor, whose small wait
set takes a ``cmd_vel`` flood 2-3 times faster.

Where the big simulators disagree, the standard's own text decides: stepping
while playing fails without a step; STOPPED is paused at time 0 in the initial
world, and pausing from it is an incorrect transition; the reset scope is a
bitfield; twists are in the world frame.
"""

import json
import threading
from typing import Callable, Optional

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node

from r2d2_sim.entities import EntityError
from r2d2_sim.timing import stamp_of

__all__ = ['SimulationInterfaces', 'EntityServices', 'StandardNode', 'available', 'STEP_CHUNK']

# Physics steps taken per hold of the node's lock by step_simulation: 0.1 s of
# simulated time, a few milliseconds of wall time.
STEP_CHUNK = 24
SPAWNABLE_DIRECTORIES = ('package://r2d2_sim/urdf',)


def available() -> bool:
    """Return True when simulation_interfaces (with its type support) can be imported."""
    try:
        from simulation_interfaces.srv import GetSimulatorFeatures
        GetSimulatorFeatures.Request.__class__.__import_type_support__()
    except Exception:  # ImportError, or a library of the type support missing
        return False
    return True


class StandardNode(Node):
    """The node the standard's services live on; destroying it twice is harmless."""

    def __init__(self, simulator: Node) -> None:
        super().__init__(f'{simulator.get_name()}_standard', context=simulator.context,
                         namespace=simulator.get_namespace(),
                         start_parameter_services=False)
        self.action_server: Optional[ActionServer] = None
        self._destroyed = False

    def destroy_node(self) -> None:
        """Destroy the action server, then the node, once."""
        if self._destroyed:
            return
        self._destroyed = True
        if self.action_server is not None:
            self.action_server.destroy()
        super().destroy_node()


class _Replies:
    """Setting a reply's result: OK on every success (a default Result reads as unsupported)."""

    _msg = None

    def _ok(self, response, result_field: str = 'result'):
        getattr(response, result_field).result = self._msg.Result.RESULT_OK
        return response

    def _fail(self, response, code: str, message: str, owner=None):
        """Set a generic result (NOT_FOUND...) or the service's own code (NAME_NOT_UNIQUE...)."""
        generic = getattr(self._msg.Result, f'RESULT_{code}', None)
        value = generic if generic is not None else getattr(owner or type(response), code)
        response.result.result = value
        response.result.error_message = message
        return response

    def _fail_entity(self, response, error: EntityError, owner=None):
        return self._fail(response, error.code, str(error), owner)


class SimulationInterfaces(_Replies):
    """
    The standard for ``node`` (a SimNode), served by ``self.node``; entities in EntityServices.

    ``close()`` (or destroying ``self.node``) takes the services down.
    """

    def __init__(self, node, on_quit: Optional[Callable[[], None]] = None) -> None:
        from simulation_interfaces import action, msg, srv
        self._node = node
        self._msg = msg
        self._on_quit = on_quit
        self._stepping = threading.Lock()  # one step request at a time
        self.node = server = StandardNode(node)
        group = ReentrantCallbackGroup()  # the long ones, beside everything else
        services = (
            ('get_simulator_features', srv.GetSimulatorFeatures, self._features, None),
            ('get_simulation_state', srv.GetSimulationState, self._get_state, None),
            ('set_simulation_state', srv.SetSimulationState, self._set_state, None),
            ('step_simulation', srv.StepSimulation, self._step, group),
            ('reset_simulation', srv.ResetSimulation, self._reset, None),
        )
        for name, srv_type, callback, callback_group in services:
            server.create_service(srv_type, name, callback, callback_group=callback_group)
        server.action_server = ActionServer(
            server, action.SimulateSteps, 'simulate_steps', self._simulate_steps,
            goal_callback=self._accept, cancel_callback=self._allow_cancel, callback_group=group)
        self.entities = EntityServices(node, server, msg, srv)

    def close(self) -> None:
        """Take the services down (destroy their node); safe to call twice."""
        self.node.destroy_node()

    # -- the simulation --------------------------------------------------------------

    def _features(self, request, response):
        features = self._msg.SimulatorFeatures
        response.features.features = [getattr(features, name) for name in (
            'SPAWNING', 'DELETING', 'ENTITY_CATEGORIES', 'SPAWNING_RESOURCE_STRING',
            'ENTITY_STATE_GETTING', 'ENTITY_STATE_SETTING', 'ENTITY_INFO_GETTING', 'SPAWNABLES',
            'SIMULATION_RESET', 'SIMULATION_RESET_TIME', 'SIMULATION_RESET_STATE',
            'SIMULATION_RESET_SPAWNED', 'SIMULATION_STATE_GETTING', 'SIMULATION_STATE_SETTING',
            'SIMULATION_STATE_PAUSE', 'STEP_SIMULATION_SINGLE', 'STEP_SIMULATION_MULTIPLE',
            'STEP_SIMULATION_ACTION', 'SPAWNING_ENTITIES')]
        response.features.spawn_formats = ['urdf']
        config = self._node.config
        response.features.custom_info = json.dumps({
            'simulator': 'r2d2_sim', 'physics_rate_hz': config.physics_rate_hz,
            'step_s': 1.0 / config.physics_rate_hz, 'world_frame': config.world_frame_id,
            'entity_filter': 'Python re.search on names (a part of the name matches)'})
        return response

    def state(self) -> int:
        """Return the standard's state: PLAYING, or STOPPED (time 0, initial world), or PAUSED."""
        state = self._msg.SimulationState
        node = self._node
        if not node.paused:
            return state.STATE_PLAYING
        simulation = node.simulation
        if simulation.step_count == 0 and simulation.pristine:
            return state.STATE_STOPPED
        return state.STATE_PAUSED

    def _get_state(self, request, response):
        with self._node.lock:
            response.state.state = self.state()
        return self._ok(response)

    def _set_state(self, request, response):
        state, node = self._msg.SimulationState, self._node
        wanted = request.state.state
        with node.lock:
            now = self.state()
            if wanted == now:
                return self._fail(response, 'ALREADY_IN_TARGET_STATE',
                                  'the simulation is in that state already')
            if wanted == state.STATE_PLAYING:
                node.set_paused(False)
            elif wanted == state.STATE_PAUSED:
                if now == state.STATE_STOPPED:
                    return self._fail(response, 'INCORRECT_TRANSITION', 'a stopped simulation '
                                      'can only be played (step it to pause it at time > 0)')
                node.set_paused(True)
            elif wanted == state.STATE_STOPPED:
                node.set_paused(True)
                node.reset_simulation(time=True, state=True, spawned=True)
            elif wanted == state.STATE_QUITTING and self._on_quit is not None:
                # After the reply has gone out: the process then stops as on SIGINT.
                threading.Timer(0.2, self._on_quit).start()
            elif wanted in (state.STATE_QUITTING, state.STATE_NO_WORLD,
                            state.STATE_LOADING_WORLD):
                return self._fail(response, 'FEATURE_UNSUPPORTED', 'this simulator has one '
                                  'world, loaded at start-up')
            else:
                return self._fail(response, 'INCORRECT_TRANSITION', f'unknown state {wanted}')
        return self._ok(response)

    def _step(self, request, response):
        error = self._run_steps(request.steps)
        return self._fail(response, 'OPERATION_FAILED', error) if error else self._ok(response)

    def _run_steps(self, steps: int, each: Optional[Callable[[int], bool]] = None,
                   chunk: int = STEP_CHUNK) -> Optional[str]:
        """
        Step a paused simulation ``steps`` physics steps; an error text if it was not paused.

        The node's lock is taken per ``chunk`` of steps; ``each(done)`` after
        each chunk returns False to stop early (a cancel).
        """
        node = self._node
        if not self._stepping.acquire(blocking=False):
            return 'another step request is running'
        try:
            done = 0
            while done < steps:
                with node.lock:
                    if not node.paused:
                        return ('the simulation is playing: pause it first' if done == 0 else
                                f'the simulation was played after {done} steps')
                    count = min(chunk, steps - done)
                    node.step_paused(count)
                done += count
                if each is not None and not each(done):
                    break
            return None
        finally:
            self._stepping.release()

    def _accept(self, goal_request):
        return GoalResponse.ACCEPT

    def _allow_cancel(self, goal_handle):
        return CancelResponse.ACCEPT

    def _simulate_steps(self, goal_handle):
        action = self._simulate_steps_type()
        result = action.Result()
        steps = goal_handle.request.steps

        def feedback(done: int) -> bool:
            goal_handle.publish_feedback(action.Feedback(completed_steps=done,
                                                         remaining_steps=steps - done))
            return not goal_handle.is_cancel_requested
        if not self._node.paused:
            goal_handle.abort()
            return self._fail(result, 'OPERATION_FAILED', 'the simulation is playing: '
                                                          'pause it first')
        error = self._run_steps(steps, feedback, chunk=1)
        if error is not None:
            goal_handle.abort()
            return self._fail(result, 'OPERATION_FAILED', error)
        if goal_handle.is_cancel_requested:
            goal_handle.canceled()
        else:
            goal_handle.succeed()
        return self._ok(result)

    def _simulate_steps_type(self):
        from simulation_interfaces.action import SimulateSteps
        return SimulateSteps

    def _reset(self, request, response):
        scope, reset = request.scope, type(request)
        if scope in (reset.SCOPE_DEFAULT, reset.SCOPE_ALL):
            scope = reset.SCOPE_TIME | reset.SCOPE_STATE | reset.SCOPE_SPAWNED
        with self._node.lock:
            self._node.reset_simulation(time=bool(scope & reset.SCOPE_TIME),
                                        state=bool(scope & reset.SCOPE_STATE),
                                        spawned=bool(scope & reset.SCOPE_SPAWNED))
        return self._ok(response)


class EntityServices(_Replies):
    """The standard's entity services on ``node``: list, read, place, describe, spawn, delete."""

    def __init__(self, node, server: Node, msg, srv) -> None:
        """Serve on ``server`` the entities of ``node``'s simulation."""
        self._node = node
        self._msg = msg
        services = (
            ('get_entities', srv.GetEntities, self._entities),
            ('get_entities_states', srv.GetEntitiesStates, self._entities_states),
            ('get_entity_state', srv.GetEntityState, self._entity_state),
            ('set_entity_state', srv.SetEntityState, self._set_entity_state),
            ('get_entity_info', srv.GetEntityInfo, self._entity_info),
            ('spawn_entity', srv.SpawnEntity, self._spawn),
            ('spawn_entities', srv.SpawnEntities, self._spawn_many),
            ('delete_entity', srv.DeleteEntity, self._delete),
            ('get_spawnables', srv.GetSpawnables, self._spawnables),
        )
        for name, srv_type, callback in services:
            server.create_service(srv_type, name, callback)

    def _matching(self, filters):
        """Return the names the filters pick: regex (search), categories, tags, a sphere."""
        import re
        entities = self._node.simulation.entities
        try:
            pattern = re.compile(filters.filter) if filters.filter else None
        except re.error as exc:
            raise EntityError('OPERATION_FAILED', f'bad filter regex: {exc}') from None
        names = [n for n in entities.names() if pattern is None or pattern.search(n)]
        if filters.categories:
            wanted = {c.category for c in filters.categories}
            names = [n for n in names if entities.category(entities.body(n)) in wanted]
        if filters.tags.tags:  # no entity has tags: ANY and ALL both match none
            names = []
        bounds = filters.bounds
        if bounds.type == bounds.TYPE_SPHERE and len(bounds.points) >= 2:
            centre = (bounds.points[0].x, bounds.points[0].y, bounds.points[0].z)
            inside = set(entities.overlapping(centre, bounds.points[1].x))
            names = [n for n in names if n in inside]
        elif bounds.type != bounds.TYPE_EMPTY:
            raise EntityError('FEATURE_UNSUPPORTED', 'only sphere bounds filter entities here')
        return names

    def _entities(self, request, response):
        try:
            with self._node.lock:
                response.entities = self._matching(request.filters)
        except EntityError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _entities_states(self, request, response):
        try:
            with self._node.lock:
                names = self._matching(request.filters)
                response.states = [self._state_message(n) for n in names]
        except EntityError as exc:
            return self._fail_entity(response, exc)
        response.entities = names
        return self._ok(response)

    def _state_message(self, name: str):
        simulation = self._node.simulation
        state = simulation.entities.state(name)
        msg = self._msg.EntityState()
        msg.header.frame_id = simulation.entities.world_frame_id
        msg.header.stamp.sec, msg.header.stamp.nanosec = stamp_of(simulation.time_ns)
        p, q = msg.pose.position, msg.pose.orientation
        p.x, p.y, p.z = state.position
        q.x, q.y, q.z, q.w = state.orientation
        v, w = msg.twist.linear, msg.twist.angular
        v.x, v.y, v.z = state.linear_velocity
        w.x, w.y, w.z = state.angular_velocity
        return msg

    def _entity_state(self, request, response):
        try:
            with self._node.lock:
                response.state = self._state_message(request.entity)
        except EntityError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _set_entity_state(self, request, response):
        state = request.state
        p, q = state.pose.position, state.pose.orientation
        v, w = state.twist.linear, state.twist.angular
        try:
            with self._node.lock:
                self._node.simulation.entities.set_state(
                    request.entity, state.header.frame_id, (p.x, p.y, p.z),
                    (q.x, q.y, q.z, q.w), (v.x, v.y, v.z), (w.x, w.y, w.z))
        except EntityError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _entity_info(self, request, response):
        entities = self._node.simulation.entities
        try:
            with self._node.lock:
                body = entities.body(request.entity)
                response.info.category.category = entities.category(body)
                response.info.description = body.source
        except EntityError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _spawn_one(self, name, allow_renaming, uri, resource_string, namespace, pose):
        """Spawn through the core; return the entity name (EntityError otherwise)."""
        from rclpy.validate_namespace import validate_namespace
        if namespace:
            try:
                validate_namespace(namespace)
            except Exception as exc:  # rclpy raises InvalidNamespaceException
                reason = str(exc).splitlines()[0]  # rclpy adds the name and a caret below
                raise EntityError('NAMESPACE_INVALID', f'{namespace[:100]!r}: {reason}') from None
            raise EntityError('FEATURE_UNSUPPORTED', 'entity_namespace (a driven robot with '
                              'its own ROS interfaces) is not supported yet')
        p, q = pose.pose.position, pose.pose.orientation
        with self._node.lock:
            return self._node.simulation.entities.spawn(
                name, allow_renaming, uri, resource_string, pose.header.frame_id,
                (p.x, p.y, p.z), (q.x, q.y, q.z, q.w))

    def _spawn(self, request, response):
        try:
            response.entity_name = self._spawn_one(
                request.name, request.allow_renaming, request.uri, request.resource_string,
                request.entity_namespace, request.initial_pose)
        except EntityError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _spawn_many(self, request, response):
        failed = False
        for spawn in request.spawn_requests:
            result = self._msg.SpawnResult()
            try:
                result.entity_name = self._spawn_one(
                    spawn.name, spawn.allow_renaming, spawn.entity_resource.uri,
                    spawn.entity_resource.resource_string, spawn.entity_namespace,
                    spawn.initial_pose)
                self._ok(result)
            except EntityError as exc:
                failed = True
                self._fail(result, exc.code, str(exc), self._msg.SpawnResult)
            response.results.append(result)
        if failed:
            return self._fail(response, 'ENTITIES_SPAWN_FAILED', 'at least one entity was '
                                                                 'not spawned: see results')
        return self._ok(response)

    def _delete(self, request, response):
        try:
            with self._node.lock:
                self._node.simulation.entities.delete(request.entity)
        except EntityError as exc:
            return self._fail_entity(response, exc)
        return self._ok(response)

    def _spawnables(self, request, response):
        """List this package's URDFs and pybullet_data's, or those of the ``sources`` asked for."""
        from r2d2_sim.entities import spawnable_uris
        known = SPAWNABLE_DIRECTORIES + ('pybullet_data',)
        sources = list(request.sources) or list(known)
        for uri in spawnable_uris():
            source = known[0] if uri.startswith(known[0]) else 'pybullet_data'
            if source in sources:
                spawnable = self._msg.Spawnable()
                spawnable.uri = uri
                spawnable.description = f'URDF from {source}'
                response.spawnables.append(spawnable)
        self._ok(response)
        unknown = [s for s in sources if s not in known]
        if unknown:
            response.result.error_message = f'unknown sources left out: {", ".join(unknown)}'
        return response
