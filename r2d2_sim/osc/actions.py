"""
The actions of ``osc.r2d2``: osc.sim's eight over the standard, and what the farm knows.

Each is a scenario_execution action (a py_trees behaviour) that asks the
simulation it was set up with (``--simulation``: an
:class:`~.in_process.R2D2Simulation` or a
:class:`~.over_ros.StandardSimulation`) through the
:class:`~.port.SimulatorPort`; they know nothing of either side. The first
eight have osc.sim's names and arguments (scenario_execution_sim, which needs
an apt ROS install); the rest drive a robot and check what the farm checks.

A refusal fails the action with one line as its feedback and in the log
(``spawn_entity: NAME_NOT_UNIQUE: ...``), never a traceback. Checks
(``assert_*``) run until they fail: put them beside the scenario's steps in
a ``one_of`` (the first branch to end decides).
"""

import itertools
import math
from typing import Any, Dict, Optional, Tuple

import py_trees
from scenario_execution.actions.base_action import BaseAction

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.regions import circle_region, Region as GroundRegion
from r2d2_sim.model.transforms import quaternion_from_rpy
from r2d2_sim.sim.oracles import DEFAULT_TIP_ANGLE_RAD
from r2d2_sim.osc.port import box_ahead, go_to, SimulatorPort, STATES, Watched

__all__ = ['SimAction', 'SpawnEntity', 'DeleteEntity', 'SetEntityState', 'LoadWorld',
           'UnloadWorld', 'ResetSimulation', 'StepSimulation', 'SetSimulationState', 'Drive',
           'DriveTo', 'WaitUntilInRegion', 'WaitUntilAtPose', 'AssertNoContact',
           'AssertMinClearance', 'AssertNotTipped', 'NO_SIMULATION']

Status = py_trees.common.Status

# Each check's watch is its own: a token drawn when the check starts names it.
_TOKENS = itertools.count()

NO_SIMULATION = ('needs an r2d2_sim simulation: run scenario_execution with --simulation '
                 'r2d2_sim.osc:R2D2Simulation (in this process) or --simulation '
                 'r2d2_sim.osc:StandardSimulation (a running simulator, over ROS)')


def given(**values: Any) -> None:
    """Raise ValueError naming the first argument the scenario left without a value."""
    for name, value in values.items():
        if value is None:
            raise ValueError(f'argument {name!r} has no value: give it (it has no default)')


Pose = Tuple[Tuple[float, float, float], Tuple[float, float, float, float]]


def _pose(value: Any, name: str = 'pose') -> Pose:
    """Return (position, orientation x y z w) of an OSC pose_3d's resolved value."""
    if not (isinstance(value, dict) and isinstance(value.get('position'), dict)
            and isinstance(value.get('orientation'), dict)):
        raise ValueError(f'{name} must be a pose_3d (position, orientation), got {value!r}')
    position, orientation = value['position'], value['orientation']
    return ((float(position['x']), float(position['y']), float(position['z'])),
            quaternion_from_rpy(float(orientation['roll']), float(orientation['pitch']),
                                float(orientation['yaw'])))


def _twist(value: Dict[str, Any]) -> Tuple[Tuple[float, float, float],
                                           Tuple[float, float, float]]:
    """Return (linear, angular) of an OSC velocity_6d's resolved value."""
    linear, angular = value['translational'], value['angular']
    return ((float(linear['x']), float(linear['y']), float(linear['z'])),
            (float(angular['roll']), float(angular['pitch']), float(angular['yaw'])))


def _centre(region: GroundRegion) -> Tuple[float, float]:
    values = region.values
    if region.kind == 'circle':
        return values[0], values[1]
    if region.kind == 'box':
        return (values[0] + values[2]) / 2.0, (values[1] + values[3]) / 2.0
    xs, ys = values[0::2], values[1::2]
    return sum(xs) / len(xs), sum(ys) / len(ys)


class SimAction(BaseAction):
    """
    An action on the simulation: :meth:`act` at each tick until it is done.

    ``act(port)`` returns SUCCESS, RUNNING or FAILURE; a RefusedError it
    raises fails the action with its one line. Subclasses take their OSC
    arguments in ``execute`` (called when the action starts).
    """

    def __init__(self) -> None:
        super().__init__()
        self.port: Optional[SimulatorPort] = None
        self.clock: Any = None
        self.failure = ''         # why act() returned FAILURE
        self.failure_line = ''    # the line the action failed with, for a verdict's reason
        self.argument_error = ''  # an argument the scenario left out or gave wrong

    def setup(self, **kwargs: Any) -> None:
        """Take the simulation and the scenario's clock that scenario_execution hands over."""
        simulation = kwargs.get('simulation')
        self.port = simulation if hasattr(simulation, 'watch') else None
        self.clock = kwargs.get('clock')

    def initialise(self) -> None:
        """Take the arguments (``execute``); one missing or malformed fails at update."""
        self.failure_line = self.failure = ''
        self.argument_error = ''
        try:
            super().initialise()
        except (TypeError, ValueError, KeyError) as exc:
            self.argument_error = f'{self.name}: {exc}'

    def now(self) -> float:
        """Return the scenario's time (s): it runs on while the simulation is paused."""
        return self.clock.now() if self.clock is not None else 0.0

    def update(self) -> Status:
        """Act once; a refusal or a mistake found at reset fails with one line."""
        port = self.port
        if port is None:
            return self._fail(f'{self.name}: {NO_SIMULATION}')
        if port.error:
            self.feedback_message = self.failure_line = port.error  # logged once, at reset
            return Status.FAILURE
        if self.argument_error:
            return self._fail(self.argument_error)
        try:
            status = self.act(port)
        except RefusedError as exc:
            return self._fail(f'{self.name}: {exc.code}: {exc.message}')
        except ValueError as exc:  # a value the simulator gave that the action cannot use
            return self._fail(f'{self.name}: {exc}')
        if status == Status.FAILURE:
            return self._fail(self.failure)
        return status

    def _fail(self, line: str) -> Status:
        self.feedback_message = self.failure_line = line
        if self.logger is not None and line:
            self.logger.error(line)
        return Status.FAILURE

    def act(self, port: SimulatorPort) -> Status:
        """Do the action's part of this tick; return its status."""
        raise NotImplementedError


# -- osc.sim's eight, same names and arguments ---------------------------------------------


class SpawnEntity(SimAction):
    """spawn_entity(entity_name, uri, initial_pose, allow_renaming, entity_namespace)."""

    def execute(self, entity_name: str, uri: str, initial_pose: Dict[str, Any],
                allow_renaming: bool, entity_namespace: str) -> None:
        given(entity_name=entity_name, uri=uri, initial_pose=initial_pose)
        self.args = (entity_name, uri, _pose(initial_pose, 'initial_pose'), bool(allow_renaming),
                     entity_namespace)

    def act(self, port: SimulatorPort) -> Status:
        name, uri, (position, orientation), renaming, namespace = self.args
        spawned = port.spawn(name, uri, position, orientation, renaming, namespace)
        self.feedback_message = f'spawned {spawned}'
        return Status.SUCCESS


class DeleteEntity(SimAction):
    """delete_entity(entity)."""

    def execute(self, entity: str) -> None:
        given(entity=entity)
        self.entity = entity

    def act(self, port: SimulatorPort) -> Status:
        port.delete(self.entity)
        return Status.SUCCESS


class SetEntityState(SimAction):
    """set_entity_state(entity, pose, twist, acceleration): acceleration is not set."""

    def execute(self, entity: str, pose: Dict[str, Any], twist: Dict[str, Any],
                acceleration: Dict[str, Any]) -> None:
        given(entity=entity)
        self.entity, self.pose, self.twist = entity, _pose(pose, 'pose'), _twist(twist)

    def act(self, port: SimulatorPort) -> Status:
        port.set_entity_state(self.entity, *self.pose, *self.twist)
        return Status.SUCCESS


class LoadWorld(SimAction):
    """load_world(uri): STOPPED after it; set_simulation_state(playing) goes on."""

    def execute(self, uri: str) -> None:
        given(uri=uri)
        self.uri = uri

    def act(self, port: SimulatorPort) -> Status:
        port.load_world(self.uri)
        return Status.SUCCESS


class UnloadWorld(SimAction):
    """unload_world()."""

    def act(self, port: SimulatorPort) -> Status:
        port.unload_world()
        return Status.SUCCESS


class ResetSimulation(SimAction):
    """reset_simulation(): time, state and spawned entities (ALL)."""

    def act(self, port: SimulatorPort) -> Status:
        port.reset_simulation()
        return Status.SUCCESS


class StepSimulation(SimAction):
    """step_simulation(steps): physics steps of a paused simulation, within this tick."""

    def execute(self, steps: int) -> None:
        self.steps = int(steps)

    def act(self, port: SimulatorPort) -> Status:
        if self.steps < 1:
            raise RefusedError('OPERATION_FAILED', f'steps must be >= 1, got {self.steps}')
        port.step_physics(self.steps)
        return Status.SUCCESS


class SetSimulationState(SimAction):
    """set_simulation_state(state): stopped, playing or paused (the scenario's lockstep)."""

    def execute(self, state: Any) -> None:
        given(state=state)
        # scenario_execution hands an enum over as (name, index).
        self.state = state[0] if isinstance(state, (tuple, list)) else str(state)

    def act(self, port: SimulatorPort) -> Status:
        if self.state not in STATES:
            raise RefusedError('INCORRECT_TRANSITION', f'no state {self.state!r}')
        port.set_state(self.state)
        return Status.SUCCESS


# -- what the farm knows: drive, wait, check -----------------------------------------------


class _Driving(SimAction):
    """An action that commands a robot (``entity``, ``namespace``): stopped when given up."""

    entity = ''
    namespace = ''

    def request_cancel(self) -> bool:
        """Stop the robot when the branch that drove it is given up."""
        if self.port is not None and not self.port.error and self.entity:
            try:
                self.port.command(self.entity, self.namespace, 0.0, 0.0)
            except RefusedError:
                pass  # it left the world: nothing to stop
        return True


class Drive(_Driving):
    """drive(entity, linear, angular, duration, entity_namespace): a velocity held, then 0."""

    def execute(self, entity: str, linear: float, angular: float, duration: float,
                entity_namespace: str) -> None:
        self.entity, self.namespace = entity, entity_namespace
        self.linear, self.angular, self.duration = float(linear), float(angular), float(duration)
        if not self.duration >= 0.0:
            raise ValueError(f'duration must be >= 0, got {self.duration:g} s')
        self.started: Optional[float] = None

    def act(self, port: SimulatorPort) -> Status:
        if self.started is None:
            self.started = self.now()
        # A tick's command holds for the period after it: whole periods up to the duration.
        if self.now() - self.started < self.duration - 1e-9:
            port.command(self.entity, self.namespace, self.linear, self.angular)
            return Status.RUNNING
        port.command(self.entity, self.namespace, 0.0, 0.0)
        return Status.SUCCESS


class DriveTo(_Driving):
    """
    drive_to(entity, pose, speed, stop_distance, tolerance, entity_namespace).

    Heads for a named pose ('goal': the scenario's goal) and stops there;
    stands while anything is within ``stop_distance`` ahead (the standard's
    entities that meet the box in front of it). A stand-in for a robot's own
    navigation, the farm's stopper's law (:func:`~.port.go_to`).
    """

    def execute(self, entity: str, pose: str, speed: float, stop_distance: float,
                tolerance: float, entity_namespace: str) -> None:
        self.entity, self.pose_name, self.namespace = entity, pose, entity_namespace
        self.speed, self.stop_distance = float(speed), float(stop_distance)
        self.tolerance = float(tolerance)
        if not (math.isfinite(self.speed) and self.speed > 0.0):
            # 0 would stand for ever; a negative speed drives away from the pose.
            raise ValueError(f'speed must be > 0, got {self.speed:g} m/s')
        if not (math.isfinite(self.stop_distance) and self.stop_distance >= 0.0):
            raise ValueError(f'stop_distance must be >= 0, got {self.stop_distance:g} m')
        self.region: Optional[GroundRegion] = None

    def act(self, port: SimulatorPort) -> Status:
        if self.region is None:
            self.region = port.region(self.pose_name, self.tolerance)
            self.bounds = port.bounds(self.entity)
        pose = port.pose(self.entity)
        if self.region.contains(pose[0][0], pose[0][1]):
            port.command(self.entity, self.namespace, 0.0, 0.0)
            return Status.SUCCESS
        ahead = box_ahead(self.bounds, pose, self.stop_distance)
        blocked = any(name != self.entity for name in port.meeting(ahead))
        port.command(self.entity, self.namespace,
                     *go_to(pose, _centre(self.region), self.speed, blocked))
        return Status.RUNNING


class WaitUntilInRegion(SimAction):
    """wait_until_in_region(entity, x, y, radius): until its base stands in that circle."""

    def execute(self, entity: str, x: float, y: float, radius: float) -> None:
        given(x=x, y=y, radius=radius)
        self.entity = entity
        self.region = circle_region(float(x), float(y), float(radius))

    def act(self, port: SimulatorPort) -> Status:
        position = port.pose(self.entity)[0]
        return Status.SUCCESS if self.region.contains(position[0], position[1]) \
            else Status.RUNNING


class WaitUntilAtPose(SimAction):
    """wait_until_at_pose(entity, pose, tolerance): 'goal' is the scenario's goal region."""

    def execute(self, entity: str, pose: str, tolerance: float) -> None:
        self.entity, self.pose_name, self.tolerance = entity, pose, float(tolerance)
        self.region: Optional[GroundRegion] = None

    def act(self, port: SimulatorPort) -> Status:
        if self.region is None:
            self.region = port.region(self.pose_name, self.tolerance)
        position = port.pose(self.entity)[0]
        return Status.SUCCESS if self.region.contains(position[0], position[1]) \
            else Status.RUNNING


class _Check(SimAction):
    """
    A check: RUNNING while it holds, FAILURE with the reason the moment it does not.

    It watches from when it starts: what happened (and ended) before, earlier
    in a ``serial``, does not count, over ROS as in process.
    """

    tip_rad = DEFAULT_TIP_ANGLE_RAD  # the run watch's, where the check does not ask
    clearance_m = 0.0
    token = -1                       # its watch, drawn when it starts

    def initialise(self) -> None:
        """Take the arguments; draw a token: the watch begins at the first tick."""
        super().initialise()
        self.token = next(_TOKENS)

    def act(self, port: SimulatorPort) -> Status:
        seen = port.watch(self.entity, self.tip_rad, self.clearance_m, self.token)
        self.failure = self.broken(seen)
        return Status.FAILURE if self.failure else Status.RUNNING

    def request_cancel(self) -> bool:
        """Stop watching when the branch that checked is given up."""
        if self.port is not None and not self.port.error:
            self.port.unwatch(self.token)
        return True

    def broken(self, seen: Watched) -> str:
        """Return why the check failed ('' while it holds)."""
        raise NotImplementedError


class AssertNoContact(_Check):
    """assert_no_contact(entity): fails the moment it touches anything but the floor."""

    def execute(self, entity: str) -> None:
        self.entity = entity

    def broken(self, seen: Watched) -> str:
        if seen.touched is None:
            return ''
        return f'{self.entity} touched {seen.touched} at {seen.touched_s:.3f} s'


class AssertMinClearance(_Check):
    """assert_min_clearance(entity, distance): fails when anything comes nearer."""

    def execute(self, entity: str, distance: float) -> None:
        given(distance=distance)
        distance_m = float(distance)
        if not (math.isfinite(distance_m) and distance_m > 0.0):
            # Nothing is ever nearer than 0 m or less: such a check could never fail.
            raise ValueError(f'distance must be > 0, got {distance_m:g} m')
        self.entity, self.clearance_m = entity, distance_m

    def broken(self, seen: Watched) -> str:
        if seen.within is None:
            return ''
        measured = '' if seen.clearance_m is None else f'{seen.clearance_m:.3f} m, '
        return (f'{self.entity} came within {self.clearance_m:g} m of {seen.within} '
                f'({measured}at {seen.within_s:.3f} s)')


class AssertNotTipped(_Check):
    """assert_not_tipped(entity, angle): fails when it leans further than the angle."""

    def execute(self, entity: str, angle: float) -> None:
        given(angle=angle)
        tip_rad = float(angle)
        if not 0.0 < tip_rad < math.pi:
            # Refused here in degrees, over ROS as in process (whose watch says radians).
            raise ValueError(f'angle must be in (0, 180) deg, got {math.degrees(tip_rad):g} deg')
        self.entity, self.tip_rad = entity, tip_rad

    def broken(self, seen: Watched) -> str:
        if seen.tipped_s is None:
            return ''
        return (f'{self.entity} tipped over (leaned past {math.degrees(self.tip_rad):g} deg) '
                f'at {seen.tipped_s:.3f} s')
