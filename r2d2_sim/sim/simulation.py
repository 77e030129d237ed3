"""
The simulation core: one physics step for the whole world, read top to bottom, with no ROS.

:meth:`Simulation.step` is the one place where a command becomes wheel torque
and comes back as odometry: each robot's drive controller turns its latest
command into wheel targets (limits, ramp, timeout), PyBullet steps, and each
robot measures what is due at that step: its state when a publication is due
(joints, base, wheel odometry, read once for every output), its camera, laser,
3D lidar, IMU and battery at their own rates; the rays of every robot's laser
and lidar are cast together. It returns the measurements as plain data;
outputs only translate them into messages. Every step also checks that no
robot's physics has blown up, and puts back one that has.

The world changes through this class alone (spawn, delete, place, reset):
it decides whether a spawned entity is a driven robot, and whoever follows
the robots (the ROS node's fleet) is told of every change and may refuse one,
which is then undone. Any entity can be deleted, start-up ones included; a
reset of the state builds the physics world again (so a run after it repeats
bit for bit), and a full reset builds it as it was at start-up, bringing back
deleted start-up entities under their names.

The world around the robots is a file (:mod:`r2d2_sim.sim.worlds`): the
``world`` parameter's at start-up, another one loaded while running
(:meth:`Simulation.load_world`), which a full reset then builds again, or
none after :meth:`Simulation.unload_world`. Its named poses are frames a
spawn or a teleport may be given in.

This module holds the step, the reset and the robots' watchers; the two
other concepts of the class are mixed in from modules of their own: the
entities, asked about, spawned and deleted
(:mod:`~r2d2_sim.sim.simulation_entities`), and the world file, loaded and
unloaded (:mod:`~r2d2_sim.sim.simulation_worlds`). Every attribute is set in
``Simulation.__init__``.
"""

from typing import Callable, List, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.model.timing import StepClock, StepSchedule
from r2d2_sim.physics.body import Body
from r2d2_sim.physics.world import SimWorld
from r2d2_sim.sim.entities import Entities, EntityInfo, SpawnRequest
from r2d2_sim.sim.launch import Launch, robot_starts
from r2d2_sim.sim.sdf.loading import SdfSettings
from r2d2_sim.sim.parameters import SimConfig
from r2d2_sim.sim.robot import Frame, Measurement, Robot
from r2d2_sim.sim.robot_parameters import RobotSpec
from r2d2_sim.sim.simulation_entities import SimulationEntities
from r2d2_sim.sim.simulation_worlds import SimulationWorlds
from r2d2_sim.sim.world_places import Places
from r2d2_sim.sim.worlds import World

# Frame and Measurement are the core's data, defined beside the robot that measures them.
__all__ = ['Simulation', 'StepResult', 'Frame', 'Measurement', 'SpawnRequest', 'EntityInfo',
           'GUI_CAMERA_RATE_HZ']

# Follow the robot with the GUI camera this many times per simulated second.
GUI_CAMERA_RATE_HZ = 30.0

# Told the robots after every change of the set (start-up, spawn, delete, reset).
RobotsWatcher = Callable[[Sequence[Robot]], None]


class StepResult(NamedTuple):
    """What one physics step produced: whether the state was due, and each robot's measurement."""

    step: int
    time_ns: int
    state_due: bool                                  # a state publication (and /clock) is due
    measurements: Tuple[Optional[Measurement], ...]  # per robot, in Simulation.robots order


def _ignore(text: str) -> None:
    pass


class Simulation(SimulationEntities, SimulationWorlds):
    """
    The world, its robots and the step schedule.

    ``config`` holds the world's settings; ``robots`` the robots listed in
    the ``robots`` parameter, each with its own settings and namespace
    (resolved under ``namespace``, the simulator's own). Without them the
    world has one robot, named after its URDF, with ``config``'s settings, in
    ``namespace`` itself. More robots join through :meth:`spawn` and leave
    through :meth:`delete_entity`. ``warn`` and ``error`` receive one-line
    reports (the node logs them, throttled); they default to silence. Raises a
    SetupError subclass (ConfigError, WorldError...) when the configuration
    cannot be simulated.
    """

    def __init__(self, config: SimConfig, robots: Sequence[RobotSpec] = (),
                 warn: Callable[[str], None] = _ignore,
                 error: Callable[[str], None] = _ignore, namespace: str = '/') -> None:
        self.config = config
        self.namespace = namespace
        rate = config.physics_rate_hz
        self.time_step_s = 1.0 / rate
        self.clock = StepClock(rate)
        self.publish_schedule = StepSchedule(rate, config.publish_rate_hz)
        self.steps_per_gui_frame = max(1, round(rate / GUI_CAMERA_RATE_HZ))
        self.last_frame_step = 0
        self.robots: List[Robot] = []
        self.models: List[Body] = []  # extra_models and the world model loaded at start-up
        self._warn, self._error = warn, error
        self._watchers: List[RobotsWatcher] = []
        # Told the simulated time after each step (oracles.RunWatch): none by default.
        self._step_watchers: List[Callable[[int], None]] = []
        self.places = Places(config.world_paths)
        # What SDF worlds and spawns are searched and compared with.
        self.sdf = SdfSettings(tuple(config.model_paths), self.time_step_s,
                               tuple(config.gravity_m_s2), config.ground_plane,
                               config.strict_worlds, tuple(self.places.roots()))
        # The world file loaded (the empty world for world ''); None after unload_world.
        self.world_file: Optional[World] = None
        self.world = SimWorld(gui=config.gui, time_step_s=self.time_step_s,
                              gravity_m_s2=config.gravity_m_s2, ground_plane=config.ground_plane)
        self.entities = Entities(self.world, config.world_frame_id, self.sdf)
        # What a full reset builds again: every start-up entity, in load order.
        self._launch = Launch(self.world, warn, error)
        try:
            world_file = self._start_world(config.world)
            self.robots, self.models = self._launch.load(
                config, robot_starts(config, robots, namespace), world_file)
            self._world_loaded(world_file)
        except Exception:
            self.close()
            raise
        # Nothing changed since start-up (or a full reset): with time at 0, 'stopped'.
        self.pristine = True

    def _named_warn(self, name: str) -> Callable[[str], None]:
        return lambda text: self._warn(f'robot {name}: {text}')

    # -- who follows the robots --------------------------------------------------------

    def watch_robots(self, watcher: RobotsWatcher) -> None:
        """
        Call ``watcher(robots)`` now and after every change of the robots (in their order).

        A watcher that raises while a robot is spawned refuses it: the robot
        is deleted again, and the spawn fails.
        """
        self._watchers.append(watcher)
        watcher(tuple(self.robots))

    def watch_steps(self, watcher: Callable[[int], None]) -> Callable[[], None]:
        """Call ``watcher(time_ns)`` after every step from now on; return what stops it."""
        self._step_watchers.append(watcher)

        def unwatch() -> None:
            if watcher in self._step_watchers:
                self._step_watchers.remove(watcher)
        return unwatch

    def _robots_changed(self) -> None:
        for watcher in self._watchers:
            watcher(tuple(self.robots))

    def _forget_robots(self, robots: Sequence[Robot]) -> None:
        for robot in robots:
            self.robots.remove(robot)
            robot.close()

    # -- stepping -------------------------------------------------------------------------

    @property
    def robot(self) -> Robot:
        """Return the first robot: the one a single-robot simulation has."""
        return self.robots[0]

    @property
    def step_count(self) -> int:
        """Return the number of physics steps taken since start."""
        return self.world.step_count

    @property
    def time_ns(self) -> int:
        """Return the simulated time now, in integer nanoseconds."""
        return self.clock.time_ns(self.world.step_count)

    @property
    def blow_ups(self) -> int:
        """Return how often a robot's physics blew up and it was reset."""
        return sum(robot.blow_ups for robot in self.robots)

    def steps_to_next_publish(self) -> int:
        """Return the number of physics steps until the next state publication."""
        return self.publish_schedule.next_step - self.world.step_count

    def step(self) -> Optional[StepResult]:
        """
        Run one physics step; return what was measured (None when nothing is due).

        Commands -> wheel targets -> physics -> each robot's state when a
        publication is due (or the cheap blow-up check), and its sensors at
        their own rates.
        """
        world, robots = self.world, self.robots
        step = world.step_count
        for robot in robots:
            robot.drive_wheels(step)
        world.step(1)
        self.pristine = False
        step += 1
        if world.gui and step % self.steps_per_gui_frame == 0 and robots:
            world.follow_camera(robots[0].body)
        state_due = self.publish_schedule.due(step)
        time_ns = self.clock.time_ns(step)
        measurements = [robot.measure(step, time_ns, state_due) for robot in robots]
        casting = [(i, robot.pending_rays()) for i, robot in enumerate(robots)
                   if measurements[i] is not None and robot.pending_rays()]
        if casting:
            # Every robot's rays of this step cast together (raycast.cast_requests: a
            # call per robot, its mask's); each robot then takes its answers.
            answers = iter(world.cast_requests([r for _, rays in casting for r in rays]))
            for i, rays in casting:
                measurements[i] = robots[i].take_rays(
                    measurements[i], [next(answers) for _ in rays])
        measurements = tuple(measurements)
        for watcher in self._step_watchers:
            watcher(time_ns)
        if state_due:
            self.last_frame_step = step
        elif not any(measurements):
            return None
        return StepResult(step, time_ns, state_due, measurements)

    def read_states(self) -> StepResult:
        """Read every robot's state now, as a state publication at the current step would."""
        step = self.world.step_count
        time_ns = self.clock.time_ns(step)
        self.last_frame_step = step
        return StepResult(step, time_ns, True, tuple(
            Measurement(time_ns, robot.read_frame(step, time_ns), None, None, None)
            for robot in self.robots))

    def reset(self, *, time: bool = False, state: bool = True, spawned: bool = False) -> None:
        """
        Reset what is asked: ``~/reset`` is ``state`` alone, the standard's scopes these three.

        ``spawned``: delete every entity spawned while running. ``state``: the
        physics world built again, every body in it at its initial state
        (spawned ones at their spawn pose) and every robot at rest, commands
        and odometry dropped: the same commands then give the same run, bit
        for bit, as after start-up. ``time``: the step count and simulated
        time back to 0, every schedule from there. All three (the standard's
        ALL, and STOPPED): the world as at start-up, "as if closed and
        launched again": start-up entities deleted since come back, under
        their names, in their places. No other scope brings them back.
        """
        changed = False
        if spawned:
            self._forget_robots([r for r in self.robots if r.body.spawned])
            self.entities.delete_spawned()
            changed = True
        if state:
            rebuilt = self._launch.rebuild(self.robots, as_launched=time and spawned)
            for name in rebuilt.dropped:
                self.entities.dropped(name)
            self.robots = rebuilt.robots
            if rebuilt.models is not None:
                self.models = rebuilt.models
            self.models = [model for model in self.models if model.alive]
            changed = rebuilt.changed or changed
        if time:
            self._restart_time()
        if time and state and spawned:
            self.entities.restore_info(self._launch.infos())
        if changed:
            self._robots_changed()
        self.pristine = time and state and spawned

    def _restart_time(self) -> None:
        """Put the step count and simulated time back to 0, every schedule from there."""
        steps_back = self.world.step_count
        self.world.step_count = 0
        self.publish_schedule.restart(0)
        self.last_frame_step = 0
        for robot in self.robots:
            robot.restart_time(steps_back)

    def close(self) -> None:
        """Disconnect the physics client; safe to call twice."""
        for robot in self.robots:
            robot.close()
        self.entities.close()
        if self.world_file is not None:
            self.world_file.close()
        self.world.close()
