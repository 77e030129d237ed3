"""
The entities of the simulation, as the standard sees them: asked about, placed, spawned, deleted.

:class:`SimulationEntities` is mixed into :class:`~r2d2_sim.sim.simulation.Simulation`:
what GetEntities, GetEntityInfo, GetEntityState and their setters ask of
the world (thin answers from :class:`~r2d2_sim.sim.entities.Entities`, with
the category a robot gets), and the two changes of the set of entities:
a spawn (a plain entity, or a driven robot when it has a namespace, which
the robots' watchers may refuse) and a delete. The robots list, the
watchers and ``pristine`` are the Simulation's, set in its ``__init__``.
"""

from typing import List, Sequence, Tuple

from r2d2_sim.errors import RefusedError, SetupError
from r2d2_sim.model.transforms import BaseState, yaw_of
from r2d2_sim.physics.body import Body
from r2d2_sim.sim.entities import Category, EntityInfo, SpawnRequest
from r2d2_sim.sim.entity_bounds import Region
from r2d2_sim.sim.launch import docked
from r2d2_sim.sim.parameter_readers import namespace as read_namespace
from r2d2_sim.sim.parameters import ConfigError, SimConfig
from r2d2_sim.sim.robot import Robot
from r2d2_sim.sim.robot_parameters import resolve_namespace, robot_config

# A spawn overlapping a robot deeper than resting contacts sink (about 0.01 mm) is a shove.
SHOVE_DEPTH_M = 0.001


class SimulationEntities:
    """The Simulation's entities: the standard's questions about them, spawn and delete."""

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
            self._warn_of_overlaps(body)
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
