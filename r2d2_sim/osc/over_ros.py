"""
scenario_execution's step-based simulation over ROS: any simulator of the simulation standard.

``scenario_execution --simulation r2d2_sim.osc:StandardSimulation scenario.osc``
runs the same scenario as :class:`~.in_process.R2D2Simulation` against a
simulator running elsewhere (``sim_node``, Gazebo...), on plain rclpy (no
py_trees_ros): its services are found by type under the scenario's
``simulator_namespace`` (the conformance kit's discovery), whatever their
names; the scenario holds it paused and steps it one control period per tick
(StepSimulation), so the run is in lockstep as in process. ``reset`` pauses
it, loads the scenario's world if another is loaded, resets it (ALL), places
the robot at the scenario's start and spawns its boxes.

What the standard offers decides the checks here: the robot's pose from
GetEntityState; contact and clearance from GetEntities' bounds filter (the
entities whose collision shapes meet the robot's bounds box, grown by the
distance asked), sampled once per control period. A box is never smaller than
the robot, so a check that passes here passes in process; near its limit one
may fail here only. Velocity commands go on ``<namespace>/cmd_vel``; r2d2_sim
says which namespace each robot has and confirms each command arrived before
the next step (its ``get_status``), so that runs repeat.
"""

import argparse
import json
import math
import os
import struct
from typing import Any, Dict, List, Optional, Sequence, Tuple

from geometry_msgs.msg import Twist

from r2d2_sim.apps.cli import positive_number
from r2d2_sim.conformance.discovery import find_interfaces, normal_prefix, simulator_levels
from r2d2_sim.errors import RefusedError, ScenarioError
from r2d2_sim.model.regions import circle_region, Region as GroundRegion
from r2d2_sim.model.transforms import yaw_of, yaw_to_quaternion
from r2d2_sim.osc.base import ScenarioSimulation, steps_per_period
from r2d2_sim.osc.in_process import GOAL
from r2d2_sim.osc.parameters import read_parameters, RunSettings
from r2d2_sim.osc.port import hull_at, Pose3, Watched
from r2d2_sim.sim.bounds import Region
from r2d2_sim.sim.spawnables import box_urdf
from r2d2_sim.testing.remote import RemoteProbe
from r2d2_sim.testing.standard import StandardClient

__all__ = ['StandardSimulation', 'DISCOVERY_TIMEOUT_S', 'CALL_TIMEOUT_S']

# How long a simulator has to appear under the namespace (wall s): R2D2_OSC_DISCOVERY_S.
DISCOVERY_TIMEOUT_S = 10.0
# Each service call's deadline (wall s): R2D2_OSC_CALL_S.
CALL_TIMEOUT_S = 30.0


def _seconds(variable: str, default: float) -> float:
    """Return the wall seconds an environment variable gives (ScenarioError unless > 0)."""
    text = os.environ.get(variable)
    if text is None:
        return default
    try:
        return positive_number(text)
    except argparse.ArgumentTypeError as exc:
        raise ScenarioError(f'{variable} (seconds) {exc}') from None


# What the scenario needs of the standard.
NEEDED = ('StepSimulation', 'ResetSimulation', 'SetSimulationState', 'GetSimulationState',
          'GetEntityState', 'GetEntities', 'GetEntityBounds', 'SpawnEntity')
# A robot that stands at the start already is not placed again: the same bits as the reset
# left them, so a run repeats the in-process one (a SetEntityState, even to the same pose,
# changes the run). PyBullet keeps positions in float32 (0.3 reads back 0.30000001192...):
# x and y are compared with the start rounded to float32, within SAME_POSE (m), which holds at
# any distance from the origin (float32's step is 1e-6 m at 8 m, 8e-6 m at 100 m). The yaw is
# compared within SAME_YAW (rad): it comes from a float32 quaternion (components <= 1, a step
# of at most 6e-8), through the simulator's own Euler conversion and body offset, whose last
# bits cannot be predicted here.
SAME_POSE = 1e-9
SAME_YAW = 1e-6
TRIGGER = 'std_srvs/srv/Trigger'


def _float32(value: float) -> float:
    """Return ``value`` rounded to float32, as PyBullet keeps a position."""
    return float(struct.unpack('f', struct.pack('f', value))[0])


def _bounds_region(bounds: Any) -> Region:
    kinds = {bounds.TYPE_BOX: 'box', bounds.TYPE_CONVEX_HULL: 'convex_hull',
             bounds.TYPE_SPHERE: 'sphere'}
    kind = kinds.get(bounds.type, 'empty')
    points = tuple((p.x, p.y, p.z) for p in bounds.points)
    return Region.box(points[1], points[0]) if kind == 'box' else Region(kind, points)


def _bounds_message(region: Region) -> Any:
    from geometry_msgs.msg import Vector3
    from simulation_interfaces.msg import Bounds
    kinds = {'box': Bounds.TYPE_BOX, 'convex_hull': Bounds.TYPE_CONVEX_HULL,
             'sphere': Bounds.TYPE_SPHERE, 'empty': Bounds.TYPE_EMPTY}
    return Bounds(type=kinds[region.kind],
                  points=[Vector3(x=float(x), y=float(y), z=float(z))
                          for x, y, z in region.points])


class _Watch:
    """One entity's checks over the standard, sampled after each control period."""

    def __init__(self, entity: str, tip_angle_rad: float, clearance_m: float) -> None:
        self.entity, self.tip_cos, self.clearance_m = entity, math.cos(tip_angle_rad), clearance_m
        self.touched: Optional[Tuple[str, float]] = None
        self.within: Optional[Tuple[str, float]] = None
        self.tipped_s: Optional[float] = None

    def seen(self) -> Watched:
        touched, within = self.touched or (None, None), self.within or (None, None)
        return Watched(touched[0], touched[1], within[0], within[1], None, self.tipped_s)


class StandardSimulation(ScenarioSimulation):
    """
    A simulator of the standard, over ROS, stepped by scenario_execution one period a tick.

    Made with no arguments; connects at the first ``reset`` to the
    simulator under its ``simulator_namespace`` parameter, on the domain of
    ``ROS_DOMAIN_ID``. Leaves the simulator running at ``shutdown``.
    """

    def __init__(self) -> None:
        self.probe: Optional[RemoteProbe] = None
        self.client: Optional[StandardClient] = None
        self.namespace = ''
        self.settings: Optional[RunSettings] = None
        self.error: Optional[str] = None
        self._call_s = CALL_TIMEOUT_S  # R2D2_OSC_CALL_S, read when connecting
        self.playing = True
        self.logger: Any = None
        self._steps_per_period = 0
        self._step_s = 0.0  # the simulator's physics step (s)
        self._status: Any = None  # r2d2_sim's get_status client, when the simulator has one
        self._publishers: Dict[str, Any] = {}
        self._watches: Dict[int, _Watch] = {}  # each check's own, by its token
        self._poses: Dict[str, Pose3] = {}  # this period's, read once
        self._bounds: Dict[str, Region] = {}
        self._steps = 0  # physics steps sent since the simulator's time was last 0

    def start(self, values: Dict[str, Any]) -> None:
        """Put the simulator where the scenario begins (see :mod:`.parameters`), paused."""
        self.error = None
        self.playing = True
        self._watches, self._poses, self._bounds = {}, {}, {}
        try:
            self.settings = read_parameters(values)
            self._connect(self.settings.simulator_namespace)
            self._start(self.settings)
        except ScenarioError as exc:
            self._fail(str(exc))
        except RefusedError as exc:
            self._fail(f'{exc.code}: {exc.message}')

    # -- the connection: the standard found by type ------------------------------------------

    def _connect(self, namespace: str) -> None:
        namespace = normal_prefix(namespace)
        if self.client is not None and namespace == self.namespace:
            return
        self._disconnect()
        probe = self.probe = RemoteProbe(int(os.environ.get('ROS_DOMAIN_ID', '0')),
                                         '_r2d2_osc')
        timeout_s = _seconds('R2D2_OSC_DISCOVERY_S', DISCOVERY_TIMEOUT_S)
        self._call_s = _seconds('R2D2_OSC_CALL_S', CALL_TIMEOUT_S)
        found: Dict[str, str] = {}
        levels: List[str] = []

        def answered() -> bool:
            nonlocal found, levels
            graph = probe.node.get_service_names_and_types()
            levels = simulator_levels(graph)
            found = find_interfaces(graph, namespace)[0]
            return all(interface in found for interface in NEEDED)
        if not probe.spin_until(answered, timeout_s):
            elsewhere = ', '.join(levels) or 'none'
            missing = ', '.join(i for i in NEEDED if i not in found)
            raise ScenarioError(
                f'no simulator answers under simulator_namespace {namespace!r} within '
                f'{timeout_s:g} s (missing {missing}); simulators answer under: {elsewhere}')
        self.namespace = namespace
        self.client = StandardClient(probe.node, probe.spin_until, timeout_s=self._call_s,
                                     names=found, resend_s=1.0)
        status = [name for name, types in probe.node.get_service_names_and_types()
                  if TRIGGER in types and name.endswith('/get_status')
                  and normal_prefix(name.rsplit('/', 2)[0]) == namespace]
        self._status = (probe.node.create_client(_trigger(), sorted(status)[0])
                        if status else None)

    def _physics_step_s(self) -> float:
        """Return the simulator's physics step (s): its features' custom_info says (r2d2_sim)."""
        client = self._client()
        response = client.call('get_simulator_features',
                               client.srv.GetSimulatorFeatures.Request())
        try:
            step_s = float(json.loads(response.features.custom_info)['step_s'])
        except (ValueError, KeyError, TypeError):
            step_s = math.nan
        if not (math.isfinite(step_s) and step_s > 0.0):
            raise ScenarioError('the simulator does not say its physics step (custom_info '
                                '"step_s" of GetSimulatorFeatures): cannot step it one control '
                                'period at a time')
        return step_s

    def _disconnect(self) -> None:
        self._publishers = {}
        self._status = None
        self.client = None
        if self.probe is not None:
            self.probe.close()
            self.probe = None

    def _client(self) -> StandardClient:
        if self.client is None:
            raise RefusedError('OPERATION_FAILED', self.error or 'no simulator is connected')
        return self.client

    def _start(self, settings: RunSettings) -> None:
        client, scenario = self._client(), settings.scenario
        self._steps_per_period = 0
        step_s = self._physics_step_s()  # asked at each reset: it may have restarted
        self._steps_per_period = steps_per_period(1.0 / step_s, "the simulator's physics rate")
        self._step_s = step_s
        self._hold()
        if scenario.world:
            current = client.current_world()
            if current is None or current.world_resource.uri != scenario.world:
                client.load_world(uri=scenario.world)
        client.reset(0)
        self._hold()
        state = client.entity_state(settings.robot)  # NOT_FOUND names the entity
        self._place(settings, state)
        for index, box in enumerate(scenario.obstacles):
            client.spawn(resource_string=box_urdf(box.size), name=f'box_{index}',
                         position=(box.x, box.y, box.size[2] / 2.0),
                         orientation=yaw_to_quaternion(box.yaw), allow_renaming=False)
        self._steps = 0

    def _place(self, settings: RunSettings, state: Any) -> None:
        """Put the robot at the scenario's start, unless it stands there already."""
        start, pose = settings.scenario.start, state.pose
        q = pose.orientation
        yaw = yaw_of((q.x, q.y, q.z, q.w))
        if (abs(pose.position.x - _float32(start.x)) <= SAME_POSE
                and abs(pose.position.y - _float32(start.y)) <= SAME_POSE
                and abs(math.remainder(yaw - start.yaw, 2 * math.pi)) <= SAME_YAW):
            return
        self._client().set_entity_state(settings.robot,
                                        (start.x, start.y, pose.position.z),
                                        yaw_to_quaternion(start.yaw))

    def _back_to_start(self) -> None:
        """
        Put the robot back at the scenario's start after a reset or a world load.

        The simulator resets it to its own initial pose, which is not the
        scenario's start unless it was started with the scenario's parameters;
        in process the robot goes back to the scenario's start. A world without
        the robot leaves nothing to place.
        """
        if self.settings is None:
            return
        try:
            state = self._client().entity_state(self.settings.robot)
        except RefusedError as exc:
            if exc.code == 'NOT_FOUND':
                return
            raise
        self._place(self.settings, state)

    def _hold(self) -> None:
        """Pause the simulator unless it already holds (PAUSED, or STOPPED: paused at time 0)."""
        client = self._client()
        states = client.msg.SimulationState
        if client.state() not in (states.STATE_PAUSED, states.STATE_STOPPED):
            client.set_state(states.STATE_PAUSED)

    # -- stepping -----------------------------------------------------------------------------

    def step(self) -> None:
        """
        Step one control period while playing; then sample every watched entity.

        A refusal (the simulator gone or going away mid-run) is the run's one
        line: the next action fails with it (scenario_execution's loop lets
        any exception from here out as a traceback, with no test.xml).
        """
        if self.error or self.client is None or not self.playing:
            return
        try:
            self.client.step(self._steps_per_period)
            self._steps += self._steps_per_period
            self._poses = {}
            for watch in self._watches.values():
                self._sample(watch)
        except RefusedError as exc:
            self._fail(f'the simulator failed mid-run: {exc.code}: {exc.message}')

    def _sample(self, watch: _Watch) -> None:
        try:
            pose = self.pose(watch.entity)
            bounds = self.bounds(watch.entity)
        except RefusedError:
            return  # it left the world: nothing more to see
        now = self.time_s
        if watch.touched is None:
            touched = self._others(watch.entity, hull_at(bounds, pose))
            if touched:
                watch.touched = (touched[0], now)
        if watch.within is None and watch.clearance_m > 0.0:
            near = self._others(watch.entity, hull_at(bounds, pose, watch.clearance_m))
            if near:
                watch.within = (near[0], now)
        x, y, _, _ = pose[1]
        if watch.tipped_s is None and 1.0 - 2.0 * (x * x + y * y) < watch.tip_cos:
            watch.tipped_s = now

    def _others(self, entity: str, region: Region) -> List[str]:
        return [name for name in self.meeting(region) if name != entity]

    def shutdown(self) -> None:
        """Disconnect; the simulator keeps running (it is someone else's)."""
        self._disconnect()

    # -- the port: what the actions ask ------------------------------------------------------

    @property
    def time_s(self) -> float:
        """Return the simulated time (s): the steps sent since it was 0, each the simulator's."""
        return self._steps * self._step_s

    def spawn(self, name: str, uri: str, position: Sequence[float],
              orientation: Sequence[float], allow_renaming: bool, namespace: str) -> str:
        """Spawn an entity (SpawnEntity); return its name."""
        return self._client().spawn(uri=uri, name=name, position=position,
                                    orientation=orientation, allow_renaming=allow_renaming,
                                    namespace=namespace)

    def delete(self, name: str) -> None:
        """Delete an entity (DeleteEntity)."""
        self._client().delete(name)

    def set_entity_state(self, name: str, position: Sequence[float],
                         orientation: Sequence[float], linear: Sequence[float],
                         angular: Sequence[float]) -> None:
        """Place an entity (SetEntityState)."""
        self._client().set_entity_state(name, position, orientation, linear, angular)
        self._poses.pop(name, None)

    def load_world(self, uri: str) -> None:
        """Load a world (LoadWorld): STOPPED after it, the robot at the scenario's start."""
        self._client().load_world(uri=uri)
        self.playing = False
        self._poses, self._bounds = {}, {}
        self._steps = 0  # a world loads at time 0
        self._back_to_start()

    def unload_world(self) -> None:
        """Unload the world (UnloadWorld)."""
        self._client().unload_world()
        self.playing = False
        self._poses, self._bounds = {}, {}
        self._steps = 0

    def reset_simulation(self) -> None:
        """Reset all (ResetSimulation ALL), kept paused, the robot at the scenario's start."""
        self._client().reset(0)
        self._hold()
        self._poses = {}
        self._steps = 0
        self._back_to_start()

    def step_physics(self, steps: int) -> None:
        """Step a paused scenario (StepSimulation)."""
        self._check_paused()
        self._client().step(steps)
        self._steps += steps
        self._poses = {}

    def _check_world(self) -> None:
        client = self._client()
        if client.state() == client.msg.SimulationState.STATE_NO_WORLD:
            raise RefusedError('INCORRECT_STATE', 'no world is loaded: load_world first')

    def command(self, entity: str, namespace: str, linear: float, angular: float) -> None:
        """Publish a Twist on the robot's cmd_vel; with r2d2_sim, wait until it was taken."""
        probe = self.probe
        if probe is None:
            raise RefusedError('OPERATION_FAILED', self.error or 'no simulator is connected')
        robots = self._robots()
        if robots is not None and entity not in robots:
            raise RefusedError('NOT_FOUND', f'no robot named {entity!r} to drive; robots: '
                                            f'{", ".join(robots) or "none"}')
        if robots is not None:
            namespace = robots[entity]['namespace']
        else:
            namespace = self.namespace.rstrip('/') + '/' + namespace.strip('/')
        topic = namespace.rstrip('/') + '/cmd_vel'
        publisher = self._publishers.get(topic)
        if publisher is None:
            publisher = self._publishers[topic] = probe.node.create_publisher(Twist, topic, 10)
            if not probe.spin_until(lambda: publisher.get_subscription_count() > 0,
                                    self._call_s):
                raise RefusedError('NOT_FOUND', f'nothing takes commands on {topic}')
        twist = Twist()
        twist.linear.x, twist.angular.z = float(linear), float(angular)
        before = robots[entity]['commands_received'] if robots is not None else None
        publisher.publish(twist)
        if before is not None:
            def taken() -> bool:
                now = self._robots()
                return now is not None and now[entity]['commands_received'] > before
            if not probe.spin_until(taken, self._call_s):
                raise RefusedError('OPERATION_FAILED', f'{topic}: the command was not taken')

    def _robots(self) -> Optional[Dict[str, Any]]:
        """Return r2d2_sim's robots (namespace, commands taken) by name; None for others."""
        if self._status is None or self.probe is None:
            return None
        from std_srvs.srv import Trigger
        response = self.probe.call_client(self._status, Trigger.Request(), self._call_s)
        if response is None:
            raise RefusedError('OPERATION_FAILED', 'the simulator\'s get_status did not answer')
        return json.loads(response.message)['robots']

    def pose(self, entity: str) -> Pose3:
        """Return the pose GetEntityState gives, read once per control period."""
        pose = self._poses.get(entity)
        if pose is None:
            p = self._client().entity_state(entity).pose
            pose = self._poses[entity] = ((p.position.x, p.position.y, p.position.z),
                                          (p.orientation.x, p.orientation.y, p.orientation.z,
                                           p.orientation.w))
        return pose

    def region(self, name: str, tolerance_m: float) -> GroundRegion:
        """Return the scenario's goal ('goal'), or a circle around a named pose (GetNamedPoses)."""
        if name == GOAL and self.settings is not None:
            return self.settings.scenario.goal
        poses = {p.name: p for p in self._client().named_poses()}
        pose = poses.get(name)
        if pose is None:
            raise RefusedError('NOT_FOUND', f'no named pose {name!r} in the world; it has: '
                                            f'{", ".join(sorted(poses)) or "none"}')
        position = pose.pose.position
        return circle_region(position.x, position.y, tolerance_m)

    def meeting(self, region: Region) -> List[str]:
        """Return the entities that meet a region (GetEntities with a bounds filter)."""
        return self._client().entities(bounds=_bounds_message(region))

    def bounds(self, entity: str) -> Region:
        """Return the box around an entity (GetEntityBounds), read once per entity."""
        bounds = self._bounds.get(entity)
        if bounds is None:
            bounds = self._bounds[entity] = _bounds_region(self._client().entity_bounds(entity))
        return bounds

    def watch(self, entity: str, tip_angle_rad: float, clearance_m: float, token: int
              ) -> Watched:
        """Return what ``entity`` did since the watch ``token`` began: now, then each period."""
        watch = self._watches.get(token)
        if watch is None:
            self.pose(entity)  # NOT_FOUND now, not at the next step
            watch = self._watches[token] = _Watch(entity, tip_angle_rad, clearance_m)
            self._sample(watch)
        return watch.seen()

    def unwatch(self, token: int) -> None:
        """Stop sampling the watch ``token``: its check ended."""
        self._watches.pop(token, None)


def _trigger() -> Any:
    from std_srvs.srv import Trigger
    return Trigger
