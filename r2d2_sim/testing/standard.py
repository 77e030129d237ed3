"""
A client of ROS 2's simulation standard (``simulation_interfaces``), for any simulator.

:class:`StandardClient` calls the services and the action by their standard
names under a prefix (``''`` for r2d2_sim, O3DE and Isaac Sim; ``'/gzserver'``
for Gazebo), on a node the caller spins, and raises :class:`StandardError`
with the result code's name when a call does not succeed. ``SimProcess.standard``
is one; the verbs of :class:`~r2d2_sim.testing.sim_process.SimProcess`
(``spawn``, ``entity_state``, ``step_physics``...) use it.
"""

from typing import Callable, List, Optional, Sequence

from rclpy.action import ActionClient
from rclpy.node import Node

from r2d2_sim.errors import RefusedError

__all__ = ['StandardClient', 'StandardError']


class StandardError(RefusedError):
    """
    A standard service answered with something else than RESULT_OK.

    A :class:`~r2d2_sim.errors.RefusedError` (``code``, ``message``) that
    also names the ``service``: ``str()`` is ``CODE: service: message``.
    """

    def __init__(self, service: str, code: str, message: str) -> None:
        super().__init__(code, f'{service}: {message}')
        self.service = service
        self.message = message


def _code_name(response, value: int) -> str:
    """Name a result value: the generic RESULT_* names first, then the service's own constants."""
    from simulation_interfaces.msg import Result
    for owner in (Result, type(response)):
        for name in dir(owner):
            if name.isupper() and getattr(owner, name) == value:
                return name.replace('RESULT_', '')
    return str(value)


class StandardClient:
    """
    The standard's services on ``node``, each call waited for by ``spin_until(condition, s)``.

    ``prefix`` goes in front of every name; ``timeout_s`` bounds each call.
    """

    def __init__(self, node: Node, spin_until: Callable[[Callable[[], bool], float], bool],
                 prefix: str = '', timeout_s: float = 30.0) -> None:
        from simulation_interfaces import action, msg, srv
        self.msg, self.srv = msg, srv
        self._node = node
        self._spin_until = spin_until
        self._prefix = prefix.rstrip('/')
        self.timeout_s = timeout_s
        self._clients = {}
        self._steps = ActionClient(node, action.SimulateSteps, f'{self._prefix}/simulate_steps')

    def call(self, name: str, request, check: bool = True):
        """Call service ``name`` (e.g. 'spawn_entity') and return the response."""
        srv_type = self._service_types()[name]
        client = self._clients.get(name)
        if client is None:
            client = self._clients[name] = self._node.create_client(
                srv_type, f'{self._prefix}/{name}')
        if not self._spin_until(client.service_is_ready, self.timeout_s):
            raise StandardError(name, 'UNAVAILABLE', 'the service is not there')
        future = client.call_async(request)
        if not self._spin_until(future.done, self.timeout_s):
            raise StandardError(name, 'TIMEOUT', f'no answer within {self.timeout_s:g} s')
        response = future.result()
        result = getattr(response, 'result', None)
        if check and result is not None and result.result != self.msg.Result.RESULT_OK:
            raise StandardError(name, _code_name(response, result.result), result.error_message)
        return response

    def _service_types(self):
        srv = self.srv
        return {'get_simulator_features': srv.GetSimulatorFeatures,
                'get_simulation_state': srv.GetSimulationState,
                'set_simulation_state': srv.SetSimulationState,
                'step_simulation': srv.StepSimulation, 'reset_simulation': srv.ResetSimulation,
                'get_entities': srv.GetEntities, 'get_entities_states': srv.GetEntitiesStates,
                'get_entity_state': srv.GetEntityState, 'set_entity_state': srv.SetEntityState,
                'get_entity_info': srv.GetEntityInfo, 'set_entity_info': srv.SetEntityInfo,
                'get_entity_bounds': srv.GetEntityBounds, 'spawn_entity': srv.SpawnEntity,
                'spawn_entities': srv.SpawnEntities, 'delete_entity': srv.DeleteEntity,
                'get_spawnables': srv.GetSpawnables,
                'get_available_worlds': srv.GetAvailableWorlds, 'load_world': srv.LoadWorld,
                'unload_world': srv.UnloadWorld, 'get_current_world': srv.GetCurrentWorld,
                'get_named_poses': srv.GetNamedPoses,
                'get_named_pose_bounds': srv.GetNamedPoseBounds}

    def features(self) -> List[int]:
        """Return the feature codes the simulator declares."""
        return list(self.call('get_simulator_features',
                              self.srv.GetSimulatorFeatures.Request()).features.features)

    def state(self) -> int:
        """Return the simulation state, one of SimulationState's ``STATE_*`` constants."""
        return self.call('get_simulation_state',
                         self.srv.GetSimulationState.Request()).state.state

    def set_state(self, state: int) -> None:
        """Ask for a simulation state (SimulationState.STATE_PLAYING, _PAUSED, _STOPPED)."""
        request = self.srv.SetSimulationState.Request()
        request.state.state = state
        self.call('set_simulation_state', request)

    def step(self, steps: int) -> None:
        """Step a paused simulation ``steps`` physics steps; returns once they are done."""
        self.call('step_simulation', self.srv.StepSimulation.Request(steps=steps))

    def reset(self, scope: int = 0) -> None:
        """Reset with a ResetSimulation scope bitfield (0: all)."""
        self.call('reset_simulation', self.srv.ResetSimulation.Request(scope=scope))

    def entities(self, pattern: str = '', tags: Sequence[str] = (), match_all: bool = False,
                 bounds=None) -> List[str]:
        """
        Return the names of the entities the filters pick.

        ``pattern``: a regex a part of the name matches; ``tags``: any of them
        (all, with ``match_all``); ``bounds``: a Bounds message they overlap.
        """
        request = self.srv.GetEntities.Request()
        request.filters.filter = pattern
        request.filters.tags.tags = list(tags)
        request.filters.tags.filter_mode = 1 if match_all else 0
        if bounds is not None:
            request.filters.bounds = bounds
        return list(self.call('get_entities', request).entities)

    def entity_info(self, name: str):
        """Return an entity's EntityInfo (category, description, tags)."""
        return self.call('get_entity_info', self.srv.GetEntityInfo.Request(entity=name)).info

    def set_entity_info(self, name: str, category: int, description: str = '',
                        tags: Sequence[str] = ()) -> None:
        """Set an entity's category, description and tags (all three, as the standard does)."""
        request = self.srv.SetEntityInfo.Request(entity=name)
        request.info.category.category = category
        request.info.description = description
        request.info.tags = list(tags)
        self.call('set_entity_info', request)

    def entity_bounds(self, name: str):
        """Return an entity's Bounds (a box in its base link's frame)."""
        return self.call('get_entity_bounds',
                         self.srv.GetEntityBounds.Request(entity=name)).bounds

    def load_world(self, uri: str = '', resource_string: str = '',
                   fail_on_unsupported_element: bool = False,
                   ignore_missing_or_unsupported_assets: bool = False):
        """Load a world (``uri`` or the file's text); return the LoadWorld response."""
        return self.call('load_world', self.srv.LoadWorld.Request(
            uri=uri, resource_string=resource_string,
            fail_on_unsupported_element=fail_on_unsupported_element,
            ignore_missing_or_unsupported_assets=ignore_missing_or_unsupported_assets))

    def unload_world(self) -> None:
        """Unload the world."""
        self.call('unload_world', self.srv.UnloadWorld.Request())

    def current_world(self):
        """Return the WorldResource loaded now; None when no world is."""
        response = self.call('get_current_world', self.srv.GetCurrentWorld.Request(),
                             check=False)
        if response.result.result == self.srv.GetCurrentWorld.Response.NO_WORLD_LOADED:
            return None
        if response.result.result != self.msg.Result.RESULT_OK:
            code = _code_name(response, response.result.result)
            raise StandardError('get_current_world', code, response.result.error_message)
        return response.world

    def available_worlds(self, tags: Sequence[str] = (), match_all: bool = False,
                         additional_sources: Sequence[str] = (),
                         continue_on_error: bool = False) -> list:
        """Return the WorldResources GetAvailableWorlds lists."""
        request = self.srv.GetAvailableWorlds.Request(
            additional_sources=list(additional_sources), continue_on_error=continue_on_error)
        request.filter.tags = list(tags)
        request.filter.filter_mode = 1 if match_all else 0
        return list(self.call('get_available_worlds', request).worlds)

    def named_poses(self, tags: Sequence[str] = (), match_all: bool = False) -> list:
        """Return the world's NamedPose messages whose tags pass the filter."""
        request = self.srv.GetNamedPoses.Request()
        request.tags.tags = list(tags)
        request.tags.filter_mode = 1 if match_all else 0
        return list(self.call('get_named_poses', request).poses)

    def named_pose_bounds(self, name: str):
        """Return a named pose's Bounds (relative to the pose)."""
        return self.call('get_named_pose_bounds',
                         self.srv.GetNamedPoseBounds.Request(name=name)).bounds

    def entity_state(self, name: str):
        """Return an entity's EntityState (pose and twist in the world frame)."""
        return self.call('get_entity_state',
                         self.srv.GetEntityState.Request(entity=name)).state

    def set_entity_state(self, name: str, position: Sequence[float],
                         orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
                         linear: Sequence[float] = (0.0, 0.0, 0.0),
                         angular: Sequence[float] = (0.0, 0.0, 0.0),
                         frame_id: str = '') -> None:
        """Place an entity (pose of its base link) moving with a world-frame twist."""
        request = self.srv.SetEntityState.Request(entity=name)
        state = request.state
        state.header.frame_id = frame_id
        _fill_pose(state.pose, position, orientation)
        (state.twist.linear.x, state.twist.linear.y, state.twist.linear.z) = linear
        (state.twist.angular.x, state.twist.angular.y, state.twist.angular.z) = angular
        self.call('set_entity_state', request)

    def spawn(self, uri: str = '', resource_string: str = '', name: str = '',
              position: Sequence[float] = (0.0, 0.0, 0.0),
              orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0),
              allow_renaming: bool = True, namespace: str = '', frame_id: str = '') -> str:
        """Spawn a URDF (``uri`` or ``resource_string``) at a pose; return the entity's name."""
        request = self.srv.SpawnEntity.Request(
            name=name, allow_renaming=allow_renaming, uri=uri,
            resource_string=resource_string, entity_namespace=namespace)
        request.initial_pose.header.frame_id = frame_id
        _fill_pose(request.initial_pose.pose, position, orientation)
        return self.call('spawn_entity', request).entity_name

    def delete(self, name: str) -> None:
        """Delete an entity."""
        self.call('delete_entity', self.srv.DeleteEntity.Request(entity=name))

    def simulate_steps(self, steps: int, feedback: Optional[Callable] = None):
        """Run the SimulateSteps action to its end; return (status, result)."""
        from simulation_interfaces.action import SimulateSteps
        if not self._spin_until(lambda: self._steps.server_is_ready(), self.timeout_s):
            raise StandardError('simulate_steps', 'UNAVAILABLE', 'the action is not there')
        sent = self._steps.send_goal_async(SimulateSteps.Goal(steps=steps),
                                           feedback_callback=feedback)
        if not self._spin_until(sent.done, self.timeout_s):
            raise StandardError('simulate_steps', 'TIMEOUT', 'the goal was not answered')
        result = sent.result().get_result_async()
        if not self._spin_until(result.done, self.timeout_s):
            raise StandardError('simulate_steps', 'TIMEOUT', 'no result')
        return result.result().status, result.result().result


def _fill_pose(pose, position: Sequence[float], orientation: Sequence[float]) -> None:
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in position)
    (pose.orientation.x, pose.orientation.y, pose.orientation.z,
     pose.orientation.w) = (float(v) for v in orientation)
