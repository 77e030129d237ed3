"""
The world as launched: what start-up loads, in its order, and building the world again.

No ROS here. :class:`Startup` loads the start-up world into a
:class:`~r2d2_sim.physics.world.SimWorld` (the ground plane, the first robot,
the ``extra_models`` and the models of the loaded world, then the other
robots: the order PyBullet has always had them in, which body ids and the
solver's order follow), remembers each of those entities, and builds the
physics world again on a reset: every body loaded anew in its order
(Bullet's contact data and the order of its overlapping pairs survive a body
put back in place, and change the next steps), or, for a full reset ("as if
it was closed and launched again"), the start-up entities themselves, a
robot deleted since loaded again from its start-up arguments.

Loading another world (:meth:`Startup.switching`) makes its launch the one a
full reset builds: the same ground, robots and ``extra_models``, with that
world's models, the robots standing at its start pose. It is built beside
the old world, in a PyBullet client of its own, body by body, while the old
one may go on stepping between, and swapped in at once.
"""

import dataclasses
import math
from typing import (
    Callable, Dict, Generator, List, NamedTuple, Optional, Sequence, Tuple, TypeVar)

from r2d2_sim.errors import SetupError, WorldError
from r2d2_sim.model.transforms import yaw_of
from r2d2_sim.physics.body import Body
from r2d2_sim.physics.description import (
    DescriptionError, read_urdf, resolve_description_path, RobotDescription)
from r2d2_sim.physics.world import GROUND_PLANE_NAME, SimWorld, WorldBuild
from r2d2_sim.sim.entities import Category, EntityInfo
from r2d2_sim.sim.settings.table import ConfigError
from r2d2_sim.sim.settings.config import SimConfig
from r2d2_sim.sim.robots.robot import Robot
from r2d2_sim.sim.settings.robots import resolve_namespace, RobotSpec
from r2d2_sim.sim.worlds import World, WorldModel

__all__ = ['Startup', 'RobotStart', 'Rebuilt', 'robot_starts', 'placed', 'docked', 'finished']


class RobotStart(NamedTuple):
    """How a start-up robot is loaded: its name (None: the URDF's), settings and namespace."""

    name: Optional[str]
    config: SimConfig
    namespace: str   # resolved
    listed: bool     # one of those ``robots`` lists: its messages name it


class Rebuilt(NamedTuple):
    """The world after :meth:`Startup.rebuild`: what the simulation keeps of it."""

    robots: List[Robot]            # in load order
    models: Optional[List[Body]]   # the start-up models (as launched), else None: the same
    changed: bool                  # the robots are not the same ones
    dropped: List[str]             # bodies that could not be loaded again, by name


class _Entity:
    """One entity of the start-up world, in load order: its body, a robot's start, its info."""

    def __init__(self, body: Body, robot: Optional[RobotStart] = None, model: bool = False,
                 world_model: bool = False, info: EntityInfo = EntityInfo(),
                 start: Optional[RobotStart] = None) -> None:
        self.body = body    # the latest loaded for it (a robot loaded again has a new one)
        self.robot = robot  # placed in the world (its initial pose at the world's start)
        self.start = start  # a robot's start as the parameters give it (placed in each world)
        self.model = model  # one of extra_models, or a model of the world
        self.world_model = world_model  # the world's, which another world replaces
        self.info = info    # what GetEntityInfo says of it at start-up


def docked(config: SimConfig, world: Optional[World],
           warn: Optional[Callable[[str], None]] = None) -> SimConfig:
    """
    Return ``config`` with its ``battery_dock`` named pose of ``world`` as its dock pose.

    Without ``battery_dock``, ``config`` as it is. A world without that pose
    (or none loaded) is a ConfigError, or with ``warn`` one warning and no dock.
    """
    name = config.battery_dock
    if not name:
        return config
    pose = next((p for p in world.named_poses if p.name == name), None) if world else None
    if pose is None:
        where = f'the world {world.name}' if world is not None else 'no world'
        message = f'battery_dock {name[:100]!r} is not a named pose of {where}'
        if warn is None:
            raise ConfigError(message)
        warn(message + ': no dock to charge on')
        return dataclasses.replace(config, battery_dock_pose=())
    dock = (pose.position[0], pose.position[1], yaw_of(pose.orientation))
    return dataclasses.replace(config, battery_dock_pose=dock)


def placed(start: RobotStart, world: World,
           warn: Optional[Callable[[str], None]] = None) -> RobotStart:
    """
    Return a start-up robot's start in ``world``: its initial pose from the world's start pose.

    ``initial_pose`` [x, y, yaw] is relative to the world's start pose when
    it names one (x, y and yaw of that pose: robots stand on the ground), else
    to the world's origin. Its dock is the world's (:func:`docked`, ``warn``
    as it takes it).
    """
    try:
        start = start._replace(config=docked(start.config, world, warn))
    except ConfigError as exc:
        raise ConfigError(f'robot {start.name}: {exc}' if start.listed else str(exc)) from None
    pose = world.start_pose
    if pose is None:
        return start
    x, y, yaw = start.config.initial_pose
    yaw0 = yaw_of(pose.orientation)
    c, s = math.cos(yaw0), math.sin(yaw0)
    initial = (pose.position[0] + c * x - s * y, pose.position[1] + s * x + c * y,
               math.remainder(yaw0 + yaw, 2.0 * math.pi))
    return start._replace(config=dataclasses.replace(start.config, initial_pose=initial))


def _robot_info(start: RobotStart) -> EntityInfo:
    """Return a start-up robot's info: a ROBOT, with the ``tags`` parameter's tags."""
    return EntityInfo(Category.ROBOT, tags=tuple(start.config.tags))


def robot_starts(config: SimConfig, specs: Sequence[RobotSpec],
                 namespace: str) -> List[RobotStart]:
    """
    Return how each start-up robot is loaded: the listed ones, else the one default robot.

    Namespaces resolve under ``namespace`` (the simulator's); ConfigError for
    two robots in one namespace.
    """
    if not specs:
        return [RobotStart(None, config, namespace, False)]
    namespaces = [resolve_namespace(namespace, spec.namespace) for spec in specs]
    for i, resolved in enumerate(namespaces):
        if resolved in namespaces[:i]:
            other = specs[namespaces.index(resolved)].name
            raise ConfigError(f'robots {other} and {specs[i].name} both have the namespace '
                              f'{resolved}: each robot needs one of its own')
    return [RobotStart(spec.name, spec.config, resolved, True)
            for spec, resolved in zip(specs, namespaces)]


class Startup:
    """
    Load the start-up world into ``world`` and build it again when asked.

    ``warn`` and ``error`` get the robots' one-line reports (a listed robot's
    name in front of its warnings); ``error`` also says when a body cannot be
    loaded again.
    """

    def __init__(self, world: SimWorld, warn: Callable[[str], None],
                 error: Callable[[str], None]) -> None:
        self._world = world
        self._warn, self._error = warn, error
        self._entities: List[_Entity] = []
        self.world_file: Optional[World] = None

    def load(self, config: SimConfig, starts: Sequence[RobotStart], world_file: World
             ) -> Tuple[List[Robot], List[Body]]:
        """
        Load the start-up world with ``world_file``'s models: return its robots and models.

        Raises a SetupError when a robot or a model cannot be loaded, or two
        robots start inside each other; the caller closes the world then.
        """
        self.world_file = world_file
        plane = self._world.bodies.get(GROUND_PLANE_NAME)  # the world loaded it
        if plane is not None:
            self._entities.append(_Entity(plane))
        robots: List[Robot] = []
        models: List[Body] = []
        try:
            with self._world.expecting_ray_robots(_with_rays(starts)):
                robots.append(self._start_robot(starts[0], world_file))
                for description, position in config.extra_models:
                    models.append(self._load_extra(description, position))
                for model in world_file.models:
                    self._entities.append(self._load_world_model(model))
                    models.append(self._entities[-1].body)
                for start in starts[1:]:
                    robots.append(self._start_robot(start, world_file))
            _check_apart(robots)
        except Exception:
            for robot in robots:  # their ray groups and temporary description files
                robot.close()
            raise
        return robots, models

    def infos(self) -> Dict[str, EntityInfo]:
        """Return each start-up entity's info at start, by name (what a full reset restores)."""
        return {entity.body.name: entity.info for entity in self._entities}

    def names(self) -> List[str]:
        """Return the names of the start-up entities that stay when another world is loaded."""
        return [entity.body.name for entity in self._entities if not entity.world_model]

    def names_around_world(self) -> Tuple[List[str], List[str]]:
        """Return the names of :meth:`names` a world's models load after, and those before."""
        kept, at = self._kept()
        return [e.body.name for e in kept[:at]], [e.body.name for e in kept[at:]]

    def _kept(self) -> Tuple[List['_Entity'], int]:
        """Return the entities that stay when another world is loaded, and where its go."""
        kept = [entity for entity in self._entities if not entity.world_model]
        robot_places = [i for i, entity in enumerate(kept) if entity.robot is not None]
        # The world's models load after the first robot and extra_models, before the others.
        return kept, robot_places[1] if len(robot_places) > 1 else len(kept)

    def _load_extra(self, description: str, position: Tuple[float, float, float]) -> Body:
        try:  # checked as the urdf parameter is: PyBullet crashed on what it refuses
            path = resolve_description_path(description)
            read_urdf(path)
        except DescriptionError as exc:
            raise WorldError(f'extra_models: {exc}') from None
        model = self._world.load(path, position, source=description)
        model.drop_damping()  # as a spawned entity: no damping Gazebo would not have
        self._entities.append(_Entity(model, model=True))
        return model

    def _load_world_model(self, model: WorldModel, into: Optional[WorldBuild] = None
                          ) -> '_Entity':
        body = self._world.load(model.path, model.position, model.orientation, name=model.name,
                                source=model.source, into=into,
                                flags=self._world.model_flags if model.sdf else 0,
                                made_from=model.made_from, given_as=model.given_as)
        body.drop_damping()
        if model.sdf:
            body.free_joints()  # Gazebo's joints: held by their friction, not a motor
        return _Entity(body, model=True, world_model=True, info=EntityInfo(
            description=model.description, tags=model.tags))

    def _start_robot(self, start: RobotStart, world_file: World) -> Robot:
        at = placed(start, world_file)
        robot = self.load_robot(at)
        self._entities.append(_Entity(robot.body, at, info=_robot_info(at), start=start))
        return robot

    def _robot_starts(self) -> List[RobotStart]:
        """Return the start of each start-up robot still in the launch, as its parameters say."""
        return [entity.start for entity in self._entities if entity.start is not None]

    def load_robot(self, start: RobotStart, into: Optional[WorldBuild] = None) -> Robot:
        """
        Load a driven robot standing at its ``initial_pose``; return it.

        Its description, drive and sensors are ``start.config``'s; ``into``:
        a world being built (``SimWorld.build``) instead of the live one. Raises a
        SetupError (WorldError, ConfigError) when it cannot be loaded or
        driven, naming the robot when it is a listed one; nothing of it stays.
        """
        name, config, namespace, listed = start
        off = self._off_ground(start)
        if off is not None:
            raise WorldError(f'robot {name}: {off}' if listed else off)
        try:
            description = RobotDescription.load(config.urdf, config.robot_description)
        except DescriptionError as exc:
            raise WorldError(f'robot {name}: {exc}' if listed else str(exc)) from None
        body = None
        try:
            # The body's source is where PyBullet read it: the urdf parameter as given,
            # or the temporary file robot_description's text was written to.
            body = self._world.load_robot(
                description.path, config.initial_pose, config.body_yaw_offset_rad, name=name,
                source=description.path if config.robot_description else config.urdf or None,
                into=into,
                given_as='the robot_description parameter' if config.robot_description else None)
            source = ('the robot_description parameter' if config.robot_description
                      else description.path)
            warn = self._warn
            if listed:
                warn = _named(self._warn, body.name)
            with self._world.ray_groups_of(into):
                try:
                    return Robot(self._world, body, config, source, description.text,
                                 warn=warn, error=self._error, resources=[description],
                                 namespace=namespace)
                except SetupError as exc:
                    if not listed or str(exc).startswith(f'robot {body.name}'):
                        raise
                    # Which of the robots cannot be driven or sensed ("no link named head").
                    raise type(exc)(f'robot {body.name}: {exc}') from exc
        except Exception:
            if body is not None:
                if into is not None:
                    into.bodies.pop(body.name, None)
                    body.remove()
                else:
                    self._world.remove(body)
            description.close()
            raise

    def _off_ground(self, start: RobotStart) -> Optional[str]:
        """Return why ``start`` (placed) would have the robot fall for ever; None if not."""
        x, y, _ = start.config.initial_pose
        off = self._world.off_ground(x, y)
        if off is None:
            return None
        return f'initial_pose puts the robot at x {x:g}, y {y:g}, {off}: it would fall for ever'

    def off_ground(self, world_file: World) -> Optional[str]:
        """Return why a start-up robot would fall for ever in ``world_file``; None if none."""
        for start in self._robot_starts():
            try:
                off = self._off_ground(placed(start, world_file))
            except ConfigError:
                continue  # its dock: said when the world is built
            if off is not None:
                return f'robot {start.name}: {off}' if start.name else off
        return None

    def rebuild(self, robots: Sequence[Robot], as_launched: bool) -> Rebuilt:
        """
        Build the physics world again, each body loaded in its order, from its initial state.

        ``robots`` are the simulation's now; each starts again right after its
        body is loaded, as it did. ``as_launched``: the start-up entities (a
        robot deleted since is loaded again from its start: a new Robot),
        else the bodies in the world now. A body that cannot be loaded again
        (its file gone) leaves the world, with one error line.
        """
        robot_of = {id(robot.body): robot for robot in robots}
        world = self._world
        plan: List[Tuple[Body, Optional[_Entity]]]
        if as_launched:
            plan = [(entity.body, entity) for entity in self._entities]
        else:
            plan = [(body, None) for body in world.bodies.values()]
        world.clear()
        after: List[Robot] = []
        dropped: List[str] = []
        changed = False
        for body, entity in plan:
            robot = robot_of.get(id(body))
            if entity is not None and entity.robot is not None and robot is None:
                changed = True  # a start-up robot deleted since: built again
                robot = self._load_again(entity)
                if robot is not None:
                    after.append(robot)
                continue
            try:
                world.reload(body)
            except WorldError as exc:
                self._error(f'{body.name} left the world: {exc}')
                dropped.append(body.name)
                if robot is not None:
                    robot.close()
                    changed = True
                continue
            if robot is not None:
                if as_launched:
                    # As launched: its readings repeat too. First, so that the encoders
                    # take their baseline when the robot starts again, as at start-up.
                    robot.restart_noise()
                robot.reloaded()
                after.append(robot)
        models = [e.body for e in self._entities if e.model] if as_launched else None
        return Rebuilt(after, models, changed, dropped)

    def switching(self, world_file: World, robots: Sequence[Robot], beside: bool = True,
                  leaving: Callable[[], None] = lambda: None
                  ) -> Generator[None, None, Rebuilt]:
        """
        Build the physics world again as launched with ``world_file`` instead of the old world.

        A generator: beside (``SimWorld.build``), it yields after each body
        it loads, while the old world may go on stepping between (a caller
        holds the simulation's lock for each ``next``), and its last ``next``
        swaps the new world in at once; in place (``beside`` False, or a GUI
        world) it yields nothing. Returns (``StopIteration.value``) what the
        simulation keeps. The ground, the robots and ``extra_models`` stay
        (loaded again in their order, the robots at the new world's start
        pose: a robot whose start does not move is the same Robot, others are
        built anew); the old world's models leave, the new world's take their
        place in the order. ``robots`` are the simulation's now (spawned ones
        excluded), as they are at the swap. ``leaving()`` is called once, as
        the old world goes (just before the swap, or before it is emptied in
        place): it may raise to keep the old world. Raises WorldError when a new
        model cannot be loaded (the caller checked them first; the old world
        is then as it was if built beside); a body of the old launch that
        cannot be loaded again leaves the world, with one error line.
        """
        robot_of = {id(robot.body): robot for robot in robots}
        kept, at = self._kept()
        # Each robot's own start: a robot that left the world took its start with it.
        robot_starts = {id(entity): placed(entity.start, world_file, self._warn)
                        for entity in kept if entity.start is not None}  # in load order
        # The robots whose start does not move: the same Robot, its ray group kept.
        staying = [robot_of[id(entity.body)] for entity in kept
                   if id(entity.body) in robot_of
                   and robot_of[id(entity.body)].config == robot_starts[id(entity)].config]
        if not beside or self._world.gui:
            leaving()
        build = self._world.build(beside, [robot.ray_group for robot in staying
                                           if robot.ray_group is not None])
        entities: List[_Entity] = []
        after: List[Robot] = []
        restarted: List[Robot] = []  # kept robots, to start again once their bodies are in
        built: List[Tuple[Robot, int]] = []  # robots built anew, and the step they were built at
        replaced: List[Robot] = []  # the robots they replace
        dropped: List[str] = []
        changed = False
        # Built anew, a robot hides its own links from its rays only if it is alone (SimWorld).
        with self._world.expecting_ray_robots(_with_rays(self._robot_starts())):
            try:
                for entity in kept[:at] + [None] + kept[at:]:
                    if entity is None:
                        for model in world_file.models:
                            entities.append(self._load_world_model(model, build))
                            if build.beside:
                                yield
                        continue
                    if entity.robot is None:
                        if self._reload(entity.body, dropped, build):
                            entities.append(entity)
                        if build.beside:
                            yield
                        continue
                    start = robot_starts[id(entity)]
                    entity = _Entity(entity.body, start, info=_robot_info(start),
                                     start=entity.start)
                    robot = robot_of.get(id(entity.body))
                    if robot is not None and robot in staying:  # its start did not move
                        if self._reload(entity.body, dropped, build):
                            entities.append(entity)
                            restarted.append(robot)
                            after.append(robot)
                            if not build.beside:  # as it was: started before the next load
                                robot.reloaded()
                                robot.restart_noise()
                            else:
                                yield
                            continue
                    if robot is not None:
                        if build.beside:
                            replaced.append(robot)  # it goes on in the old world until the swap
                        else:
                            robot.close()
                    changed = True
                    if entity.body.name not in dropped:
                        entities.append(entity)  # a full reset tries again if it fails now
                        robot = self._load_again(entity, build)  # at the new start, new interfaces
                        if robot is not None:
                            after.append(robot)
                            built.append((robot, self._world.step_count))
                    if build.beside:
                        yield
                if build.beside:
                    leaving()
                    for robot in replaced:  # their ray groups back to the old world's list
                        robot.close()
                self._world.take(build)
            except BaseException:
                self._world.abandon(build)
                with self._world.ray_groups_of(build):
                    for robot, _ in built:
                        robot.close()
                raise
        if build.beside:
            for robot in restarted:
                robot.reloaded()
                robot.restart_noise()
        for robot, step in built:
            # Built while the old world stepped on: as if built now.
            robot.restart_time(step - self._world.step_count)
        self._entities, self.world_file = entities, world_file
        return Rebuilt(after, [e.body for e in entities if e.model], changed, dropped)

    def _reload(self, body: Body, dropped: List[str], into: Optional[WorldBuild] = None) -> bool:
        """Load ``body`` again; False (one error line, its name in ``dropped``) if it cannot be."""
        try:
            self._world.reload(body, into)
        except WorldError as exc:
            self._error(f'{body.name} left the world: {exc}')
            dropped.append(body.name)
            return False
        return True

    def _load_again(self, entity: _Entity, into: Optional[WorldBuild] = None
                    ) -> Optional[Robot]:
        """Load a deleted start-up robot as at start-up; None (one error line) if it cannot be."""
        assert entity.robot is not None  # asked only of a robot's entity
        try:
            robot = self.load_robot(entity.robot, into)
        except SetupError as exc:
            self._error(f'robot {entity.body.name} cannot be loaded again: {exc}')
            return None
        entity.body = robot.body
        return robot


T = TypeVar('T')


def finished(steps: Generator[None, None, T]) -> T:
    """Run a generator of steps (:meth:`Startup.switching`) to its end; return its value."""
    while True:
        try:
            next(steps)
        except StopIteration as stop:
            return stop.value


def _named(warn: Callable[[str], None], name: str) -> Callable[[str], None]:
    return lambda text: warn(f'robot {name}: {text}')


def _with_rays(starts: Sequence[RobotStart]) -> int:
    """Return how many of the robots cast rays (a laser or a 3D lidar)."""
    return sum(1 for start in starts if start.config.scan_rate_hz or start.config.lidar3d_rate_hz)


def _check_apart(robots: Sequence[Robot]) -> None:
    """Refuse robots that start inside each other (two poses left alike, a name mistyped)."""
    boxes = [(robot, robot.body.bounding_box()) for robot in robots]
    for i, (robot, box) in enumerate(boxes):
        for other, other_box in boxes[:i]:
            if all(box[0][k] < other_box[1][k] and other_box[0][k] < box[1][k]
                   for k in range(3)):
                raise ConfigError(f'robots {other.name} and {robot.name} overlap where they '
                                  f'start: give {robot.name}.initial_pose a place of its own')
