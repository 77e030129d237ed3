"""
The client of ROS 2's simulation standard (``simulation_interfaces``), for any simulator.

:class:`StandardClient` calls the services and the ``SimulateSteps`` action on
a node the caller spins, and raises :class:`StandardError` (a
:class:`~r2d2_sim.errors.RefusedError`) with the result code's name when a
call does not succeed. It is the one client of the standard in the package:
``SimProcess.standard`` is one, the verbs of
:class:`~r2d2_sim.testing.sim_process.SimProcess` (``spawn``,
``entity_state``, ``step_physics``...) go through it, and so does the
conformance kit, which gives it what a client that knows nothing of the
simulator needs: the service names it found by type (``names``), a resend
for idempotent queries (``resend_s``) and a deadline for the whole run
(``deadline``).

Services are named by their interface, ``'SpawnEntity'``, or by the
standard's usual name, ``'spawn_entity'``: without ``names``, each is
``<prefix>/<usual name>`` (``''`` for r2d2_sim, O3DE and Isaac Sim 6;
``'/gzserver'`` for Gazebo). Result codes are named by :func:`code_name`.
"""

import re
import time
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

from rclpy.action import ActionClient
from rclpy.action.client import ClientGoalHandle
from rclpy.client import Client
from rclpy.node import Node
from rclpy.qos import QoSProfile

from r2d2_sim.client import step_count
from r2d2_sim.errors import RefusedError
from r2d2_sim.testing.executor import import_interface
from r2d2_sim.testing.remote import send_request, Wait

__all__ = ['StandardClient', 'StandardError', 'code_name', 'usual_name', 'interface_of',
           'IDEMPOTENT']

# The action's interface name (its usual name is simulate_steps).
ACTION = 'SimulateSteps'
# Queries that may be sent again when a reply is slow: asking twice changes nothing.
IDEMPOTENT = frozenset({
    'GetSimulatorFeatures', 'GetSimulationState', 'GetEntities', 'GetEntitiesStates',
    'GetEntityState', 'GetEntityInfo', 'GetEntityBounds', 'GetSpawnables', 'GetNamedPoses',
    'GetNamedPoseBounds', 'GetCurrentWorld', 'GetAvailableWorlds'})
# The action's feedback comes once a step: keep a long goal's, not the last ten.
FEEDBACK_DEPTH = 1000

Position = Sequence[float]
Orientation = Sequence[float]
IDENTITY = (0.0, 0.0, 0.0, 1.0)


def usual_name(interface: str) -> str:
    """Return an interface's usual service name: GetEntityState -> get_entity_state."""
    return re.sub(r'(?<!^)(?=[A-Z])', '_', interface).lower()


def interface_of(name: str) -> str:
    """Return the interface a usual name stands for: spawn_entity -> SpawnEntity."""
    if '_' in name or name.islower():
        return ''.join(part.capitalize() for part in name.split('_'))
    return name


def code_name(value: int, interface: Optional[str] = None) -> Optional[str]:
    """
    Name a result value: Result's ``RESULT_*`` first, then ``interface``'s own; None if neither.

    ``code_name(101, 'SpawnEntity')`` is ``'NAME_NOT_UNIQUE'``, ``code_name(2)``
    ``'NOT_FOUND'``. ``interface`` is a service (its Response's constants) or a
    message that carries codes of its own (``SpawnResult``).
    """
    from simulation_interfaces import msg, srv
    owners: List[Any] = [msg.Result]
    if interface is not None:
        service = getattr(srv, interface, None)
        owners.append(service.Response if service is not None else getattr(msg, interface))
    for owner in owners:
        for name in dir(owner):
            if name.isupper() and getattr(owner, name) == value:
                return name.replace('RESULT_', '')
    return None


class StandardError(RefusedError):
    """
    A standard service answered with something else than RESULT_OK, or did not answer.

    A :class:`~r2d2_sim.errors.RefusedError` (``code``, ``message``) that
    also names the ``service`` (its usual name): ``str()`` is
    ``CODE: service: message``. ``code`` is the result's name, or
    ``UNAVAILABLE`` (no such service, or not ready in time) or ``TIMEOUT``
    (no reply in time); ``value`` is the result's number (None for those two).
    """

    def __init__(self, service: str, code: str, message: str,
                 value: Optional[int] = None) -> None:
        super().__init__(code, f'{service}: {message}')
        self.service = service
        self.message = message
        self.value = value


class StandardClient:
    """
    The standard's services and action on ``node``, each wait done by ``spin_until(condition, s)``.

    ``prefix`` goes in front of every usual name; ``names`` ({interface:
    service or action name}, as a generic client finds them by type) replaces
    that rule, and an interface it lacks is UNAVAILABLE. ``timeout_s`` bounds
    each wait; ``resend_s``: an idempotent query is sent again after this
    long without a reply (None: never); ``deadline`` (``time.monotonic()``
    time, None: none) bounds every wait of every call, whatever its timeout.
    Without simulation_interfaces it raises
    :class:`~r2d2_sim.testing.executor.MissingInterfaceError` (one line).
    """

    def __init__(self, node: Node, spin_until: Wait, prefix: str = '', timeout_s: float = 30.0,
                 *, names: Optional[Mapping[str, str]] = None,
                 resend_s: Optional[float] = None) -> None:
        needed_by = 'StandardClient (SimProcess.standard, spawn, entities, step_physics...)'
        self.msg, self.srv, self.action = (
            import_interface(f'simulation_interfaces.{part}', needed_by)
            for part in ('msg', 'srv', 'action'))
        self.node = node
        self.spin_until = spin_until
        self.prefix = prefix.rstrip('/')
        self.timeout_s = timeout_s
        self.resend_s = resend_s
        self.deadline: Optional[float] = None
        self.names: Optional[Dict[str, str]] = dict(names) if names is not None else None
        self._clients: Dict[str, Client] = {}
        self._steps: Optional[ActionClient] = None

    # -- names, clients, waits ---------------------------------------------------------------

    def name_of(self, interface: str) -> Optional[str]:
        """Return the service (or action) name of an interface; None when ``names`` lacks it."""
        if self.names is not None:
            return self.names.get(interface)
        return f'{self.prefix}/{usual_name(interface)}'

    def use_names(self, names: Mapping[str, str]) -> None:
        """Take the names found by type; clients of interfaces renamed or gone are dropped."""
        self.names = dict(names)
        for interface in [i for i, c in self._clients.items() if self.name_of(i) != c.srv_name]:
            self.forget(interface)
        if self._steps is not None and self.name_of(ACTION) is None:
            self._steps = None

    def forget(self, interface: str) -> None:
        """Destroy the client of ``interface``; the next call makes a new one."""
        client = self._clients.pop(interface, None)
        if client is not None:
            self.node.destroy_client(client)

    def client(self, interface: str) -> Client:
        """Return the (cached) client of a service; StandardError UNAVAILABLE if it has no name."""
        client = self._clients.get(interface)
        if client is None:
            name = self.name_of(interface)
            if name is None:
                raise StandardError(usual_name(interface), 'UNAVAILABLE',
                                    f'no {interface} service under {self.prefix or "/"!r}')
            client = self._clients[interface] = self.node.create_client(
                getattr(self.srv, interface), name)
        return client

    def wait_s(self, timeout_s: Optional[float] = None) -> float:
        """Return how long a wait may last: ``timeout_s`` (the client's), cut at the deadline."""
        wait = self.timeout_s if timeout_s is None else timeout_s
        if self.deadline is not None:
            wait = min(wait, self.deadline - time.monotonic())
        return max(wait, 0.0)

    def wait(self, condition: Callable[[], bool], timeout_s: Optional[float] = None) -> bool:
        """Spin until ``condition()`` holds (True), or the timeout or the deadline passes."""
        return self.spin_until(condition, self.wait_s(timeout_s))

    # -- calls ------------------------------------------------------------------------------

    def send(self, name: str, request: Any, timeout_s: Optional[float] = None) -> Any:
        """
        Call service ``name`` and return its response, whatever its result.

        StandardError UNAVAILABLE when the service has no name or is not
        ready within the timeout, TIMEOUT when it does not answer in time.
        """
        interface = interface_of(name)
        client = self.client(interface)
        timeout = self.wait_s(timeout_s)
        if not self.spin_until(client.service_is_ready, timeout):
            raise StandardError(usual_name(interface), 'UNAVAILABLE',
                                f'{client.srv_name} was not ready within {timeout:g} s')
        resend = self.resend_s if interface in IDEMPOTENT else None
        response = send_request(client, request, self.spin_until, self.wait_s(timeout_s), resend)
        if response is None:
            raise StandardError(usual_name(interface), 'TIMEOUT',
                                f'{client.srv_name} did not answer within {timeout:g} s')
        return response

    def call(self, name: str, request: Any, check: bool = True,
             timeout_s: Optional[float] = None) -> Any:
        """
        Call service ``name`` (``'spawn_entity'`` or ``'SpawnEntity'``); return the response.

        With ``check``, a result other than RESULT_OK is a StandardError
        named by :func:`code_name`.
        """
        response = self.send(name, request, timeout_s)
        result = getattr(response, 'result', None)
        if check and result is not None and result.result != self.msg.Result.RESULT_OK:
            raise self.error(name, response)
        return response

    def error(self, name: str, response: Any) -> StandardError:
        """Return the StandardError of a response's result (its code named)."""
        interface = interface_of(name)
        value = response.result.result
        return StandardError(usual_name(interface), code_name(value, interface) or str(value),
                             response.result.error_message, value)

    # -- requests, built once for every caller ------------------------------------------------

    def state_request(self, state: int) -> Any:
        """Return a SetSimulationState request for ``state`` (SimulationState.STATE_*)."""
        request = self.srv.SetSimulationState.Request()
        request.state.state = state
        return request

    def entity_state_request(self, name: str, position: Position,
                             orientation: Orientation = IDENTITY,
                             linear: Position = (0.0, 0.0, 0.0),
                             angular: Position = (0.0, 0.0, 0.0), frame_id: str = '',
                             stamp: Tuple[int, int] = (0, 0)) -> Any:
        """Return a SetEntityState request: a pose and a twist in ``frame_id``, stamped."""
        request = self.srv.SetEntityState.Request(entity=name)
        state = request.state
        state.header.frame_id = frame_id
        state.header.stamp.sec, state.header.stamp.nanosec = stamp
        fill_pose(state.pose, position, orientation)
        fill_vector(state.twist.linear, linear)
        fill_vector(state.twist.angular, angular)
        return request

    def spawn_request(self, uri: str = '', resource_string: str = '', name: str = '',
                      position: Position = (0.0, 0.0, 0.0), orientation: Orientation = IDENTITY,
                      allow_renaming: bool = True, namespace: str = '', frame_id: str = '',
                      stamp: Tuple[int, int] = (0, 0)) -> Any:
        """Return a SpawnEntity request: a resource (``uri`` or text) at a pose, stamped."""
        request = self.srv.SpawnEntity.Request(
            name=name, allow_renaming=allow_renaming, uri=uri,
            resource_string=resource_string, entity_namespace=namespace)
        pose = request.initial_pose
        pose.header.frame_id = frame_id
        pose.header.stamp.sec, pose.header.stamp.nanosec = stamp
        fill_pose(pose.pose, position, orientation)
        return request

    # -- the services, one verb each ----------------------------------------------------------

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
        self.call('set_simulation_state', self.state_request(state))

    def step(self, steps: int) -> None:
        """
        Step a paused simulation ``steps`` physics steps; returns once they are done.

        ValueError (nothing sent) unless ``steps`` is a whole number >= 0.
        """
        steps = step_count(steps)
        self.call('step_simulation', self.srv.StepSimulation.Request(steps=steps))

    def reset(self, scope: int = 0) -> None:
        """Reset with a ResetSimulation scope bitfield (0: all)."""
        self.call('reset_simulation', self.srv.ResetSimulation.Request(scope=scope))

    def entities(self, pattern: str = '', tags: Sequence[str] = (), match_all: bool = False,
                 bounds: Any = None) -> List[str]:
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

    def entity_info(self, name: str) -> Any:
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

    def entity_bounds(self, name: str) -> Any:
        """Return an entity's Bounds (a box in its base link's frame)."""
        return self.call('get_entity_bounds',
                         self.srv.GetEntityBounds.Request(entity=name)).bounds

    def load_world(self, uri: str = '', resource_string: str = '',
                   fail_on_unsupported_element: bool = False,
                   ignore_missing_or_unsupported_assets: bool = False) -> Any:
        """Load a world (``uri`` or the file's text); return the LoadWorld response."""
        return self.call('load_world', self.srv.LoadWorld.Request(
            uri=uri, resource_string=resource_string,
            fail_on_unsupported_element=fail_on_unsupported_element,
            ignore_missing_or_unsupported_assets=ignore_missing_or_unsupported_assets))

    def unload_world(self) -> None:
        """Unload the world."""
        self.call('unload_world', self.srv.UnloadWorld.Request())

    def current_world(self) -> Any:
        """Return the WorldResource loaded now; None when no world is."""
        response = self.call('get_current_world', self.srv.GetCurrentWorld.Request(),
                             check=False)
        if response.result.result == self.srv.GetCurrentWorld.Response.NO_WORLD_LOADED:
            return None
        if response.result.result != self.msg.Result.RESULT_OK:
            raise self.error('get_current_world', response)
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

    def named_pose_bounds(self, name: str) -> Any:
        """Return a named pose's Bounds (relative to the pose)."""
        return self.call('get_named_pose_bounds',
                         self.srv.GetNamedPoseBounds.Request(name=name)).bounds

    def entity_state(self, name: str) -> Any:
        """Return an entity's EntityState (pose and twist in the world frame)."""
        return self.call('get_entity_state',
                         self.srv.GetEntityState.Request(entity=name)).state

    def set_entity_state(self, name: str, position: Position,
                         orientation: Orientation = IDENTITY,
                         linear: Position = (0.0, 0.0, 0.0),
                         angular: Position = (0.0, 0.0, 0.0),
                         frame_id: str = '') -> None:
        """Place an entity (pose of its base link) moving with a world-frame twist."""
        self.call('set_entity_state', self.entity_state_request(
            name, position, orientation, linear, angular, frame_id))

    def spawn(self, uri: str = '', resource_string: str = '', name: str = '',
              position: Position = (0.0, 0.0, 0.0), orientation: Orientation = IDENTITY,
              allow_renaming: bool = True, namespace: str = '', frame_id: str = '') -> str:
        """Spawn a URDF (``uri`` or ``resource_string``) at a pose; return the entity's name."""
        return self.call('spawn_entity', self.spawn_request(
            uri, resource_string, name, position, orientation, allow_renaming, namespace,
            frame_id)).entity_name

    def delete(self, name: str) -> None:
        """Delete an entity."""
        self.call('delete_entity', self.srv.DeleteEntity.Request(entity=name))

    # -- the action ---------------------------------------------------------------------------

    def action_client(self) -> ActionClient:
        """Return the SimulateSteps action's client once its server is ready (else UNAVAILABLE)."""
        name = self.name_of(ACTION)
        if name is None:
            raise StandardError('simulate_steps', 'UNAVAILABLE',
                                f'no SimulateSteps action under {self.prefix or "/"!r}')
        if self._steps is None:
            self._steps = ActionClient(self.node, self.action.SimulateSteps, name,
                                       feedback_sub_qos_profile=QoSProfile(depth=FEEDBACK_DEPTH))
        steps = self._steps
        timeout = self.wait_s()
        # Ready: its three services answer and its feedback and status topics are linked.
        if not self.spin_until(steps.server_is_ready, timeout):
            raise StandardError('simulate_steps', 'UNAVAILABLE',
                                f'the SimulateSteps action {name} was not ready within '
                                f'{timeout:g} s')
        return steps

    def send_goal(self, steps: int, feedback: Optional[Callable[[Any], None]] = None
                  ) -> ClientGoalHandle:
        """Send a SimulateSteps goal; return its handle (``accepted`` says whether it was)."""
        sent = self.action_client().send_goal_async(self.action.SimulateSteps.Goal(steps=steps),
                                                    feedback_callback=feedback)
        timeout = self.wait_s()
        if not self.spin_until(sent.done, timeout):
            raise StandardError('simulate_steps', 'TIMEOUT',
                                f'a SimulateSteps goal was not answered within {timeout:g} s')
        return sent.result()

    def goal_result(self, handle: ClientGoalHandle, timeout_s: Optional[float] = None
                    ) -> Tuple[int, Any]:
        """Wait for a goal's end; return (its GoalStatus, its SimulateSteps.Result)."""
        future = handle.get_result_async()
        timeout = self.wait_s(timeout_s)
        if not self.spin_until(future.done, timeout):
            raise StandardError('simulate_steps', 'TIMEOUT',
                                f'a SimulateSteps goal did not end within {timeout:g} s')
        return future.result().status, future.result().result

    def simulate_steps(self, steps: int, feedback: Optional[Callable[[Any], None]] = None
                       ) -> Tuple[int, Any]:
        """Run the SimulateSteps action to its end; return (status, result)."""
        return self.goal_result(self.send_goal(steps, feedback))


def fill_pose(pose: Any, position: Position, orientation: Orientation) -> None:
    """Write a position and an (x, y, z, w) orientation into a geometry_msgs Pose."""
    fill_vector(pose.position, position)
    (pose.orientation.x, pose.orientation.y, pose.orientation.z,
     pose.orientation.w) = (float(v) for v in orientation)


def fill_vector(target: Any, values: Position) -> None:
    """Write three numbers into a Vector3 or Point."""
    target.x, target.y, target.z = (float(v) for v in values)
