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
"""

from typing import Callable, List, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.errors import RefusedError, SetupError, WorldError
from r2d2_sim.model.timing import StepClock, StepSchedule
from r2d2_sim.model.transforms import BaseState, Transform, yaw_of
from r2d2_sim.physics.body import Body
from r2d2_sim.physics.world import SimWorld
from r2d2_sim.sim.entities import Category, Entities, EntityInfo, SpawnRequest
from r2d2_sim.sim.entity_bounds import Region
from r2d2_sim.sim.launch import docked, Launch, robot_starts
from r2d2_sim.sim.sdf.loading import SdfSettings
from r2d2_sim.sim.tags import TagsFilter, tags_match
from r2d2_sim.sim.world_manifest import NamedPose
from r2d2_sim.sim.worlds import (
    empty_world, list_worlds, LoadOptions, Places, read_world, World, WorldEntry)
from r2d2_sim.sim.parameter_readers import namespace as read_namespace
from r2d2_sim.sim.parameters import ConfigError, SimConfig
from r2d2_sim.sim.robot import Frame, Measurement, Robot
from r2d2_sim.sim.robot_parameters import resolve_namespace, robot_config, RobotSpec

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


class Simulation:
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
                               config.strict_worlds)
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

    def _start_world(self, uri: str) -> World:
        """Read the ``world`` parameter's world (the operator's: any file); WorldError if bad."""
        if not uri:
            return empty_world()
        try:
            return read_world(uri, '', self.places, self._options(LoadOptions()), trusted=True,
                              sdf=self.sdf)
        except RefusedError as exc:
            raise WorldError(f'world {uri}: {exc.message}') from None

    def _options(self, options: LoadOptions) -> LoadOptions:
        """Return a load's options with ``strict_worlds``: refuse what is not simulated."""
        strict = options.fail_on_unsupported_element or self.config.strict_worlds
        return options._replace(fail_on_unsupported_element=strict)

    def _world_loaded(self, world_file: Optional[World]) -> None:
        """Take ``world_file`` as the world now: its named poses, each entity's start-up info."""
        if self.world_file is not None and self.world_file is not world_file:
            self.world_file.close()
        if world_file is not None and world_file is not self.world_file and world_file.notes:
            self._warn(f'world {world_file.name}: {"; ".join(world_file.notes)}')
        self.world_file = world_file
        poses = world_file.named_poses if world_file is not None else ()
        self.entities.named_frames = {p.name: Transform(p.position, p.orientation)
                                      for p in poses}
        self.entities.restore_info(self._launch.infos())

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

    # -- the entities, as the standard sees them -----------------------------------------

    @property
    def world_frame_id(self) -> str:
        """Return the frame entity poses are given in."""
        return self.entities.world_frame_id

    def entity_names(self) -> List[str]:
        """Return every entity's name, in the order the world loaded them."""
        return self.entities.names()

    def entity_category(self, name: str) -> int:
        """Return an entity's category: as set, else ROBOT, STATIC_ or DYNAMIC_OBJECT."""
        info = self.entities.info(name)
        if info.category is not None:
            return info.category
        body = self.entities.body(name)
        if any(robot.body is body for robot in self.robots):
            return Category.ROBOT
        return Category.STATIC_OBJECT if body.static else Category.DYNAMIC_OBJECT

    def entity_source(self, name: str) -> str:
        """Return where an entity's description came from (a path, a URI, 'resource_string')."""
        return self.entities.body(name).source

    def entity_info(self, name: str) -> EntityInfo:
        """Return GetEntityInfo's answer: category, description (as set, else the source), tags."""
        info = self.entities.info(name)
        description = info.description if info.description is not None else \
            self.entity_source(name)
        return EntityInfo(self.entity_category(name), description, info.tags)

    def set_entity_info(self, name: str, category: int, description: str,
                        tags: Sequence[str]) -> None:
        """Set an entity's category (a label), description and tags (SetEntityInfo)."""
        self.entities.set_info(name, category, description, tags)

    def entity_tags(self, name: str) -> Tuple[str, ...]:
        """Return an entity's tags."""
        return self.entities.info(name).tags

    def entity_bounds(self, name: str) -> Region:
        """Return the box around an entity's collision shape, in its base link's frame."""
        return self.entities.bounds(name)

    def entity_state(self, name: str) -> BaseState:
        """Return the pose of an entity's URDF base link and its origin's twist, in the world."""
        return self.entities.state(name)

    def set_entity_state(self, name: str, frame_id: str, position: Sequence[float],
                         orientation: Sequence[float], linear: Sequence[float],
                         angular: Sequence[float]) -> None:
        """Place an entity (see :meth:`Entities.set_state <r2d2_sim.sim.entities.Entities>`)."""
        body = self.entities.set_state(name, frame_id, position, orientation, linear, angular)
        self.pristine = False
        for robot in self.robots:
            if robot.body is body:
                robot.teleported()  # its IMU must not take the jump for an acceleration

    def entities_overlapping(self, region: Region) -> List[str]:
        """Return the entities whose collision shape meets a region (box, hull, sphere)."""
        return self.entities.overlapping(region)

    # -- worlds and their named poses ---------------------------------------------------

    @property
    def world_is_loaded(self) -> bool:
        """Return False after unload_world, until a world is loaded: the standard's NO_WORLD."""
        return self.world_file is not None

    def available_worlds(self, additional_sources: Sequence[str] = (),
                         tags: TagsFilter = TagsFilter(), offline_only: bool = False,
                         continue_on_error: bool = False) -> Tuple[List[WorldEntry], str]:
        """Return the worlds that can be loaded and a note (see :func:`worlds.list_worlds`)."""
        return list_worlds(self.places, additional_sources, tags, offline_only,
                           continue_on_error)

    def load_world(self, uri: str, resource_string: str = '',
                   options: LoadOptions = LoadOptions()) -> World:
        """
        Load a world in place of the current one, as LoadWorld asks; return it.

        Everything is read and checked first (the files, every model loaded
        once in a physics world of its own, the models' names against the
        robots'), so a refusal leaves the world exactly as it was. Then the
        world is built as launched with the new world: spawned entities gone,
        the start-up robots (deleted ones too) at its start pose, the ground
        and ``extra_models`` as at start-up, time at 0 and nothing changed
        since (STOPPED, once the caller pauses). RefusedError with LoadWorld's
        codes (see :func:`~r2d2_sim.sim.worlds.read_world`); OPERATION_FAILED
        for a model named like a robot or a start-up model.
        """
        world_file = read_world(uri, resource_string, self.places, self._options(options),
                                sdf=self.sdf)
        try:
            self._check_world(world_file)
        except BaseException:
            world_file.close()
            raise
        self._switch(world_file)
        return world_file

    def unload_world(self) -> None:
        """
        Unload the world: its models and named poses leave, and every spawned entity.

        The ground, the robots and ``extra_models`` stay, built again as
        launched with no world, at time 0; :attr:`world_is_loaded` is False
        until a world is loaded (the standard's NO_WORLD). RefusedError
        NO_WORLD_LOADED when none is.
        """
        if self.world_file is None:
            raise RefusedError('NO_WORLD_LOADED', 'no world is loaded')
        self._switch(empty_world())
        self._world_loaded(None)

    def named_poses(self, tags: TagsFilter = TagsFilter()) -> List[NamedPose]:
        """Return the world's named poses whose tags pass the filter, in the world file's order."""
        poses = self.world_file.named_poses if self.world_file is not None else ()
        return [pose for pose in poses if tags_match(pose.tags, tags)]

    def named_pose(self, name: str) -> NamedPose:
        """Return the named pose ``name``; RefusedError NOT_FOUND if the world has none such."""
        if self.world_file is None:
            raise RefusedError('NOT_FOUND', f'no named pose {name[:100]!r}: no world is loaded')
        return self.world_file.named_pose(name)

    def _check_world(self, world_file: World) -> None:
        """Refuse a world whose models would take a start-up entity's name, or cannot load."""
        taken = set(self._launch.names())
        for model in world_file.models:
            if model.name is not None and model.name in taken:
                raise RefusedError('OPERATION_FAILED', f'the world\'s model {model.name!r} '
                                   'would take the name of one of the simulator\'s own '
                                   'entities (a robot, the ground plane, extra_models)')
        # Models made from SDF were written here from checked parts: not loaded twice.
        paths = sorted({model.path for model in world_file.models if not model.sdf})
        if not paths:
            return
        try:
            with SimWorld(ground_plane=False, time_step_s=self.time_step_s) as scratch:
                for path in paths:
                    scratch.load(path)
        except WorldError as exc:
            raise RefusedError('RESOURCE_PARSE_ERROR', str(exc)) from None

    def _switch(self, world_file: World) -> None:
        """Build the world as launched with ``world_file``: spawned ones gone, time at 0."""
        self._forget_robots([r for r in self.robots if r.body.spawned])
        for name, body in list(self.world.bodies.items()):
            if body.spawned:
                self.entities.dropped(name)
        for name in [n for n in self.world.bodies if n not in self._launch.names()]:
            self.entities.dropped(name)  # the old world's models: their info goes with them
        try:
            rebuilt = self._launch.switch(world_file, self.robots)
        except WorldError as exc:
            # Only a file changed between the check and the load gets here.
            self._error(f'the world {world_file.name} could not be built ({exc}): building the '
                        'previous one again, as launched')
            world_file.close()
            self._take(self._launch.rebuild([], as_launched=True))
            self.entities.restore_info(self._launch.infos())
            raise RefusedError('OPERATION_FAILED', f'the world could not be built: {exc}; the '
                                                   'previous world was built again as '
                                                   'launched') from None
        self._take(rebuilt)
        self._world_loaded(world_file)

    def _take(self, rebuilt) -> None:
        """Take a rebuilt world's robots and models, time at 0, and tell the robots' watchers."""
        for robot in self.robots:
            if robot not in rebuilt.robots:
                robot.close()  # a second close of a robot the launch closed does nothing
        self.robots = rebuilt.robots
        self.models = rebuilt.models
        self._restart_time()
        self.pristine = True
        self._robots_changed()

    def spawn(self, request: SpawnRequest) -> str:
        """
        Spawn an entity as the standard asks (:class:`SpawnRequest`); return its name.

        With a ``namespace`` it is a driven robot with the world's robot
        settings, its odometry starting at its pose: RefusedError
        NAMESPACE_INVALID for a malformed or taken namespace (or the
        simulator's own), NAME_NOT_UNIQUE when its frames would be another
        robot's, OPERATION_FAILED when the world's settings cannot drive it or
        a watcher refuses it. Without one, a plain entity, free of Bullet's
        default damping as the start-up models are. Refusals leave the world
        as it was.
        """
        if not request.namespace:
            body, _, notes = self.entities.spawn(request)
            body.drop_damping()  # a free body keeps its speed, as in Gazebo and Isaac Sim
            self.pristine = False
            if notes:
                self._warn(f'{body.name}: {notes}')
            return body.name
        namespace = self._free_namespace(request.namespace)
        body, description, notes = self.entities.spawn(
            request, flags=self.world.robot_flags,
            body_yaw_offset_rad=self.config.body_yaw_offset_rad)
        if notes:
            self._warn(f'{body.name}: {notes}')
        base = body.world_state()
        try:
            config = docked(robot_config(self.config, body.name, {
                'initial_pose': [base.position[0], base.position[1], yaw_of(base.orientation)]}),
                self.world_file, self._named_warn(body.name))
            self._check_frames_free(body.name, config)
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
        self.robots.append(robot)
        self.pristine = False
        try:
            self._robots_changed()
        except Exception as exc:
            self._delete(robot.name)
            self._robots_changed()
            if isinstance(exc, ConfigError):
                raise RefusedError('NAMESPACE_INVALID', str(exc)) from None
            raise
        return robot.name

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

    def _check_frames_free(self, name: str, config: SimConfig) -> None:
        """Refuse a robot whose frames would be another's on the shared /tf."""
        if config.tf_layout != 'shared':
            return
        for robot in self.robots:
            if robot.config.frame_prefix == config.frame_prefix:
                raise RefusedError('NAME_NOT_UNIQUE', f'robot {robot.name} publishes its frames '
                                   f'with the prefix {config.frame_prefix!r} already: name the '
                                   'new robot otherwise')

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
        self.pristine = False

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
