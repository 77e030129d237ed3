"""
The simulation core: one physics step, read top to bottom, with no ROS.

:meth:`Simulation.step` is the one place where a command becomes wheel torque
and comes back as odometry: the drive controller turns the latest command
into wheel targets (limits, ramp, timeout), PyBullet steps, and when a state
publication is due the robot is read once into a :class:`Frame` (joints, base,
odometry) that every output of that step shares. Every step also checks that
the physics has not blown up, and resets the robot if it has.
"""

from typing import Callable, Dict, List, NamedTuple, Optional, Tuple

from r2d2_sim.drive_controller import CommandVerdict, DriveController, timeout_steps
from r2d2_sim.kinematics import DiffDriveOdometry
from r2d2_sim.parameters import ConfigError, SimConfig
from r2d2_sim.robot import find_drive_train, HeadCamera, ImuSensor, LaserScanner
from r2d2_sim.timing import StepClock, StepSchedule
from r2d2_sim.world import BaseState, ExtraModel, JointRecord, JointStates, SimWorld

# Follow the robot with the GUI camera this many times per simulated second.
GUI_CAMERA_RATE_HZ = 30.0


class Frame(NamedTuple):
    """The robot after one physics step, read once for every output due at that step."""

    step: int
    time_ns: int
    joints: JointStates              # the movable joints, in joint index order
    base: BaseState                  # true pose and twist of the body frame
    odometry: Optional[DiffDriveOdometry]  # wheel odometry (None without wheels)

    @property
    def stamp(self):
        """Return (sec, nanosec) of the frame's simulated time."""
        return divmod(self.time_ns, 10**9)


class StepResult(NamedTuple):
    """What one physics step produced: the frame if a publication is due, the sensors due."""

    frame: Optional[Frame]
    sensors_due: Tuple[str, ...]  # of 'camera', 'scan', 'imu', at their own rates


NOTHING_DUE = StepResult(None, ())


def _ignore(text: str) -> None:
    pass


class Simulation:
    """
    The world, the robot's drive controller and camera, and the step schedule.

    ``warn`` and ``error`` receive one-line reports (the node logs them,
    throttled); they default to silence. Raises ConfigError or WorldError when
    the configuration cannot be simulated.
    """

    def __init__(self, config: SimConfig, warn: Callable[[str], None] = _ignore,
                 error: Callable[[str], None] = _ignore) -> None:
        self.config = config
        self._error = error
        self.time_step_s = 1.0 / config.physics_rate_hz
        self.clock = StepClock(config.physics_rate_hz)
        self.publish_schedule = StepSchedule(config.physics_rate_hz, config.publish_rate_hz)
        self.steps_per_gui_frame = max(1, round(config.physics_rate_hz / GUI_CAMERA_RATE_HZ))
        self.blow_ups = 0
        self.last_frame_step = 0
        self.controller: Optional[DriveController] = None
        self.camera: Optional[HeadCamera] = None
        self.laser: Optional[LaserScanner] = None
        self.imu: Optional[ImuSensor] = None
        # Each sensor's own rate, in physics steps (camera, scan, imu when on).
        self.sensor_schedules: Dict[str, StepSchedule] = {}
        self.world = SimWorld(
            config.urdf or None, robot_description=config.robot_description,
            gui=config.gui, time_step_s=self.time_step_s,
            gravity_m_s2=config.gravity_m_s2, ground_plane=config.ground_plane,
            initial_pose=config.initial_pose,
            body_yaw_offset_rad=config.body_yaw_offset_rad,
            extra_models=[ExtraModel(name, position) for name, position in config.extra_models]
            + ([ExtraModel(config.world, (0.0, 0.0, 0.0))] if config.world else []))
        try:
            self._build(warn)
        except Exception:
            self.world.close()
            raise

    def _build(self, warn: Callable[[str], None]) -> None:
        config, world = self.config, self.world
        problem = world.state_problem()
        if problem is not None:
            raise ConfigError(f'the robot cannot start there: {problem}')
        self.description_source = ('the robot_description parameter'
                                   if config.robot_description else world.urdf_path)
        # base_footprint is the base's projection on the ground: the body frame
        # sits this high above it when the robot stands at rest.
        self.footprint_height_m = world.base_state().position[2]
        self.movable: List[JointRecord] = world.movable_joints()
        self.movable_indices = [j.index for j in self.movable]
        self.drive = find_drive_train(world, config, self.description_source, warn)
        if self.drive is not None:
            drive = self.drive
            world.set_wheel_lateral_friction(drive.wheel_indices,
                                             config.wheel_lateral_friction_ratio)
            self._wheel_forces = [drive.max_force_n_m] * len(drive.wheel_indices)
            # Where the wheels sit in a frame's joint readout, which odometry reads.
            slot = {index: i for i, index in enumerate(self.movable_indices)}
            self._wheel_slots = [slot[index] for index in drive.wheel_indices]
            self.controller = DriveController(
                drive.geometry, drive.limits, self.time_step_s,
                timeout_steps(config.cmd_vel_timeout_s, config.physics_rate_hz),
                len(drive.left_indices), len(drive.right_indices),
                config.wheel_velocity_sign, config.initial_pose)
            self._drive(self.controller.reset(0, self._wheel_positions()))
        rate = config.physics_rate_hz
        if config.camera_rate_hz > 0.0:
            self.camera = HeadCamera(world, config)
            self.sensor_schedules['camera'] = StepSchedule(rate, config.camera_rate_hz)
        if config.scan_rate_hz > 0.0:
            self.laser = LaserScanner(world, config, self.footprint_height_m)
            self.sensor_schedules['scan'] = StepSchedule(rate, config.scan_rate_hz)
        if config.imu_rate_hz > 0.0:
            self.imu = ImuSensor(world, config)
            self.sensor_schedules['imu'] = StepSchedule(rate, config.imu_rate_hz)

    # -- time -------------------------------------------------------------------

    @property
    def step_count(self) -> int:
        """Return the number of physics steps taken since start."""
        return self.world.step_count

    @property
    def time_ns(self) -> int:
        """Return the simulated time now, in integer nanoseconds."""
        return self.clock.time_ns(self.world.step_count)

    def steps_to_next_publish(self) -> int:
        """Return the number of physics steps until the next state publication."""
        return self.publish_schedule.next_step - self.world.step_count

    # -- the step ---------------------------------------------------------------

    def command(self, linear_x: float, angular_z: float, **other_axes: float
                ) -> Optional[CommandVerdict]:
        """Hand a Twist to the drive controller (None: the robot has no wheels)."""
        if self.controller is None:
            return None
        return self.controller.command(linear_x, angular_z, **other_axes)

    def step(self) -> StepResult:
        """
        Run one physics step; return the state frame if a publication is due, and the sensors due.

        Command -> wheel targets -> physics -> (frame and odometry, or the
        cheap blow-up check when nothing is published at this step) -> which
        sensors are due at their own rates.
        """
        world, controller = self.world, self.controller
        if controller is not None:
            targets = controller.update(world.step_count)
            if targets is not None:
                self._drive(targets)
        world.step(1)
        step = world.step_count
        if world.gui and step % self.steps_per_gui_frame == 0:
            world.follow_camera()
        frame = None
        if self.publish_schedule.due(step):
            frame = self.frame()
        else:
            problem = world.state_problem()  # two raw queries, about 4 us
            if problem is not None:
                self._recover(problem)
        if not self.sensor_schedules:
            return NOTHING_DUE if frame is None else StepResult(frame, ())
        return StepResult(frame, tuple(name for name, schedule in self.sensor_schedules.items()
                                       if schedule.due(step)))

    def frame(self) -> Frame:
        """Read the robot once (resetting it first if the state is absurd); integrate odometry."""
        world = self.world
        joints = world.joint_states(self.movable_indices)
        base = world.base_state()
        problem = world.joint_problem(self.movable_indices, joints) or world.state_problem(base)
        if problem is not None:
            self._recover(problem)
            joints = world.joint_states(self.movable_indices)
            base = world.base_state()
        step = world.step_count
        odometry = None
        if self.controller is not None:
            positions = joints.positions
            self.controller.update_odometry([positions[s] for s in self._wheel_slots], step)
            odometry = self.controller.odometry
        self.last_frame_step = step
        return Frame(step, self.clock.time_ns(step), joints, base, odometry)

    def reset(self) -> None:
        """Put the robot back at its initial pose at rest, dropping the command and odometry."""
        self.world.reset()
        if self.imu is not None:
            self.imu.reset()
        if self.controller is not None:
            self._drive(self.controller.reset(self.world.step_count, self._wheel_positions()))

    def _recover(self, problem: str) -> None:
        self.blow_ups += 1
        self._error(f'physics blew up at t={self.time_ns / 1e9:.6f} s ({problem}): '
                    'resetting the robot to its initial pose')
        self.reset()

    def _drive(self, velocities: List[float]) -> None:
        self.world.set_joint_velocities(self.drive.wheel_indices, velocities, self._wheel_forces)

    def _wheel_positions(self) -> List[float]:
        return list(self.world.joint_states(self.drive.wheel_indices).positions)

    def close(self) -> None:
        """Disconnect the physics client; safe to call twice."""
        self.world.close()
