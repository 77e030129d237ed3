"""
The world as launched: what start-up loads, in its order, and building the world again.

No ROS here. :class:`Launch` loads the start-up world into a
:class:`~r2d2_sim.physics.world.SimWorld` (the ground plane, the first robot,
the ``extra_models`` and the ``world`` model, then the other robots: the order
PyBullet has always had them in, which body ids and the solver's order
follow), remembers each of those entities, and builds the physics world again
on a reset: every body loaded anew in its order (Bullet's contact data and
the order of its overlapping pairs survive a body put back in place, and
change the next steps), or, for a full reset ("as if it was closed and
launched again"), the start-up entities themselves, a robot deleted since
loaded again from its start-up arguments.
"""

from typing import Callable, List, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.errors import SetupError, WorldError
from r2d2_sim.physics.body import Body
from r2d2_sim.physics.description import (
    DescriptionError, resolve_description_path, RobotDescription)
from r2d2_sim.physics.world import GROUND_PLANE_NAME, SimWorld
from r2d2_sim.sim.parameters import ConfigError, SimConfig
from r2d2_sim.sim.robot import Robot
from r2d2_sim.sim.robot_parameters import resolve_namespace, RobotSpec

__all__ = ['Launch', 'RobotStart', 'Rebuilt', 'robot_starts']


class RobotStart(NamedTuple):
    """How a start-up robot is loaded: its name (None: the URDF's), settings and namespace."""

    name: Optional[str]
    config: SimConfig
    namespace: str   # resolved
    listed: bool     # one of those ``robots`` lists: its messages name it


class Rebuilt(NamedTuple):
    """The world after :meth:`Launch.rebuild`: what the simulation keeps of it."""

    robots: List[Robot]            # in load order
    models: Optional[List[Body]]   # the start-up models (as launched), else None: the same
    changed: bool                  # the robots are not the same ones
    dropped: List[str]             # bodies that could not be loaded again, by name


class _Entity:
    """One entity of the start-up world, in load order: its body, and a robot's start."""

    def __init__(self, body: Body, robot: Optional[RobotStart] = None,
                 model: bool = False) -> None:
        self.body = body    # the latest loaded for it (a robot loaded again has a new one)
        self.robot = robot
        self.model = model  # one of extra_models, or the world model


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


class Launch:
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

    def load(self, config: SimConfig, starts: Sequence[RobotStart]
             ) -> Tuple[List[Robot], List[Body]]:
        """
        Load the start-up world: return its robots and its models, in load order.

        Raises a SetupError when a robot or a model cannot be loaded, or two
        robots start inside each other; the caller closes the world then.
        """
        plane = self._world.bodies.get(GROUND_PLANE_NAME)  # the world loaded it
        if plane is not None:
            self._entities.append(_Entity(plane))
        robots: List[Robot] = []
        models: List[Body] = []
        try:
            robots.append(self._start_robot(starts[0]))
            extra = [(name, position) for name, position in config.extra_models]
            extra += [(config.world, (0.0, 0.0, 0.0))] if config.world else []
            for description, position in extra:
                models.append(self._load_model(description, position))
            for start in starts[1:]:
                robots.append(self._start_robot(start))
            _check_apart(robots)
        except Exception:
            for robot in robots:  # their ray groups and temporary description files
                robot.close()
            raise
        return robots, models

    def _load_model(self, description: str, position) -> Body:
        try:
            path = resolve_description_path(description)
        except DescriptionError as exc:
            raise WorldError(str(exc)) from None
        model = self._world.load(path, position, source=description)
        model.drop_damping()  # as a spawned entity: no damping Gazebo would not have
        self._entities.append(_Entity(model, model=True))
        return model

    def _start_robot(self, start: RobotStart) -> Robot:
        robot = self.load_robot(start)
        self._entities.append(_Entity(robot.body, start))
        return robot

    def load_robot(self, start: RobotStart) -> Robot:
        """
        Load a driven robot standing at its ``initial_pose``; return it.

        Its description, drive and sensors are ``start.config``'s. Raises a
        SetupError (WorldError, ConfigError) when it cannot be loaded or
        driven, naming the robot when it is a listed one; nothing of it stays.
        """
        name, config, namespace, listed = start
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
                source=description.path if config.robot_description else config.urdf or None)
            source = ('the robot_description parameter' if config.robot_description
                      else description.path)
            warn = self._warn
            if listed:
                warn = _named(self._warn, body.name)
            return Robot(self._world, body, config, source, description.text, warn=warn,
                         error=self._error, resources=[description], namespace=namespace)
        except Exception:
            if body is not None:
                self._world.remove(body)
            description.close()
            raise

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

    def _load_again(self, entity: _Entity) -> Optional[Robot]:
        """Load a deleted start-up robot as at start-up; None (one error line) if it cannot be."""
        try:
            robot = self.load_robot(entity.robot)
        except SetupError as exc:
            self._error(f'robot {entity.body.name} cannot be loaded again: {exc}')
            return None
        entity.body = robot.body
        return robot


def _named(warn: Callable[[str], None], name: str) -> Callable[[str], None]:
    return lambda text: warn(f'robot {name}: {text}')


def _check_apart(robots: Sequence[Robot]) -> None:
    """Refuse robots that start inside each other (two poses left alike, a name mistyped)."""
    boxes = [(robot, robot.body.bounding_box()) for robot in robots]
    for i, (robot, box) in enumerate(boxes):
        for other, other_box in boxes[:i]:
            if all(box[0][k] < other_box[1][k] and other_box[0][k] < box[1][k]
                   for k in range(3)):
                raise ConfigError(f'robots {other.name} and {robot.name} overlap where they '
                                  f'start: give {robot.name}.initial_pose a place of its own')
