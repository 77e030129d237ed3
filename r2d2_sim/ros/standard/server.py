"""
ROS 2's simulation standard on the simulator node: ``simulation_interfaces`` (Jazzy 1.x).

The services and the action have relative names on the node
(``get_simulator_features``, ``step_simulation``, ``simulate_steps``...), so
they resolve to the root as O3DE, Isaac Sim and the example clients expect,
and move with ``-r __ns:=``. Every reply sets its result: a default
``Result`` (0) means "unsupported". The operations themselves are the core's
(:mod:`r2d2_sim.sim.entities`, :class:`~r2d2_sim.sim.simulation.Simulation`); this
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
bitfield; twists are in the world frame. After UnloadWorld the state is
NO_WORLD ("inactive and cannot be started, stopped, or paused") until a
LoadWorld, which leaves it STOPPED; while one runs, it is LOADING_WORLD: the
old world runs on until the swap (not "inactive"), but nothing can be started,
stopped, paused, stepped or reset meanwhile, which PLAYING or PAUSED would
promise (docs/changing-the-world.md).
"""

import json
import threading
import time
from typing import Any, Callable, Optional, Tuple

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node

from r2d2_sim.ros.quiet_node import NO_TYPE_DESCRIPTION_SERVICE, QuietNode
from r2d2_sim.ros.seams import (
    EntityChanges, EntityReads, SimulatorControl, WorldChanges, WorldReads)
from r2d2_sim.ros.standard.entities import Activity, EntityServices, Replies
from r2d2_sim.ros.standard.worlds import WorldServices
from r2d2_sim.sim.entities import MAX_FILTER_LENGTH
from r2d2_sim.sim.tags import MAX_TAG_LENGTH, MAX_TAGS

__all__ = ['SimulationInterfaces', 'EntityServices', 'WorldServices', 'StandardNode',
           'available', 'STEP_CHUNK', 'FEATURES']

# Physics steps taken per hold of the node's lock by step_simulation: 0.1 s of
# simulated time, a few milliseconds of wall time.
STEP_CHUNK = 24
# Every feature of simulation_interfaces 1.5.1 (all 32): each is implemented.
FEATURES = (
    'SPAWNING', 'DELETING', 'NAMED_POSES', 'POSE_BOUNDS', 'ENTITY_TAGS', 'ENTITY_BOUNDS',
    'ENTITY_BOUNDS_BOX', 'ENTITY_BOUNDS_CONVEX', 'ENTITY_CATEGORIES', 'SPAWNING_RESOURCE_STRING',
    'ENTITY_STATE_GETTING', 'ENTITY_STATE_SETTING', 'ENTITY_INFO_GETTING', 'ENTITY_INFO_SETTING',
    'SPAWNABLES', 'SIMULATION_RESET', 'SIMULATION_RESET_TIME', 'SIMULATION_RESET_STATE',
    'SIMULATION_RESET_SPAWNED', 'SIMULATION_STATE_GETTING', 'SIMULATION_STATE_SETTING',
    'SIMULATION_STATE_PAUSE', 'STEP_SIMULATION_SINGLE', 'STEP_SIMULATION_MULTIPLE',
    'STEP_SIMULATION_ACTION', 'WORLD_LOADING', 'WORLD_RESOURCE_STRING', 'WORLD_TAGS',
    'WORLD_UNLOADING', 'WORLD_INFO_GETTING', 'AVAILABLE_WORLDS', 'SPAWNING_ENTITIES')


def available() -> bool:
    """Return True when simulation_interfaces (with its type support) can be imported."""
    try:
        from simulation_interfaces.srv import GetSimulatorFeatures
        GetSimulatorFeatures.Request.__class__.__import_type_support__()
    except Exception:  # ImportError, or a library of the type support missing
        return False
    return True


class StandardNode(QuietNode):
    """The node the standard's services live on; destroying it twice is harmless."""

    def __init__(self, simulator: Node) -> None:
        name = f'{simulator.get_name()}_standard'
        # A node-local remap wins over a global one: '-r __node:=x' (launch's
        # name=, SimProcess's node_name) renames the simulator, not this node
        # into a second 'x'. The global namespace remap still applies.
        super().__init__(name, context=simulator.context, namespace=simulator.get_namespace(),
                         start_parameter_services=False,
                         cli_args=['--ros-args', '-r', f'__node:={name}'],
                         parameter_overrides=[NO_TYPE_DESCRIPTION_SERVICE])
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


class SimulationInterfaces(Replies):
    """
    The standard for a simulator: its control, its entities, its worlds.

    ``simulator`` pauses, steps and resets; ``entity_reads`` and
    ``entity_changes`` are its entities read and changed, ``world_reads``
    and ``world_changes`` the world around them (the simulator node is both
    ``simulator`` and ``world_changes``). The services live on a node of their own
    beside ``simulator_node`` (the simulator's: ``self.node``, in its context
    and namespace); the entity services are
    :class:`~r2d2_sim.ros.standard.entities.EntityServices`, the world
    services :class:`~r2d2_sim.ros.standard.worlds.WorldServices`.
    ``close()`` (or destroying ``self.node``) takes the services down.
    """

    def __init__(self, simulator: SimulatorControl, entity_reads: EntityReads,
                 entity_changes: EntityChanges, world_reads: WorldReads,
                 world_changes: WorldChanges, simulator_node: Node,
                 on_quit: Optional[Callable[[], None]] = None) -> None:
        from simulation_interfaces import action, msg, srv
        self._simulator = simulator
        self._msg = msg
        self._log = simulator_node.get_logger()
        self._on_quit = on_quit
        self._quitting = False  # QUITTING was answered OK: paused, the exit on its way
        self.activity = Activity()  # one step request or world load at a time
        self._stepping = self.activity.stepping
        self._closing = threading.Event()
        self._steps_action = action.SimulateSteps
        self.node = server = StandardNode(simulator_node)
        group = ReentrantCallbackGroup()  # the long ones, beside everything else
        services = (
            ('get_simulator_features', srv.GetSimulatorFeatures, self._features, None),
            ('get_simulation_state', srv.GetSimulationState, self._get_state, None),
            ('set_simulation_state', srv.SetSimulationState, self._set_state, None),
            ('step_simulation', srv.StepSimulation, self._step, group),
            ('reset_simulation', srv.ResetSimulation, self._reset, None),
        )
        for name, srv_type, callback, callback_group in services:
            server.create_service(srv_type, name, self._guarded(callback),
                                  callback_group=callback_group)
        server.action_server = ActionServer(
            server, action.SimulateSteps, 'simulate_steps', self._simulate_steps,
            goal_callback=self._accept, cancel_callback=self._allow_cancel, callback_group=group)
        self.entities = EntityServices(entity_reads, entity_changes, simulator.lock,
                                       self.activity, server, msg, srv)
        self.worlds = WorldServices(world_reads, world_changes, self.activity, server, msg, srv,
                                    group)

    def stop(self, timeout_s: float = 2.0) -> None:
        """Refuse new steps and wait (up to ``timeout_s``) for a running one to end its chunk."""
        self._closing.set()
        if self._stepping.acquire(timeout=timeout_s):
            self._stepping.release()

    def close(self) -> None:
        """Stop stepping, then take the services down (destroy their node); safe to call twice."""
        self.stop()
        self.node.destroy_node()

    # -- the simulation --------------------------------------------------------------

    def _features(self, request: Any, response: Any) -> Any:
        features = self._msg.SimulatorFeatures
        response.features.features = [getattr(features, name) for name in FEATURES]
        response.features.spawn_formats = ['urdf', 'sdf']
        config = self._simulator.config
        response.features.custom_info = json.dumps({
            'simulator': 'r2d2_sim', 'physics_rate_hz': config.physics_rate_hz,
            'step_s': 1.0 / config.physics_rate_hz, 'world_frame': config.world_frame_id,
            'entity_filter': 'RE2 search on names (a part of the name matches), at most '
                             f'{MAX_FILTER_LENGTH} characters',
            'world_formats': ['urdf', 'sdf', 'r2d2_sim world manifest (*.world.yaml)'],
            'tags': f'at most {MAX_TAGS} per list, {MAX_TAG_LENGTH} characters each'})
        return response

    def state(self) -> int:
        """
        Return the standard's state: PLAYING, STOPPED or PAUSED.

        STOPPED: paused at time 0 with nothing run since the world was as
        launched (a stop, a full reset or a world loaded: "pausing and
        resetting with ALL"; entity changes and later resets keep it), as
        Gazebo's "paused at iteration 0"; a step or a play leaves it. A reset
        of TIME alone from PAUSED reads PAUSED: the world is not the launched one.

        LOADING_WORLD while a world loads or unloads, NO_WORLD after UnloadWorld,
        QUITTING from an OK to it until the process ends.
        """
        state = self._msg.SimulationState
        node = self._simulator
        if self._quitting:
            return state.STATE_QUITTING
        if self.activity.loading.is_set():
            return state.STATE_LOADING_WORLD
        if not node.world_is_loaded:
            return state.STATE_NO_WORLD
        if not node.paused:
            return state.STATE_PLAYING
        if node.step_count == 0 and node.unrun_since_launch:
            return state.STATE_STOPPED
        return state.STATE_PAUSED

    def _get_state(self, request: Any, response: Any) -> Any:
        if self._quitting:
            response.state.state = self._msg.SimulationState.STATE_QUITTING
            return self._ok(response)
        if self.activity.loading.is_set():  # answered at once, not after the load
            response.state.state = self._msg.SimulationState.STATE_LOADING_WORLD
            return self._ok(response)
        with self._simulator.lock:
            response.state.state = self.state()
        return self._ok(response)

    def _set_state(self, request: Any, response: Any) -> Any:
        state, node = self._msg.SimulationState, self._simulator
        wanted = request.state.state
        if wanted == state.STATE_QUITTING:
            return self._quit(response)
        if self._quitting:
            return self._fail(response, 'INCORRECT_TRANSITION', 'the simulator is quitting')
        if self.activity.loading.is_set():
            return self._fail(response, 'INCORRECT_TRANSITION', 'a world is loading: the '
                              'simulation cannot be started, stopped or paused meanwhile')
        with node.lock:
            now = self.state()
            if wanted == now:
                return self._fail(response, 'ALREADY_IN_TARGET_STATE',
                                  'the simulation is in that state already')
            if now == state.STATE_NO_WORLD and wanted != state.STATE_QUITTING:
                return self._fail(response, 'INCORRECT_TRANSITION', 'no world is loaded '
                                  '(UnloadWorld): the simulation cannot be started, stopped or '
                                  'paused; load one (LoadWorld)')
            if wanted in (state.STATE_NO_WORLD, state.STATE_LOADING_WORLD):
                return self._fail(response, 'INCORRECT_TRANSITION', 'NO_WORLD and '
                                  'LOADING_WORLD are reached through UnloadWorld and LoadWorld')
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
            else:
                return self._fail(response, 'INCORRECT_TRANSITION', f'unknown state {wanted}')
        return self._ok(response)

    def _quit(self, response: Any) -> Any:
        """
        Stop the simulation, then exit (SimulationState.msg's QUITTING), after the reply.

        Stopped here is paused under the lock: no step after the reply, a step
        request under way ends at its next chunk, and the state reads
        QUITTING until the process is gone. Not reset: a world built again
        only to be closed would cost time and put ``/clock`` back to 0 for
        whoever still listens.
        """
        if self._on_quit is None:
            return self._fail(response, 'FEATURE_UNSUPPORTED', 'this simulator runs in '
                              'a process it does not own here: it cannot quit')
        if self._quitting:
            return self._fail(response, 'ALREADY_IN_TARGET_STATE', 'the simulator is '
                              'quitting already')
        node = self._simulator
        with node.lock:
            if node.world_is_loaded and not node.paused:
                node.set_paused(True)
            self._quitting = True
            self._closing.set()  # steps: refused from now, a running one ends
        # After the reply has gone out: the process then stops as on SIGINT.
        threading.Timer(0.2, self._on_quit).start()
        return self._ok(response)

    def _step(self, request: Any, response: Any) -> Any:
        error, _ = self._run_steps(request.steps)
        return self._fail(response, 'OPERATION_FAILED', error) if error else self._ok(response)

    def _run_steps(self, steps: int, each: Optional[Callable[[int], bool]] = None,
                   chunk: int = STEP_CHUNK) -> Tuple[Optional[str], int]:
        """
        Step a paused simulation ``steps`` physics steps; return (error text or None, done).

        The node's lock is taken per ``chunk`` of steps; ``each(done)`` after
        each chunk returns False to stop early (a cancel). A node shutting
        down stops it at the next chunk; so does a stop or a reset of any scope
        (the world was put back between chunks, or the clock moved), and
        playing: an error then, with the steps done. Zero steps are checked as
        one is: playing, or no world, fails.
        """
        node = self._simulator
        if not self._stepping.acquire(blocking=False):
            return ('a world is loading' if self.activity.loading.is_set() else
                    'another step request is running'), 0
        done = 0
        start: Optional[int] = None  # the step count it began at
        resets = 0  # and the world's resets then
        try:
            while done < steps or start is None:  # once at least: zero steps are checked
                if self._closing.is_set():
                    return f'the simulator is shutting down (after {done} steps)', done
                with node.lock:
                    if not node.world_is_loaded:
                        return 'no world is loaded (UnloadWorld): load one to step', done
                    if not node.paused:
                        return ('the simulation is playing: pause it first' if done == 0 else
                                f'the simulation was played after {done} steps'), done
                    if start is None:
                        start, resets = node.step_count, node.reset_count
                    elif node.step_count != start + done or node.reset_count != resets:
                        # A stop or a reset between chunks (STATE or SPAWNED alone leave
                        # the step count as it was): never step on from a world put back.
                        return f'the simulation was stopped or reset after {done} steps', done
                    if steps == 0:
                        return None, 0
                    count = min(chunk, steps - done)
                    node.advance(count)
                done += count
                # PyBullet keeps the GIL while it steps: hand it over between
                # chunks, or the other threads (the main loop seeing a SIGINT,
                # the other services) get it only every switch interval.
                time.sleep(0)
                if each is not None and not each(done):
                    break
            return None, done
        finally:
            self._stepping.release()

    def _accept(self, goal_request: Any) -> GoalResponse:
        return GoalResponse.ACCEPT

    def _allow_cancel(self, goal_handle: ServerGoalHandle) -> CancelResponse:
        return CancelResponse.ACCEPT

    def _simulate_steps(self, goal_handle: ServerGoalHandle) -> Any:
        action = self._steps_action
        result = action.Result()
        steps = goal_handle.request.steps

        def feedback(done: int) -> bool:
            goal_handle.publish_feedback(action.Feedback(completed_steps=done,
                                                         remaining_steps=steps - done))
            return not goal_handle.is_cancel_requested
        error, done = self._run_steps(steps, feedback, chunk=1)
        if error is not None:
            goal_handle.abort()
            return self._fail(result, 'OPERATION_FAILED', error)
        if done < steps:  # stopped by a cancel; one that came after the last step changes nothing
            goal_handle.canceled()
        else:
            goal_handle.succeed()
        return self._ok(result)

    def _reset(self, request: Any, response: Any) -> Any:
        scope, reset = request.scope, type(request)
        known = reset.SCOPE_TIME | reset.SCOPE_STATE | reset.SCOPE_SPAWNED
        if scope in (reset.SCOPE_DEFAULT, reset.SCOPE_ALL):
            scope = known
        if scope & ~known:
            return self._fail(response, 'FEATURE_UNSUPPORTED', f'reset scope bits '
                              f'{scope & ~known} are none this simulator knows (TIME 1, '
                              'STATE 2, SPAWNED 4, ALL 255): nothing was reset')
        if self.activity.loading.is_set():
            return self._fail(response, 'INCORRECT_STATE', 'a world is loading')
        with self._simulator.lock:
            if not self._simulator.world_is_loaded:
                return self._fail(response, 'INCORRECT_STATE', 'no world is loaded '
                                  '(UnloadWorld): there is nothing to reset; load one')
            self._simulator.reset_simulation(time=bool(scope & reset.SCOPE_TIME),
                                             state=bool(scope & reset.SCOPE_STATE),
                                             spawned=bool(scope & reset.SCOPE_SPAWNED))
        return self._ok(response)
