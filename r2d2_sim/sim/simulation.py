"""
The simulation core: one physics step for the whole world, read top to bottom, with no ROS.

:meth:`Simulation.step` is the one place where a command becomes wheel torque
and comes back as odometry: each robot's drive controller turns its latest
command into wheel targets (limits, ramp, timeout), PyBullet steps, and each
robot measures what is due at that step: its state when a publication is due
(joints, base, wheel odometry, read once for every output), its camera, laser
and IMU at their own rates. It returns the measurements as plain data;
outputs only translate them into messages. Every step also checks that no
robot's physics has blown up, and puts back one that has.
"""

from typing import Callable, List, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.physics.description import DescriptionError, RobotDescription
from r2d2_sim.sim.entities import Entities, EntityError
from r2d2_sim.errors import SetupError, WorldError
from r2d2_sim.sim.parameters import ConfigError, SimConfig
from r2d2_sim.sim.robot import Frame, Measurement, Robot
from r2d2_sim.sim.robot_parameters import robot_config, RobotSpec
from r2d2_sim.model.timing import StepClock, StepSchedule
from r2d2_sim.model.transforms import yaw_of
from r2d2_sim.physics.world import ExtraModel, SimWorld

# Frame and Measurement are the core's data, defined beside the robot that measures them.
__all__ = ['Simulation', 'StepResult', 'Frame', 'Measurement', 'GUI_CAMERA_RATE_HZ']

# Follow the robot with the GUI camera this many times per simulated second.
GUI_CAMERA_RATE_HZ = 30.0


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
    the ``robots`` parameter, each with its own settings. Without them the
    world has one robot, named after its URDF, with ``config``'s settings.
    More robots join with :meth:`add_robot` and :meth:`spawn_robot`, and a
    spawned one leaves with :meth:`delete_entity`. ``warn`` and ``error``
    receive one-line reports (the node logs them, throttled); they default
    to silence. Raises a SetupError subclass (ConfigError, WorldError...)
    when the configuration cannot be simulated.
    """

    def __init__(self, config: SimConfig, robots: Sequence[RobotSpec] = (),
                 warn: Callable[[str], None] = _ignore,
                 error: Callable[[str], None] = _ignore) -> None:
        self.config = config
        rate = config.physics_rate_hz
        self.time_step_s = 1.0 / rate
        self.clock = StepClock(rate)
        self.publish_schedule = StepSchedule(rate, config.publish_rate_hz)
        self.steps_per_gui_frame = max(1, round(rate / GUI_CAMERA_RATE_HZ))
        self.last_frame_step = 0
        self.robots: List[Robot] = []
        self.entities: Optional[Entities] = None
        self._warn, self._error = warn, error
        first = robots[0].config if robots else config
        self.world = SimWorld(
            first.urdf or None, robot_description=first.robot_description,
            gui=config.gui, time_step_s=self.time_step_s,
            gravity_m_s2=config.gravity_m_s2, ground_plane=config.ground_plane,
            initial_pose=first.initial_pose, body_yaw_offset_rad=first.body_yaw_offset_rad,
            robot_name=robots[0].name if robots else None,
            extra_models=[ExtraModel(name, position) for name, position in config.extra_models]
            + ([ExtraModel(config.world, (0.0, 0.0, 0.0))] if config.world else []))
        try:
            source = ('the robot_description parameter' if first.robot_description
                      else self.world.urdf_path)
            self.robots.append(Robot(self.world, self.world.robot, first, source,
                                     self.world.robot_description, warn=warn, error=error))
            for spec in robots[1:]:
                self.add_robot(spec.name, spec.config)
            self._check_apart()
        except Exception:
            for robot in self.robots:
                robot.close()
            self.world.close()
            raise
        self.entities = Entities(self.world, lambda: self.robots, config.world_frame_id,
                                 self._teleported)
        # Nothing changed since start-up (or a full reset): with time at 0, 'stopped'.
        self.pristine = True

    def _check_apart(self) -> None:
        """Refuse robots that start inside each other (two poses left alike, a name mistyped)."""
        boxes = [(robot, robot.body.bounding_box()) for robot in self.robots]
        for i, (robot, box) in enumerate(boxes):
            for other, other_box in boxes[:i]:
                if all(box[0][k] < other_box[1][k] and other_box[0][k] < box[1][k]
                       for k in range(3)):
                    raise ConfigError(f'robots {other.name} and {robot.name} overlap where they '
                                      f'start: give {robot.name}.initial_pose a place of its own')

    def add_robot(self, name: str, config: SimConfig) -> Robot:
        """
        Load a driven robot ``name`` standing at ``config.initial_pose``; return it.

        Its description, drive and sensors are ``config``'s (see
        :func:`~r2d2_sim.sim.robot_parameters.robot_config`). Raises a SetupError
        (WorldError, ConfigError) when it cannot be loaded or driven; nothing
        of it then stays in the world.
        """
        try:
            description = RobotDescription.load(config.urdf, config.robot_description)
        except DescriptionError as exc:
            raise WorldError(f'robot {name}: {exc}') from None
        body = None
        try:
            body = self.world.load_robot(description.path, config.initial_pose,
                                         config.body_yaw_offset_rad, name=name,
                                         source=config.urdf or description.path)
            source = ('the robot_description parameter' if config.robot_description
                      else description.path)
            robot = Robot(self.world, body, config, source, description.text,
                          warn=self._named_warn(name), error=self._error,
                          resources=[description])
        except Exception:
            if body is not None:
                self.world.remove(body)
            description.close()
            raise
        self.robots.append(robot)
        self.pristine = False
        return robot

    def spawn_robot(self, name: str, allow_renaming: bool, uri: str, resource_string: str,
                    frame_id: str, position: Sequence[float],
                    orientation: Sequence[float]) -> Robot:
        """
        Spawn a driven robot through the standard: at its pose exactly, with the world's settings.

        As :meth:`Entities.spawn <r2d2_sim.sim.entities.Entities.spawn>` (the
        same names, resources and refusals), then driven as a robot whose
        odometry starts at that pose; EntityError OPERATION_FAILED when the
        world's robot settings cannot drive it.
        """
        body, description = self.entities.spawn_body(
            name, allow_renaming, uri, resource_string, frame_id, position, orientation,
            flags=self.world.robot_flags, body_yaw_offset_rad=self.config.body_yaw_offset_rad)
        base = body.world_state()
        try:
            config = robot_config(self.config, body.name, {
                'initial_pose': [base.position[0], base.position[1], yaw_of(base.orientation)]})
            self._check_frames_free(body.name, config)
            robot = Robot(self.world, body, config, body.source, description,
                          warn=self._named_warn(body.name), error=self._error)
        except EntityError:
            self.entities.delete(body.name)
            raise
        except SetupError as exc:
            self.entities.delete(body.name)
            raise EntityError('OPERATION_FAILED', f'{body.name} cannot be driven: {exc}') from None
        self.robots.append(robot)
        self.pristine = False
        return robot

    def _named_warn(self, name: str) -> Callable[[str], None]:
        return lambda text: self._warn(f'robot {name}: {text}')

    def _check_frames_free(self, name: str, config: SimConfig) -> None:
        """Refuse a robot whose frames would be another's on the shared /tf."""
        if config.tf_layout != 'shared':
            return
        for robot in self.robots:
            if robot.config.frame_prefix == config.frame_prefix:
                raise EntityError('NAME_NOT_UNIQUE', f'robot {robot.name} publishes its frames '
                                  f'with the prefix {config.frame_prefix!r} already: name the new '
                                  'robot otherwise')

    def delete_entity(self, name: str) -> None:
        """Delete a spawned entity, and the robot it is if it is one (start-up ones stay)."""
        body = self.entities.body(name)
        self.entities.delete(name)  # refuses a start-up entity before anything changes
        self._forget_robots([r for r in self.robots if r.body is body])
        self.pristine = False

    def _forget_robots(self, robots: Sequence[Robot]) -> None:
        for robot in robots:
            self.robots.remove(robot)
            robot.close()

    def _teleported(self, body) -> None:
        self.pristine = False
        for robot in self.robots:
            if robot.body is body:
                robot.teleported()

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
        if world.gui and step % self.steps_per_gui_frame == 0:
            world.follow_camera()
        state_due = self.publish_schedule.due(step)
        time_ns = self.clock.time_ns(step)
        measurements = tuple(robot.measure(step, time_ns, state_due) for robot in robots)
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

        ``spawned``: delete every entity spawned while running. ``state``: every
        body back where it started (spawned ones at their spawn pose) and
        every robot at rest, commands and odometry dropped. ``time``: the
        step count and simulated time back to 0, every schedule from there.
        """
        if spawned:
            self._forget_robots([r for r in self.robots if r.body.spawned])
            self.entities.delete_spawned()
        if state:
            self.world.reset()
            for robot in self.robots:
                robot.reset()
        if time:
            steps_back = self.world.step_count
            self.world.step_count = 0
            self.publish_schedule.restart(0)
            self.last_frame_step = 0
            for robot in self.robots:
                robot.restart_time(steps_back)
        self.pristine = time and state and spawned

    def close(self) -> None:
        """Disconnect the physics client; safe to call twice."""
        for robot in self.robots:
            robot.close()
        if self.entities is not None:
            self.entities.close()
        self.world.close()
