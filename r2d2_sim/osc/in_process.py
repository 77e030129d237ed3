"""
scenario_execution's step-based simulation, in the scenario's process: the core, no ROS.

``scenario_execution --simulation r2d2_sim.osc:R2D2Simulation scenario.osc``
runs a scenario against :class:`R2D2Simulation`: ``reset(**parameters)``
builds a fresh core :class:`~r2d2_sim.sim.simulation.Simulation` for the
farm's Scenario the parameters describe (:mod:`.parameters`: world, start,
goal, boxes, seed, limits), ``step()`` advances one control period
(:data:`CONTROL_PERIOD_S`, whole physics steps) in lockstep with the
behaviour tree, and the actions of :mod:`.actions` change and read the world
through it (:class:`~.port.SimulatorPort`). The same seed gives the same run,
bit for bit.

A scenario author's mistake found at reset (a world or a named pose that does
not exist, a parameter that cannot be) is logged as one line and fails the
scenario at the first action, with that line as its reason: scenario_execution
prints a traceback for an exception raised in ``reset``.
"""

from typing import Any, Dict, List, Optional, Sequence

from r2d2_sim.errors import RefusedError, ScenarioError, SetupError
from r2d2_sim.model.regions import circle_region, Region as GroundRegion
from r2d2_sim.model.transforms import yaw_to_quaternion
from r2d2_sim.osc.base import CONTROL_PERIOD_S, ScenarioSimulation, steps_per_period
from r2d2_sim.osc.parameters import read_parameters, RunSettings
from r2d2_sim.osc.port import Pose3, Watched
from r2d2_sim.sim.bounds import Region
from r2d2_sim.sim.entities import SpawnRequest
from r2d2_sim.sim.oracles import DEFAULT_CLEARANCE_RANGE_M, RunWatch
from r2d2_sim.sim.settings.robots import parse_world
from r2d2_sim.sim.simulation import Simulation
from r2d2_sim.sim.spawnables import box_urdf

__all__ = ['R2D2Simulation', 'CONTROL_PERIOD_S', 'IN_PROCESS_PARAMETERS', 'GOAL',
           'TRAJECTORY_PERIOD_S']

# Under every in-process run: what nobody reads here is not measured (the physics does not
# depend on it, so the run is the same as sim_node's with its defaults).
IN_PROCESS_PARAMETERS: Dict[str, Any] = {'scan_rate': 0.0, 'imu_rate': 0.0,
                                         'publish_rate': 1.0 / CONTROL_PERIOD_S}
# The scenario's goal region, as the run's watch and wait_until_at_pose name it.
GOAL = 'goal'
# The robot's trajectory, for the farm's report, at this period of simulated time.
TRAJECTORY_PERIOD_S = 0.1


def _quiet(text: str) -> None:
    pass


class R2D2Simulation(ScenarioSimulation):
    """
    R2D2 in PyBullet, stepped by scenario_execution: one control period per tick.

    Made with no arguments (scenario_execution's ``--simulation`` does so);
    every run's settings come from the scenario's parameters at ``reset``.
    After a run, :meth:`measures` says what the robot did (the farm's
    Outcome's measures), whatever the verdict.
    """

    def __init__(self) -> None:
        self.simulation: Optional[Simulation] = None
        self.settings: Optional[RunSettings] = None
        # A mistake found at reset, one line: every action fails with it.
        self.error: Optional[str] = None
        self.playing = True
        self.logger: Any = None
        self.warnings: List[str] = []
        self._steps_per_period = 0
        self._run: Optional[RunWatch] = None
        self._watches: Dict[int, RunWatch] = {}  # each check's own, by its token
        # The last run's measures, kept when its simulation is closed (shutdown comes first).
        self._finished: Dict[str, Any] = {}

    def start(self, values: Dict[str, Any]) -> None:
        """Build the world of the scenario's parameters afresh (see :mod:`.parameters`)."""
        self._close()
        self._finished = {}
        self.error = None
        self.playing = True
        self.warnings = []
        try:
            self.settings = read_parameters(values)
            self.simulation = self._build(self.settings)
        except (ScenarioError, SetupError) as exc:
            self._fail(str(exc))
        except RefusedError as exc:
            self._fail(exc.message)

    def _build(self, settings: RunSettings) -> Simulation:
        scenario = settings.scenario
        config, robots = parse_world({**IN_PROCESS_PARAMETERS, **scenario.parameters(),
                                      **settings.parameters})
        steps = steps_per_period(config.physics_rate_hz, 'physics_rate')
        simulation = Simulation(config, robots, warn=self.warnings.append, error=_quiet)
        try:
            for index, box in enumerate(scenario.obstacles):
                simulation.spawn(SpawnRequest(
                    name=f'box_{index}', resource_string=box_urdf(box.size),
                    position=(box.x, box.y, box.size[2] / 2.0),
                    orientation=yaw_to_quaternion(box.yaw)))
            simulation.entities.body(settings.robot)  # NOT_FOUND, listing the entities
            self._run = RunWatch(simulation, settings.robot, regions={GOAL: scenario.goal},
                                 trajectory_period_s=TRAJECTORY_PERIOD_S)
        except BaseException:
            simulation.close()
            raise
        self._steps_per_period = steps
        return simulation

    def step(self) -> None:
        """Advance one control period while playing: :meth:`policy`, then whole physics steps."""
        simulation = self.simulation
        if simulation is None or not self.playing:
            return
        self.policy(simulation)
        for _ in range(self._steps_per_period):
            simulation.step()

    def policy(self, simulation: Simulation) -> None:
        """
        Command the robots for the next control period: override it with your own controller.

        Called before each period's physics steps, with the core simulation
        (``simulation.robots[0].command(linear, angular)``, poses from
        ``simulation.entities``); ``self.settings.scenario`` is the run's
        scenario. Run the subclass with ``--simulation module:YourClass``.
        Does nothing here: the scenario's actions drive.
        """

    def shutdown(self) -> None:
        """Close the physics."""
        self._close()

    def _close(self) -> None:
        if self._run is not None:
            self._finished = self._measures(self._run)
        for watch in self._watches.values():
            watch.close()
        self._watches = {}
        if self._run is not None:
            self._run.close()
            self._run = None
        if self.simulation is not None:
            self.simulation.close()
            self.simulation = None

    def _core(self) -> Simulation:
        if self.simulation is None:
            raise RefusedError('OPERATION_FAILED', self.error or 'the simulation was not reset')
        return self.simulation

    # -- what a run did, for the farm's report ---------------------------------------------

    def measures(self) -> Dict[str, Any]:
        """Return the followed robot's run as the farm's Outcome fields (no verdict), or {}."""
        return self._finished if self._run is None else self._measures(self._run)

    def _measures(self, watch: RunWatch) -> Dict[str, Any]:
        settings = self.settings
        if settings is None:
            return {}
        start = watch.start_ns

        def since(time_ns: Optional[int]) -> Optional[float]:
            return None if time_ns is None else (time_ns - start) / 1e9

        return {'scenario': settings.scenario, 'time_to_goal_s': since(watch.reached.get(GOAL)),
                'clearance_m': watch.clearance.distance_m, 'closest': watch.clearance.other,
                'closest_s': since(watch.clearance.time_ns), 'contacts': tuple(watch.contacts),
                'tipped_s': since(watch.tipped_ns), 'trajectory': tuple(watch.trajectory),
                'steps': watch.steps, 'seconds': (self._core().time_ns - start) / 1e9}

    # -- the port: what the actions ask ------------------------------------------------------

    @property
    def time_s(self) -> float:
        """Return the simulated time (s)."""
        return self._core().time_ns / 1e9

    def spawn(self, name: str, uri: str, position: Sequence[float],
              orientation: Sequence[float], allow_renaming: bool, namespace: str) -> str:
        """Spawn as SpawnEntity does; return the entity's name."""
        x, y, z = position
        qx, qy, qz, qw = orientation
        return self._core().spawn(SpawnRequest(
            name=name, allow_renaming=allow_renaming, uri=uri, namespace=namespace,
            position=(x, y, z), orientation=(qx, qy, qz, qw)))

    def delete(self, name: str) -> None:
        """Delete an entity."""
        self._core().delete_entity(name)

    def set_entity_state(self, name: str, position: Sequence[float],
                         orientation: Sequence[float], linear: Sequence[float],
                         angular: Sequence[float]) -> None:
        """Place an entity, moving with a world-frame twist."""
        self._core().set_entity_state(name, '', position, orientation, linear, angular)

    def load_world(self, uri: str) -> None:
        """Load a world: STOPPED after it, as the standard says (set_simulation_state plays)."""
        self._core().load_world(uri)
        self.playing = False

    def unload_world(self) -> None:
        """Unload the world: nothing steps until a world is loaded."""
        self._core().unload_world()
        self.playing = False

    def reset_simulation(self) -> None:
        """Reset time, state and spawned entities (ResetSimulation ALL)."""
        self._core().reset(time=True, state=True, spawned=True)

    def step_physics(self, steps: int) -> None:
        """Step a paused simulation ``steps`` physics steps, as StepSimulation does."""
        simulation = self._core()
        self._check_paused()
        for _ in range(steps):
            simulation.step()

    def _check_world(self) -> None:
        if not self._core().worlds.is_loaded:
            raise RefusedError('INCORRECT_STATE', 'no world is loaded: load_world first')

    def command(self, entity: str, namespace: str, linear: float, angular: float) -> None:
        """Hand a robot's drive controller a velocity command."""
        simulation = self._core()
        for robot in simulation.robots:
            if robot.name == entity:
                robot.command(linear, angular)
                return
        known = ', '.join(r.name for r in simulation.robots) or 'none'
        raise RefusedError('NOT_FOUND', f'no robot named {entity!r} to drive; robots: {known}')

    def pose(self, entity: str) -> Pose3:
        """Return an entity's base pose in the world."""
        state = self._core().entities.body(entity).world_state()
        return tuple(state.position), tuple(state.orientation)  # type: ignore[return-value]

    def region(self, name: str, tolerance_m: float) -> GroundRegion:
        """Return the scenario's goal ('goal'), or a circle around a named pose of the world."""
        if name == GOAL and self.settings is not None:
            return self.settings.scenario.goal
        world = self._core().worlds.current
        if world is None:
            raise RefusedError('NOT_FOUND', f'no named pose {name!r}: no world is loaded')
        pose = world.named_pose(name)
        return circle_region(pose.position[0], pose.position[1], tolerance_m)

    def meeting(self, region: Region) -> List[str]:
        """Return the entities whose collision shape meets the world region."""
        return self._core().entities.overlapping(region)

    def bounds(self, entity: str) -> Region:
        """Return the box around an entity's collision shape, in its base frame."""
        return self._core().entities.bounds(entity)

    def watch(self, entity: str, tip_angle_rad: float, clearance_m: float, token: int
              ) -> Watched:
        """
        Return what ``entity`` did since the watch ``token`` began: the physics' own readings.

        Each token is a :class:`RunWatch` of its own, made when first asked
        (the run's watch, from the reset, is the farm report's alone); the
        closest points are measured only when a clearance is asked.
        """
        simulation = self._core()
        watch = self._watches.get(token)
        if watch is None:
            simulation.entities.body(entity)  # NOT_FOUND, listing the entities
            # Closest points are looked for within the distance asked, however far.
            watch = self._watches[token] = RunWatch(
                simulation, entity, tip_angle_rad=tip_angle_rad, clearance=clearance_m > 0.0,
                clearance_range_m=clearance_m if clearance_m > 0.0 else DEFAULT_CLEARANCE_RANGE_M)
        first = watch.contacts[0] if watch.contacts else None
        near = watch.clearance
        within = near.distance_m < clearance_m and near.other is not None
        return Watched(first.other if first else None,
                       first.start_ns / 1e9 if first else None,
                       near.other if within else None,
                       near.time_ns / 1e9 if within and near.time_ns is not None else None,
                       near.distance_m if clearance_m > 0.0 else None,
                       None if watch.tipped_ns is None else watch.tipped_ns / 1e9)

    def unwatch(self, token: int) -> None:
        """Stop the watch ``token``: its check ended."""
        watch = self._watches.pop(token, None)
        if watch is not None:
            watch.close()
