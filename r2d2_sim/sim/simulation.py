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
deleted start-up entities under their names. Many short runs from one start
(a learning environment's episodes) come back to a state saved once
(:meth:`Simulation.save_state`, :meth:`Simulation.restore_state`): no body
is loaded again, and the run after it repeats bit for bit all the same.

The world around the robots is a file (:mod:`r2d2_sim.sim.worlds`): the
``world`` parameter's at start-up, another one loaded while running
(:meth:`Simulation.load_world`), which a full reset then builds again, or
none after :meth:`Simulation.unload_world`. Its named poses are frames a
spawn or a teleport may be given in.

Questions that change nothing go to the parts that own the data, which the
Simulation composes: :attr:`Simulation.entities` (the standard's entities:
names, states, info, bounds; :class:`~r2d2_sim.sim.entities.Entities`) and
:attr:`Simulation.worlds` (the world loaded, the worlds available, named
poses; :class:`~r2d2_sim.sim.worlds.files.WorldFiles`). Both also read a
spawn's or a world's files without changing anything, so that a caller can
do that slow part outside the simulator's lock. Every attribute is set in
``Simulation.__init__``.
"""

import dataclasses
import os
import weakref
from typing import (
    Callable, Generator, List, NamedTuple, Optional, Sequence, Set, Tuple, Union)

from r2d2_sim.errors import RefusedError, SetupError, WorldError
from r2d2_sim.model.timing import StepClock, StepSchedule
from r2d2_sim.model.transforms import Transform, yaw_of
from r2d2_sim.physics.body import Body
from r2d2_sim.physics.description import urdf_robot_name
from r2d2_sim.physics.world import SavedWorld, SimWorld, unique_name
from r2d2_sim.sim.entities import Category, Entities, EntityInfo, SpawnRequest
from r2d2_sim.sim.names import entity_name
from r2d2_sim.sim.robots.robot import Frame, Measurement, Robot
from r2d2_sim.sim.sdf.loading import SdfSettings
from r2d2_sim.sim.settings.readers import namespace as read_namespace
from r2d2_sim.sim.settings.robots import resolve_namespace, robot_config, RobotSpec
from r2d2_sim.sim.settings.table import ConfigError, NOISE_FAMILIES, PARAMETERS_BY_NAME
from r2d2_sim.sim.settings.config import read_value, SimConfig
from r2d2_sim.sim.spawnables import check_driven, Spawnable
from r2d2_sim.sim.startup import docked, finished, Rebuilt, robot_starts, Startup
from r2d2_sim.sim.worlds import empty_world, LoadOptions, Places, World, WorldFiles

# Frame and Measurement are the core's data, defined beside the robot that measures them.
__all__ = ['Simulation', 'StepResult', 'SavedState', 'Frame', 'Measurement', 'SpawnRequest',
           'EntityInfo', 'GUI_CAMERA_RATE_HZ', 'NOISE_PARAMETERS']

# Follow the robot with the GUI camera this many times per simulated second.
GUI_CAMERA_RATE_HZ = 30.0
# A spawn overlapping a robot deeper than resting contacts sink (about 0.01 mm) is a shove.
SHOVE_DEPTH_M = 0.001

# Told the robots after every change of the set (start-up, spawn, delete, reset).
RobotsWatcher = Callable[[Sequence[Robot]], None]
# The parameters restart_noise may set: every sensor's noise (the seed apart).
NOISE_PARAMETERS = frozenset(spec.name for family in NOISE_FAMILIES.values()
                             for spec in family.parameters())


class StepResult(NamedTuple):
    """What one physics step produced: whether the state was due, and each robot's measurement."""

    step: int
    time_ns: int
    state_due: bool                                  # a state publication (and /clock) is due
    measurements: Tuple[Optional[Measurement], ...]  # per robot, in Simulation.robots order


class SavedState(NamedTuple):
    """A state of the simulation to come back to (:meth:`Simulation.save_state`)."""

    world: SavedWorld              # the physics, kept by PyBullet
    robots: Tuple[Robot, ...]      # the robots then, which must be the robots still


class _WorldMoved(Exception):
    """The world changed while another was built beside it: build that one in place."""


def _ignore(text: str) -> None:
    pass


def _directories(name: str, sources: Sequence[str], places: Places,
                 home: bool = False) -> Tuple[str, ...]:
    """
    Return the directories a ``*_paths`` parameter lists; ConfigError for one that is none.

    Checked at start-up, as ``world`` is: a world path that named no
    directory failed every GetAvailableWorlds later, and a model path was
    never searched, with no word. ``home``: a leading ``~`` is the user's
    home (as the model search has always taken it).
    """
    found = []
    for source in sources:
        try:
            found.append(places.directory(os.path.expanduser(source) if home else source)[0])
        except RefusedError as exc:
            raise ConfigError(f'parameter {name}: {exc.message}') from None
    return tuple(found)


class Simulation:
    """
    The world, its robots and the step schedule.

    ``config`` holds the world's settings; ``robots`` the robots listed in
    the ``robots`` parameter, each with its own settings and namespace
    (resolved under ``namespace``, the simulator's own). Without them the
    world has one robot, named after its URDF, with ``config``'s settings, in
    ``namespace`` itself. More robots join through :meth:`spawn` and leave
    through :meth:`delete_entity`. ``entities`` and ``worlds`` answer what
    changes nothing. ``warn`` and ``error`` receive one-line reports (the
    node logs them, throttled); they default to silence. Raises a SetupError
    subclass (ConfigError, WorldError...) when the configuration cannot be
    simulated.
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
        # How often a robot that fell off the ground is looked for: once a simulated second.
        self._fall_check_steps = max(1, round(rate))
        self.last_frame_step = 0
        self.robots: List[Robot] = []
        self.models: List[Body] = []  # extra_models and the world model loaded at start-up
        self._warn, self._error = warn, error
        self._watchers: List[RobotsWatcher] = []
        # The ray groups each body was said to be hidden from (_warn_of_unseen), once each.
        self._unseen_told: 'weakref.WeakKeyDictionary[Body, Set[int]]' = (
            weakref.WeakKeyDictionary())
        # Told the simulated time after each step (oracles.RunWatch): none by default.
        self._step_watchers: List[Callable[[int], None]] = []
        # What SDF worlds and spawns are searched and compared with.
        places = Places(config.world_paths)
        _directories('world_paths', config.world_paths, places)
        model_paths = _directories('model_paths', config.model_paths, places, home=True)
        sdf = SdfSettings(model_paths, self.time_step_s, config.gravity_m_s2,
                          config.ground_plane, config.strict_worlds, tuple(places.roots()))
        # The world file loaded (the empty world for world ''), the ones that can be.
        self.worlds = WorldFiles(places, sdf, self.time_step_s)
        self.world = SimWorld(gui=config.gui, time_step_s=self.time_step_s,
                              gravity_m_s2=config.gravity_m_s2, ground_plane=config.ground_plane,
                              name_rule=entity_name)  # a URDF's robot name: one rule for all
        self.world.ray_threads = config.ray_threads or 1  # auto: one per core here (see table)
        self.entities = Entities(self.world, config.world_frame_id, sdf)
        # What a full reset builds again: every start-up entity, in load order.
        self._startup = Startup(self.world, warn, error)
        try:
            world_file = self.worlds.read_start(config.world)
            self.robots, self.models = self._startup.load(
                config, robot_starts(config, robots, namespace), world_file)
            self._world_loaded(world_file)
        except Exception:
            self.close()
            raise
        self._warn_of_unseen()
        # Nothing ran since the world was as launched (start-up, a full reset, a world
        # loaded): no step, and the node not played. At time 0 and paused: the standard's
        # STOPPED ("pausing and resetting with ALL"). A time reset alone does not set it:
        # the world it leaves is not the launched one.
        self.unrun_since_launch = True
        # How often the world was put back (any reset, a restored state, a world loaded or
        # unloaded): a long step run in chunks sees one between its chunks by this, even
        # where the step count stays (a STATE or SPAWNED reset).
        self.reset_count = 0

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
        self._warn_of_unseen()
        for watcher in self._watchers:
            watcher(tuple(self.robots))

    def _warn_of_unseen(self) -> None:
        """
        Say once, in one line, when a body's own collision filters hide it from a robot's rays.

        A robot's laser and 3D lidar pass through its ray group (a bit of 4 ... 2^30):
        a body whose URDF puts a link in that group alone (or leaves group 1, which
        rays are cast in, out of its mask) is not seen by them, though the robot
        collides with it. Checked whenever a body or a robot comes into the world.
        """
        for robot in self.robots:
            group = robot.ray_group
            if group is None:
                continue
            for body in self.world.bodies.values():
                if body is robot.body or not body.sets_own_collision_filters:
                    continue
                told = self._unseen_told.setdefault(body, set())
                if group in told:
                    continue
                told.add(group)
                missed = body.rays_miss(group)
                if missed:
                    self._warn(f'{body.name} is invisible to robot {robot.name}\'s laser and 3D '
                               'lidar, though the robot collides with it: its URDF '
                               f'{"; ".join(missed)}')

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
        self.unrun_since_launch = False
        for robot in robots:
            robot.drive_wheels(step)
        world.step(1)
        step += 1
        if world.gui and step % self.steps_per_gui_frame == 0 and robots:
            world.follow_camera(robots[0].body)
        state_due = self.publish_schedule.due(step)
        time_ns = self.clock.time_ns(step)
        measurements = [robot.measure(step, time_ns, state_due) for robot in robots]
        if world.blown_up:  # robots were put back (or given up): now what they broke too
            measurements = self._take_out_given_up(measurements)
            robots = self.robots
            self._repair()
        if step % self._fall_check_steps == 0:
            for robot in robots:
                robot.check_fall(time_ns)
        measured = any(measurements)
        casting = [(i, measurement, robots[i].pending_rays())
                   for i, measurement in enumerate(measurements)
                   if measurement is not None and robots[i].pending_rays()] if measured else ()
        if casting:
            # Every robot's rays of this step cast together (raycast.cast_requests: a
            # call per robot, its mask's); each robot then takes its answers.
            answers = iter(world.cast_requests([r for _, _, rays in casting for r in rays]))
            for i, measurement, rays in casting:
                measurements[i] = robots[i].take_rays(
                    measurement, [next(answers) for _ in rays])
        for watcher in self._step_watchers:
            watcher(time_ns)
        if state_due:
            self.last_frame_step = step
        elif not measured:
            return None
        return StepResult(step, time_ns, state_due, tuple(measurements))

    def read_states(self) -> StepResult:
        """Read every robot's state now, as a state publication at the current step would."""
        step = self.world.step_count
        time_ns = self.clock.time_ns(step)
        self.last_frame_step = step
        measurements: List[Optional[Measurement]] = [
            Measurement(time_ns, robot.read_frame(step, time_ns), None, None, None)
            for robot in self.robots]
        if self.world.blown_up:
            measurements = self._take_out_given_up(measurements)
            self._repair()
        return StepResult(step, time_ns, True, tuple(measurements))

    def _take_out_given_up(self, measurements: List[Optional[Measurement]]
                           ) -> List[Optional[Measurement]]:
        """
        Delete the robots that blew up too often in a row (Robot.given_up); return the others'.

        A robot put back after every blow-up blew up again at once, for ever:
        taken out of the world as DeleteEntity takes it (a full reset brings
        a start-up robot back), the other robots run on. ``measurements``
        are the robots', in order; what is returned is the kept robots'.
        """
        given_up = [robot for robot in self.robots if robot.given_up]
        if not given_up:
            return measurements
        kept = [m for robot, m in zip(self.robots, measurements) if not robot.given_up]
        for robot in given_up:
            self._delete(robot.name)
        self._robots_changed()
        return kept

    def _repair(self) -> None:
        """Put back what robots' blow-ups broke around them: the ground, what they touched."""
        for body, why in self.world.repair([robot.body for robot in self.robots]):
            if why is None:
                self._error(f'physics blew up: {body.name} was broken with it and is put back '
                            'where it started')
            else:
                self._error(f'physics blew up: {body.name} was broken with it and is reset in '
                            f'place where it started, not loaded again ({why})')

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
        self.reset_count += 1
        changed = False
        if spawned:
            self._forget_robots([r for r in self.robots if r.body.spawned])
            self.entities.delete_spawned()
            changed = True
        if state:
            rebuilt = self._startup.rebuild(self.robots, as_launched=time and spawned)
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
            self.entities.restore_info(self._startup.infos())
            self.unrun_since_launch = True  # as launched again: STOPPED once paused
        if changed:
            self._robots_changed()

    def save_state(self) -> SavedState:
        """
        Keep the world as it is now, to come back to it with :meth:`restore_state`.

        Far cheaper than a reset, which loads every body again: for many
        short runs from one start, such as a learning environment's episodes.
        """
        return SavedState(self.world.save_state(), tuple(self.robots))

    def restore_state(self, saved: SavedState) -> None:
        """
        Put the world back as it was saved: a run after it repeats bit for bit, whatever ran since.

        Every body's pose, twist and joints come back, and Bullet's pairs and
        contact points are dropped (a body only put back in place would leave
        those of the last run behind: see :meth:`SimWorld.restore_state
        <r2d2_sim.physics.world.SimWorld.restore_state>`); every robot is at
        rest as after a reset (commands and odometry dropped, its sensors'
        schedules starting again now); time goes on, as after a state reset.
        Only while the world holds the bodies and robots it held then:
        WorldError (one line) after a spawn, a delete, a reset or a world
        loaded since, and the world stays as it is.
        """
        if tuple(self.robots) != saved.robots:
            raise WorldError('the saved state is of other robots: robots were spawned, deleted '
                             'or loaded again since it was saved')
        self.world.restore_state(saved.world)
        self.reset_count += 1
        step = self.world.step_count
        self.publish_schedule.restart(step)
        for robot in self.robots:
            robot.restart_time(0)
            robot.reloaded()

    def forget_state(self, saved: SavedState) -> None:
        """Free what :meth:`save_state` kept (PyBullet holds it until then)."""
        self.world.forget_state(saved.world)

    def restart_noise(self, noise_seed: int, **noise: float) -> None:
        """
        Start every robot's noise streams again from ``noise_seed``, with ``noise`` if given.

        ``noise``: noise parameters by their names (``scan_noise_std``...,
        :data:`NOISE_PARAMETERS`), for every robot. Each robot keeps a stream
        of its own per sensor (the seed, its name, the sensor): a run with the
        same seed reads the same noise, as after start-up with ``noise_seed``.
        ConfigError (one line) for a value the parameter would refuse, or a
        name that is no noise parameter; nothing changes then.
        """
        unknown = sorted(set(noise) - NOISE_PARAMETERS)
        if unknown:
            raise ConfigError(f'{", ".join(unknown)}: not a noise parameter')
        values = {'noise_seed': noise_seed, **noise}
        fields = {PARAMETERS_BY_NAME[name].field: read_value(PARAMETERS_BY_NAME[name], value)
                  for name, value in values.items()}
        for robot in self.robots:
            robot.restart_noise(dataclasses.replace(robot.config, **fields))

    def _restart_time(self) -> None:
        """Put the step count and simulated time back to 0, every schedule from there."""
        steps_back = self.world.step_count
        self.world.step_count = 0
        self.publish_schedule.restart(0)
        self.last_frame_step = 0
        for robot in self.robots:
            robot.restart_time(steps_back)

    # -- the entities: placed, described, spawned, deleted ---------------------------------

    def set_entity_state(self, name: str, frame_id: str, position: Sequence[float],
                         orientation: Sequence[float], linear: Sequence[float],
                         angular: Sequence[float], acceleration: Sequence[float] = ()) -> None:
        """Place an entity (see :meth:`Entities.set_state <r2d2_sim.sim.entities.Entities>`)."""
        body = self.entities.set_state(name, frame_id, position, orientation, linear, angular,
                                       acceleration)
        for robot in self.robots:
            if robot.body is body:
                robot.teleported()  # its IMU must not take the jump for an acceleration

    def set_entity_info(self, name: str, category: int, description: str,
                        tags: Sequence[str]) -> None:
        """Set an entity's category (a label), description and tags (SetEntityInfo)."""
        self.entities.set_info(name, category, description, tags)

    def spawn(self, request: SpawnRequest, spawnable: Optional[Spawnable] = None) -> str:
        """
        Spawn an entity as the standard asks (:class:`SpawnRequest`); return its name.

        With a ``namespace`` it is a driven robot with the world's robot
        settings, its odometry starting at its pose: RefusedError
        NAMESPACE_INVALID for a malformed or taken namespace (or the
        simulator's own), NAME_NOT_UNIQUE when its frames would be another
        robot's (with ``allow_renaming``, the first ``_1``, ``_2``... name whose
        frames are free), RESOURCE_PARSE_ERROR for inertias PyBullet reads as 0
        (``check_driven``), OPERATION_FAILED when the world's settings cannot
        drive it or a watcher refuses it. Without one, a plain entity, free of
        Bullet's default damping as the start-up models are. Refusals leave
        the world as it was. ``spawnable``: the request's files read beforehand
        (``simulation.entities.read(request)``, which needs no lock).
        """
        if not request.namespace:
            body, _, notes = self.entities.spawn(request, spawnable=spawnable)
            body.drop_damping()  # a free body keeps its speed, as in Gazebo and Isaac Sim
            if notes:
                self._warn(f'{body.name}: {notes}')
            self._warn_of_overlaps(body)
            self._warn_of_unseen()
            return body.name
        try:
            namespace = self._free_namespace(request.namespace)
        except RefusedError:
            if spawnable is not None and spawnable.file is not None:
                spawnable.file.close()
            raise
        body, description, notes = self.entities.spawn(
            request, flags=self.world.robot_flags,
            body_yaw_offset_rad=self.config.body_yaw_offset_rad, spawnable=spawnable,
            usable=self._frames_free)  # renamed till its frames are free
        if notes:
            self._warn(f'{body.name}: {notes}')
        base = body.world_state()
        try:  # loaded with its inertias from the file: they must drive it (not yet stepped)
            check_driven(description, request.uri[:200] or 'the resource_string')
            config = docked(robot_config(self.config, body.name, {
                'initial_pose': [base.position[0], base.position[1], yaw_of(base.orientation)]}),
                self.worlds.current, self._named_warn(body.name))
            self._check_frames_free(config)
            robot = Robot(self.world, body, config, body.source, description,
                          warn=self._named_warn(body.name), error=self._error,
                          namespace=namespace)
        except RefusedError:
            self.entities.delete(body.name)
            raise
        except SetupError as exc:
            self.entities.delete(body.name)
            raise RefusedError('OPERATION_FAILED',
                               f'{body.name} cannot be driven: {exc}') from None
        self.entities.mark(body.name, EntityInfo(Category.ROBOT))
        self.robots.append(robot)
        try:
            self._robots_changed()
        except Exception as exc:
            self._delete(robot.name)
            self._robots_changed()
            if isinstance(exc, ConfigError):
                raise RefusedError('NAMESPACE_INVALID', str(exc)) from None
            raise
        self._warn_of_overlaps(body)
        return robot.name

    def _warn_of_overlaps(self, body: Body) -> None:
        """Say in one line which robots a spawned body overlaps: the next step shoves them."""
        met = []
        for robot in self.robots:
            if robot.body is not body:
                nearest = body.closest_points(robot.body, 0.0)
                if nearest is not None and nearest.distance_m < -SHOVE_DEPTH_M:
                    met.append(f'robot {robot.name} by {-nearest.distance_m * 1e3:.0f} mm')
        if met:
            self._warn(f'{body.name} overlaps {", ".join(met)}: the next step pushes them '
                       'apart (spawn clear of robots)')

    def _free_namespace(self, namespace: str) -> str:
        """Return a spawned robot's namespace, resolved; NAMESPACE_INVALID if it cannot be."""
        try:
            resolved = resolve_namespace(self.namespace,
                                         read_namespace('entity_namespace', namespace))
        except ConfigError as exc:
            raise RefusedError('NAMESPACE_INVALID', str(exc)) from None
        if resolved == self.namespace:
            raise RefusedError('NAMESPACE_INVALID', f'{resolved} is the simulator\'s own '
                                                    'namespace: give the robot one of its own')
        for robot in self.robots:
            if robot.namespace == resolved:
                raise RefusedError('NAMESPACE_INVALID', f'robot {robot.name} has the '
                                                        f'namespace {resolved} already')
        return resolved

    def _check_frames_free(self, config: SimConfig) -> None:
        """Refuse a robot whose frames would be another's on the shared /tf."""
        holder = self._frames_holder(config)
        if holder is not None:
            raise RefusedError('NAME_NOT_UNIQUE', f'robot {holder.name} publishes its frames '
                               f'with the prefix {config.frame_prefix!r} already: name the '
                               'new robot otherwise')

    def _frames_free(self, name: str) -> bool:
        """Return True unless a robot spawned as ``name`` would publish another's frames."""
        try:
            config = robot_config(self.config, name)
        except ConfigError:
            return True  # refused when the robot is made
        return self._frames_holder(config) is None

    def _frames_holder(self, config: SimConfig) -> Optional[Robot]:
        """Return the robot whose frames a robot of ``config`` would publish as its own."""
        if config.tf_layout != 'shared':
            return None
        return next((robot for robot in self.robots
                     if robot.config.frame_prefix == config.frame_prefix), None)

    def delete_entity(self, name: str) -> None:
        """
        Delete any entity, and the robot it is if it is one (its watchers are told).

        Start-up entities too (the ground plane, a model, a start-up robot):
        a full reset brings them back as they were loaded.
        """
        self._delete(name)
        self._robots_changed()

    def _delete(self, name: str) -> None:
        body = self.entities.body(name)  # NOT_FOUND before anything changes
        self.entities.delete(name)
        self._forget_robots([r for r in self.robots if r.body is body])
        if body in self.models:
            self.models.remove(body)

    # -- the world file: loaded, unloaded --------------------------------------------------

    def load_world(self, world: Union[str, World], resource_string: str = '',
                   options: LoadOptions = LoadOptions()) -> World:
        """
        Load a world in place of the current one, as LoadWorld asks; return it.

        ``world`` is a URI (read here with ``resource_string`` and
        ``options``: :meth:`WorldFiles.read <r2d2_sim.sim.worlds.files.WorldFiles.read>`)
        or a world read beforehand with ``simulation.worlds.read``, which
        touches no physics and needs no lock. Everything is read and checked
        first, so a refusal leaves the world exactly as it was. Then the world
        is built as launched with the new world: spawned entities gone, the
        start-up robots (deleted ones too) at its start pose, the ground and
        ``extra_models`` as at start-up, time at 0 and nothing changed since
        (STOPPED, once the caller pauses). RefusedError with LoadWorld's codes;
        OPERATION_FAILED for a model named like a robot or a start-up model.
        """
        return finished(self.loading_world(world, resource_string, options))

    def loading_world(self, world: Union[str, World], resource_string: str = '',
                      options: LoadOptions = LoadOptions()) -> Generator[None, None, World]:
        """
        Load a world as :meth:`load_world` does, one body at a time: a generator.

        The new world is built beside the old one (a PyBullet client of its
        own) and swapped in by the last ``next``, which returns the world
        (``StopIteration.value``). Between two ``next`` the old world may
        step on: a caller that holds the simulation's lock for each ``next``
        keeps the physics at its rate while a large world is built. If the
        world changed under the build (a reset, a start-up robot deleted),
        the last ``next`` builds it again in place. The same world, bit for
        bit, as :meth:`load_world` and as a launch with it.
        """
        world_file = self.worlds.read(world, resource_string, options) \
            if isinstance(world, str) else world
        try:
            self._check_names(world_file)
            off = self._startup.off_ground(world_file)
            if off is not None:
                raise RefusedError('OPERATION_FAILED', f'the world\'s start pose: {off}')
        except BaseException:
            world_file.close()
            raise
        try:
            yield from self._switching(world_file)
        except BaseException:  # refused, or the caller stopped (GeneratorExit)
            world_file.close()
            raise
        return world_file

    def unload_world(self) -> None:
        """
        Unload the world: its models and named poses leave, and every spawned entity.

        The ground, the robots and ``extra_models`` stay, built again as
        launched with no world, at time 0; ``worlds.is_loaded`` is False
        until a world is loaded (the standard's NO_WORLD). RefusedError
        NO_WORLD_LOADED when none is.
        """
        if not self.worlds.is_loaded:
            raise RefusedError('NO_WORLD_LOADED', 'no world is loaded')
        finished(self._switching(empty_world(), beside=False))
        self._world_loaded(None)

    def _world_loaded(self, world_file: Optional[World]) -> None:
        """Take ``world_file`` as the world now: its named poses, each entity's start-up info."""
        if world_file is not None and world_file is not self.worlds.current and world_file.notes:
            self._warn(f'world {world_file.name}: {"; ".join(world_file.notes)}')
        self.worlds.take(world_file)
        poses = world_file.named_poses if world_file is not None else ()
        self.entities.named_frames = {p.name: Transform(p.position, p.orientation)
                                      for p in poses}
        self.entities.restore_info(self._startup.infos())

    def _check_names(self, world_file: World) -> None:
        """
        Refuse a world whose models would take a start-up entity's name, or one another's.

        A model with no name is named as the build will name it: after its
        URDF's robot name, made unique among the bodies loaded before it (the
        ground, the first robot, ``extra_models``, the world's models before
        it). The robots after them must keep their names too.
        """
        before, after = self._startup.names_around_world()
        taken, loaded = set(before + after), set(before)
        for model in world_file.models:
            name = model.name
            if name is None:
                name = unique_name(loaded, self.world.default_name(
                    urdf_robot_name(model.path), model.path))
            if name in taken:
                named = (f'{model.name!r}' if model.name is not None else
                         f'{model.source[:200]} (named {name!r} after its URDF\'s robot name)')
                raise RefusedError('OPERATION_FAILED', f'the world\'s model {named} would take '
                                   'the name of one of the simulator\'s own entities (a robot, '
                                   'the ground plane, extra_models)')
            if name in loaded:
                raise RefusedError('OPERATION_FAILED', f'two of the world\'s models would be '
                                   f'named {name!r}')
            loaded.add(name)

    def _switching(self, world_file: World, beside: bool = True) -> Generator[None, None, None]:
        """Build the world as launched with ``world_file``: spawned ones gone, time at 0."""
        robots = self._start_up_robots()
        builds = self.world.builds
        left = []

        def leaving() -> None:
            if self.world.builds != builds or self._start_up_robots() != robots:
                raise _WorldMoved()
            drop_spawned()

        def drop_spawned() -> None:
            left.append(True)
            self._forget_robots([r for r in self.robots if r.body.spawned])
            for name, body in list(self.world.bodies.items()):
                if body.spawned:
                    self.entities.dropped(name)
            for name in [n for n in self.world.bodies if n not in self._startup.names()]:
                self.entities.dropped(name)  # the old world's models: their info goes with them
        try:
            try:
                rebuilt = yield from self._startup.switching(world_file, robots, beside, leaving)
            except _WorldMoved:
                robots, builds = self._start_up_robots(), self.world.builds
                rebuilt = finished(self._startup.switching(world_file, robots, False, leaving))
        except WorldError as exc:
            # Only a file changed between the check and the load gets here.
            self._error(f'the world {world_file.name} could not be built ({exc}): building the '
                        'previous one again, as launched')
            world_file.close()
            if not left:
                drop_spawned()
            for robot in self.robots:  # built again below: their ray groups free first
                robot.close()
            self._take(self._startup.rebuild([], as_launched=True))
            self.entities.restore_info(self._startup.infos())
            raise RefusedError('OPERATION_FAILED', f'the world could not be built: {exc}; the '
                                                   'previous world was built again as '
                                                   'launched') from None
        self._take(rebuilt)
        self._world_loaded(world_file)

    def _start_up_robots(self) -> List[Robot]:
        return [robot for robot in self.robots if not robot.body.spawned]

    def _take(self, rebuilt: Rebuilt) -> None:
        """Take a rebuilt world's robots and models, time at 0, and tell the robots' watchers."""
        for robot in self.robots:
            if robot not in rebuilt.robots:
                robot.close()  # a second close of a robot the start-up closed does nothing
        self.robots = rebuilt.robots
        self.models = rebuilt.models if rebuilt.models is not None else self.models
        self.reset_count += 1
        self._restart_time()
        self.unrun_since_launch = True  # a world loaded (or unloaded): as launched with it
        self._robots_changed()

    def close(self) -> None:
        """Disconnect the physics client; safe to call twice."""
        for robot in self.robots:
            robot.close()
        self.entities.close()
        self.worlds.close()
        self.world.close()
