"""
One driven robot in the world: its body, drive train and controller, its sensors and their rates.

No ROS here. A :class:`Robot` takes commands (:meth:`Robot.command`), turns
the latest into wheel motor targets before each physics step
(:meth:`Robot.drive`), and after the step measures what is due
(:meth:`Robot.measure`): its state for a publication (joints, base, wheel
odometry, and with ``publish_contacts`` what it touches) and each sensor at
its own rate. The laser's and the 3D lidar's rays are left pending
(:meth:`Robot.pending_rays`), so that the simulation casts every robot's rays
of a step together, then hands each robot its answers
(:meth:`Robot.take_rays`). Measurements are plain data in a
:class:`Measurement`; a robot whose physics blew up is put back where it
started, alone, unless it blew up MAX_BLOW_UPS_IN_A_ROW times in a row: then it
is given up (:attr:`Robot.given_up`), and the simulation takes it out.
"""

import math
from typing import Callable, List, NamedTuple, Optional, Sequence, Tuple, Union

import numpy

from r2d2_sim.physics.body import Body
from r2d2_sim.model.transforms import BaseState, in_body_frame, yaw_of
from r2d2_sim.physics.records import JointRecord, JointStates
from r2d2_sim.model.drive_controller import (
    CommandVerdict, DriveController, NO_WHEELS, timeout_steps)
from r2d2_sim.model.battery import Battery, BatteryReading, BatterySpec, Dock
from r2d2_sim.model.encoders import Encoders, OdometryCovariance
from r2d2_sim.model.noise import noise_generator
from r2d2_sim.sim.robots.drive_train import DriveTrain, find_drive_train
from r2d2_sim.model.kinematics import OdometryState
from r2d2_sim.sim.oracles import Touch, touching
from r2d2_sim.sim.settings.table import ConfigError
from r2d2_sim.sim.settings.config import SimConfig
from r2d2_sim.sim.robots.sensors import CameraImage, HeadCamera, ImuSensor, LaserScanner, Lidar3d
from r2d2_sim.model.sensors import ImuReading
from r2d2_sim.model.timing import stamp_of, StepSchedule
from r2d2_sim.physics.world import RayRequest, SimWorld, SPAWN_CLEARANCE_M

__all__ = ['Frame', 'Measurement', 'Robot', 'DriveTrain', 'FALLEN_DEPTH_M']

# A base this far below z 0 has nothing under it: the ground plane is a box 10 m deep, and a
# robot past its edge falls on for ever (damped: about 15 m/s, never a blow-up).
FALLEN_DEPTH_M = 10.0


class Frame(NamedTuple):
    """A robot's state after one physics step, read once for every output of that step."""

    step: int
    time_ns: int
    joints: JointStates                  # the movable joints, in joint index order
    base: BaseState                      # true pose of the body frame, its twist in that frame
    odometry: Optional[OdometryState]    # wheel odometry (None without wheels)

    @property
    def stamp(self) -> Tuple[int, int]:
        """Return (sec, nanosec) of the frame's simulated time."""
        return stamp_of(self.time_ns)


class Measurement(NamedTuple):
    """What one robot measured at one step: each field None unless due then."""

    time_ns: int
    frame: Optional[Frame]               # the state, when a state publication is due
    image: Optional[CameraImage]         # the head camera, at camera_rate
    scan: Optional[numpy.ndarray]        # REP-117 ranges (float32), at scan_rate
    imu: Optional[ImuReading]            # at imu_rate
    lidar: Optional[numpy.ndarray] = None  # 3D lidar points (rings, samples, 3), lidar3d_rate
    battery: Optional[BatteryReading] = None  # at battery_rate
    # With publish_contacts, what the robot touches, beside each frame (empty: nothing).
    contacts: Optional[Tuple[Touch, ...]] = None


def _ignore(text: str) -> None:
    pass


def _battery(config: SimConfig) -> Battery:
    """Return the robot's battery as configured, on its dock if it has one."""
    spec = BatterySpec(config.battery_capacity_ah, config.battery_initial_charge,
                       config.battery_voltage_empty_v, config.battery_voltage_full_v,
                       config.battery_idle_current_a, config.battery_current_per_effort_a_n_m,
                       config.battery_current_per_speed_a_rad_s, config.battery_charge_current_a)
    dock = None
    if config.battery_dock_pose:
        dock = Dock(*config.battery_dock_pose, *config.battery_dock_tolerance)
    return Battery(spec, dock)


# A step count no run reaches: a robot without sensors is never due to measure one.
NEVER = 1 << 62
# A robot that blows up this many times in a row, each time within CALM_S of being put
# back, is given up (Simulation takes it out of the world): one of inertias of 1e-9 on a
# 1 kg box blew up every 0.7 s, and each put-back loads it again (and every 64th
# builds the whole world again, for every other robot too), with an error line each.
MAX_BLOW_UPS_IN_A_ROW = 10
CALM_S = 5.0


class Robot:
    """
    A driven robot: its :class:`~r2d2_sim.physics.body.Body`, drive train, controller and sensors.

    ``config`` gives its drive and sensor settings and the physics rate their
    schedules run on; ``source`` says where its description came from (for
    messages), ``description`` is its URDF text, ``namespace`` where its ROS
    interfaces live (resolved; the simulator's own for the one default robot).
    ``warn`` receives one-line reports while it is built, ``error`` one line
    per blow-up. Raises ConfigError (one line) when the configuration cannot
    drive or sense this robot. ``resources`` (a temporary description
    file...) are closed with the robot (:meth:`close`).
    """

    def __init__(self, world: SimWorld, body: Body, config: SimConfig, source: str,
                 description: str, *, warn: Callable[[str], None] = _ignore,
                 error: Callable[[str], None] = _ignore, resources: Sequence = (),
                 namespace: str = '/') -> None:
        self.world = world
        self.body = body
        self.name = body.name
        self.namespace = namespace
        self.config = config
        self.source = source
        self.description = description
        self.blow_ups = 0
        # Blown up MAX_BLOW_UPS_IN_A_ROW times in a row: not put back, to be taken out.
        self.given_up = False
        self._blow_ups_in_a_row = 0
        self._put_back_at: Optional[int] = None  # the step of the last put-back
        self._error = error
        self._fall_told = False  # its fall was said (check_fall), since it was last put back
        self._resources = list(resources)
        self.laser: Optional[LaserScanner] = None
        self.lidar: Optional[Lidar3d] = None
        self.ray_group: Optional[int] = None  # the world's collision bit its rays pass through
        # (sensor, its RayRequest) due at this step, to be cast
        self._pending: List[Tuple[Union[LaserScanner, Lidar3d], RayRequest]] = []
        problem = body.state_problem()
        if problem is not None:
            raise ConfigError(f'the robot cannot start there: {problem}')
        # base_footprint is the base's projection on the ground: the body frame
        # sits this high above it when the robot stands at rest. A robot loaded
        # at start-up stands on the ground; one spawned through the standard
        # is where its pose says (in the air, maybe): measured from its lowest
        # point, with the start-up robots' clearance.
        self.footprint_height_m = body.world_state().position[2]
        if body.spawned:
            self.footprint_height_m -= body.bounding_box().low[2] - SPAWN_CLEARANCE_M
        self.movable: List[JointRecord] = body.movable_joints()
        self.movable_indices = [j.index for j in self.movable]
        self.drive: Optional[DriveTrain] = find_drive_train(body, config, source, warn)
        self.controller: Optional[DriveController] = None
        self._wheel_indices: Tuple[int, ...] = ()  # the drive train's, when it has one
        self._wheel_forces: List[float] = []
        self._wheel_slots: List[int] = []  # where the wheels sit in the joint readout
        if self.drive is not None:
            self._build_controller(self.drive)
        rate, step = config.physics_rate_hz, world.step_count
        self.camera = HeadCamera(world, body, config) if config.camera_rate_hz else None
        self._camera_depth = config.camera_depth or config.camera_point_cloud
        if config.scan_rate_hz or config.lidar3d_rate_hz:
            self.ray_group = world.take_ray_group()
            try:
                if config.scan_rate_hz:
                    self.laser = LaserScanner(world, body, config, self.footprint_height_m,
                                              self.ray_group)
                if config.lidar3d_rate_hz:
                    self.lidar = Lidar3d(world, body, config, self.footprint_height_m,
                                         self.ray_group)
            except Exception:
                world.release_ray_group(self.ray_group)
                raise
        self.imu = ImuSensor(body, config) if config.imu_rate_hz else None
        self.battery = _battery(config) if config.battery_rate_hz else None
        self._battery_step = step
        self._speed_factor = 1.0  # of the wheel targets: below 1 once the battery is empty
        self._camera_due = StepSchedule(rate, config.camera_rate_hz, step) if self.camera else None
        self._scan_due = StepSchedule(rate, config.scan_rate_hz, step) if self.laser else None
        self._lidar_due = (StepSchedule(rate, config.lidar3d_rate_hz, step) if self.lidar
                           else None)
        self._imu_due = StepSchedule(rate, config.imu_rate_hz, step) if self.imu else None
        self._battery_due = (StepSchedule(rate, config.battery_rate_hz, step) if self.battery
                             else None)
        self._schedules = [schedule for schedule in (
            self._camera_due, self._scan_due, self._lidar_due, self._imu_due, self._battery_due)
            if schedule is not None]
        # The first step a sensor may be due at: before it, a step without a publication
        # measures nothing (most steps), and only the blow-up check runs.
        self._quiet_until = 0
        self._time_step_s = 1.0 / rate

    def _build_controller(self, drive: DriveTrain) -> None:
        config = self.config
        self.body.set_wheel_lateral_friction(drive.wheel_indices,
                                             config.wheel_lateral_friction_ratio)
        self._wheel_indices = drive.wheel_indices
        self._wheel_forces = [drive.max_force_n_m] * len(drive.wheel_indices)
        slot = {index: i for i, index in enumerate(self.movable_indices)}
        self._wheel_slots = [slot[index] for index in drive.wheel_indices]
        covariance = self._odometry_covariance(drive)
        self.controller = DriveController(
            drive.geometry, drive.limits, 1.0 / config.physics_rate_hz,
            timeout_steps(config.cmd_vel_timeout_s, config.physics_rate_hz),
            len(drive.left_indices), len(drive.right_indices),
            config.wheel_velocity_sign, config.initial_pose, self._new_encoders(),
            covariance)
        self._set_wheels(self.controller.reset(self.world.step_count, self._wheel_positions()))

    def _new_encoders(self) -> Optional[Encoders]:
        """Return the wheel encoders odometry reads through, None when they are exact."""
        noise = self.config.noise('encoder')
        if noise.exact:
            return None
        return Encoders(noise, noise_generator(self.config.noise_seed, self.name, 'encoders'))

    def command(self, linear_x: float, angular_z: float, **other_axes: float) -> CommandVerdict:
        """Hand a Twist's fields to the drive controller; NO_WHEELS for a robot without wheels."""
        if self.controller is None:
            return NO_WHEELS
        return self.controller.command(linear_x, angular_z, **other_axes)

    def drive_wheels(self, step: int) -> None:
        """Before physics step ``step``: turn the latest command into wheel motor targets."""
        controller = self.controller
        if controller is not None:
            targets = controller.update(step)
            factor = self._battery_speed_factor()
            if factor != self._speed_factor:  # the battery ran out, or was charged again
                self._speed_factor = factor
                targets = controller.joint_targets()
            if targets is not None:
                self._set_wheels(targets if factor == 1.0 else [factor * t for t in targets])

    def _battery_speed_factor(self) -> float:
        """Return the fraction of their targets the wheels get: 1 unless the battery is empty."""
        battery = self.battery
        if battery is None or not battery.empty:
            return 1.0
        behaviour = self.config.battery_empty_behaviour
        return {'stop': 0.0, 'slow': self.config.battery_empty_speed}.get(behaviour, 1.0)

    def measure(self, step: int, time_ns: int, state_due: bool) -> Optional[Measurement]:
        """
        After physics step ``step``: measure what is due; None when nothing is.

        The state (and odometry) when ``state_due``, then each sensor at its
        own rate; whatever is measured, the base's whole state is checked first
        (and the joints, for a publication or the head camera), and the robot
        reset if it blew up. A step that measures nothing checks only the
        base's velocity, where a blow-up shows at once (one query, about 2 us,
        against 4 for the whole state).
        """
        if step < self._quiet_until and not state_due:
            problem = self.body.twist_problem()
            if problem is not None:
                self._recover(problem, time_ns)
            return None
        camera = self._camera_due is not None and self._camera_due.due(step)
        scan = self._scan_due is not None and self._scan_due.due(step)
        lidar = self._lidar_due is not None and self._lidar_due.due(step)
        imu = self._imu_due is not None and self._imu_due.due(step)
        battery = self._battery_due is not None and self._battery_due.due(step)
        self._quiet_until = min([schedule.next_step for schedule in self._schedules],
                                default=NEVER)
        sensing = camera or scan or lidar or imu
        frame = contacts = world = None
        if state_due:
            frame, world = self._read_frame(step, time_ns)
            if self.given_up:
                return None
            if self.config.publish_contacts:
                contacts = tuple(touching(self.world, self.body))
        elif battery and self.battery is not None:
            # The battery integrates over the steps since its last update, with the
            # wheels as they are now: its reading, stamped now, is of now. The readout
            # checks what the sensors' checks below would (and more).
            _, joints, base = self._read_body(time_ns)
            if self.given_up:
                return None
            self._run_battery(self.battery, step, joints, base)
        else:
            body = self.body
            if sensing:
                problem = body.state_problem()
                if problem is None and camera:  # the camera rides on the head's joint
                    indices = self.movable_indices
                    problem = body.joint_problem(indices, body.joint_states(indices))
            else:
                problem = body.twist_problem()
            if problem is not None:
                self._recover(problem, time_ns)
            if not sensing or self.given_up:
                return None
        self._pending = [(sensor, sensor.rays()) for sensor, due in (
            (self.laser, scan), (self.lidar, lidar)) if due and sensor is not None]
        return Measurement(
            time_ns, frame,
            self.camera.render(depth=self._camera_depth) if camera and self.camera else None,
            None,  # the scan and the lidar's points: once its rays are cast (take_rays)
            self.imu.read(time_ns / 1e9, world) if imu and self.imu else None,
            None,
            self.battery.reading() if battery and self.battery else None,
            contacts)

    def pending_rays(self) -> List[RayRequest]:
        """Return the rays the last :meth:`measure` left to cast (laser, then 3D lidar)."""
        return [request for _, request in self._pending]

    def take_rays(self, measurement: Measurement,
                  fractions: Sequence[numpy.ndarray]) -> Measurement:
        """Return ``measurement`` with the scan and the lidar's points from their rays' answers."""
        scan, lidar = measurement.scan, measurement.lidar
        for (sensor, _), answer in zip(self._pending, fractions):
            if isinstance(sensor, LaserScanner):
                scan = sensor.ranges(answer)
            else:
                lidar = sensor.points(answer)
        self._pending = []
        return measurement._replace(scan=scan, lidar=lidar)

    def read_frame(self, step: int, time_ns: int) -> Frame:
        """Read the robot once (resetting it first if the state is absurd); integrate odometry."""
        return self._read_frame(step, time_ns)[0]

    def _read_frame(self, step: int, time_ns: int) -> Tuple[Frame, BaseState]:
        """:meth:`read_frame`, and the base's state with its twist in the world (the IMU's)."""
        world, joints, base = self._read_body(time_ns)
        odometry = None
        if self.given_up:  # taken out of the world: no odometry or battery from absurd values
            return Frame(step, time_ns, joints, base, odometry), world
        if self.controller is not None:
            positions = joints.positions
            self.controller.update_odometry([positions[s] for s in self._wheel_slots], step)
            odometry = self.controller.odometry_state()
        if self.battery is not None:
            self._run_battery(self.battery, step, joints, base)
        return Frame(step, time_ns, joints, base, odometry), world

    def _read_body(self, time_ns: int) -> Tuple[BaseState, JointStates, BaseState]:
        """Read the base (in the world, its body frame) and joints; reset the robot if absurd."""
        body = self.body
        joints = body.joint_states(self.movable_indices)
        world = body.world_state()
        base = in_body_frame(world)
        problem = body.joint_problem(self.movable_indices, joints) or body.state_problem(base)
        if problem is not None:
            self._recover(problem, time_ns)
            if self.given_up:  # what it reads is absurd: nothing more is made of it
                return world, joints, base
            joints = body.joint_states(self.movable_indices)
            world = body.world_state()
            base = in_body_frame(world)
        return world, joints, base

    def _run_battery(self, battery: Battery, step: int, joints: JointStates,
                     base: BaseState) -> None:
        """Drain or charge the battery over the steps since its last update, by the wheels now."""
        slots = self._wheel_slots
        dt_s = (step - self._battery_step) * self._time_step_s
        self._battery_step = step
        velocity = base.linear_velocity
        battery.update(dt_s, [joints.efforts[s] for s in slots],
                       [joints.velocities[s] for s in slots],
                       (base.position[0], base.position[1], yaw_of(base.orientation)),
                       math.hypot(velocity[0], velocity[1]))

    def restart_time(self, steps_back: int) -> None:
        """Start the sensor rates afresh: the step count went back ``steps_back`` (a reset)."""
        step = self.world.step_count
        self._battery_step -= steps_back
        for schedule in self._schedules:
            schedule.restart(step)
        self._quiet_until = 0
        if self.controller is not None:
            self.controller.shift_time(-steps_back)
        if self.imu is not None:
            self.imu.reset()  # its time went back: no acceleration from the jump

    def restart_noise(self, config: Optional[SimConfig] = None) -> None:
        """
        Start every noise stream again from the seed, as at start-up (a full reset).

        With ``config``: the robot's settings with other noise settings or
        seed (nothing else may differ), taken from now on.
        """
        if config is not None:
            self.config = config
        for sensor in (self.laser, self.lidar, self.imu, self.camera):
            if sensor is not None:
                sensor.restart_noise(config)
        if self.controller is not None:
            # Fresh encoders counting on where the old ones left off, and a covariance
            # keeping the pose's: odometry goes on without a jump (put back by a reset
            # before or after this, it starts again from the wheels as they stand).
            self.controller.take_encoders(self._new_encoders(),
                                          self._odometry_covariance(self.drive))

    def _odometry_covariance(self, drive: Optional[DriveTrain]) -> Optional[OdometryCovariance]:
        """Return the odometry's covariance the encoders' noise gives; None when they are exact."""
        noise = self.config.noise('encoder')
        if noise.exact or drive is None:
            return None
        return OdometryCovariance(noise, drive.geometry.wheel_radius_m,
                                  drive.geometry.wheel_separation_m)

    def teleported(self) -> None:
        """Forget the motion so far: the body was placed, and the IMU must not read the jump."""
        self._fall_told = False
        if self.imu is not None:
            self.imu.reset()

    def check_fall(self, time_ns: int) -> None:
        """
        Say once, in one error line, that the robot fell more than FALLEN_DEPTH_M below z 0.

        Past the ground plane's edge it falls for ever, and every sensor goes on
        measuring; the physics is left as it is. Said again once it was put
        back (a reset, a teleport) and falls again. One query.
        """
        if self._fall_told or not self.body.com_pose()[0][2] < -FALLEN_DEPTH_M:
            return
        self._fall_told = True
        (x, y, z), _ = self.body.world_pose()
        off = self.world.off_ground(x, y)
        x, y = round(x, 1) + 0.0, round(y, 1) + 0.0  # no -0.0
        self._error(f'robot {self.name} is falling with nothing under it: at '
                    f't={time_ns / 1e9:.3f} s its base is at z {z:.1f} m, more than '
                    f'{FALLEN_DEPTH_M:g} m below z 0, at x {x:.1f}, y {y:.1f}'
                    + (f', {off}' if off is not None else '')
                    + '; it falls on until it is reset or moved')

    def reset(self) -> None:
        """Put the robot back at its initial pose at rest, dropping the command and odometry."""
        self.body.reset()
        self.reloaded()

    def reloaded(self) -> None:
        """
        Start again as at start-up: the body is at its initial pose (a rebuilt world, a reset).

        Drops the command and the IMU's last sample; odometry starts again
        at the initial pose and the wheel motors stop, as when it was built.
        """
        self._fall_told = False
        if self.imu is not None:
            self.imu.reset()
        if self.battery is not None:
            self.battery.reset()
            self._battery_step = self.world.step_count
            self._speed_factor = 1.0
        if self.controller is not None:
            self._set_wheels(self.controller.reset(self.world.step_count,
                                                   self._wheel_positions()))

    def close(self) -> None:
        """Give back what the robot holds in the world (its ray group) and close its files."""
        if self.ray_group is not None:
            self.world.release_ray_group(self.ray_group)
            self.ray_group = None
        for resource in self._resources:
            resource.close()
        self._resources.clear()

    def _recover(self, problem: str, time_ns: int) -> None:
        self.blow_ups += 1
        step, last = self.world.step_count, self._put_back_at
        in_a_row = last is not None and 0 <= step - last < CALM_S / self._time_step_s
        self._blow_ups_in_a_row = self._blow_ups_in_a_row + 1 if in_a_row else 1
        if self._blow_ups_in_a_row >= MAX_BLOW_UPS_IN_A_ROW:
            # Put back, it would blow up again: the simulation takes it out of the world.
            self.given_up = True
            self.world.blown_up = True  # what it broke around it is put back all the same
            back = '' if self.body.spawned else '; a full reset brings it back'
            self._error(f'physics blew up at t={time_ns / 1e9:.6f} s ({problem}), '
                        f'{self._blow_ups_in_a_row} times in a row within {CALM_S:g} s of '
                        f'being put back: the robot {self.name} is taken out of the world '
                        f'(deleted{back})')
            return
        self._put_back_at = step
        self._error(f'physics blew up at t={time_ns / 1e9:.6f} s ({problem}): '
                    f'resetting the robot {self.name} to its initial pose')
        # Loaded again, not reset in place: see SimWorld.put_back. What the blow-up broke
        # around it (the ground...) is put back after every robot's check of this step
        # (Simulation: SimWorld.repair).
        why = self.world.put_back(self.body)
        self.world.blown_up = True
        self.reloaded()
        if why is not None:
            self._error(f'the robot {self.name} is reset in place, not loaded again ({why}): '
                        'it may not stand on the ground')

    def _set_wheels(self, velocities: Sequence[float]) -> None:
        # Stopped, the wheels are braked: a velocity motor at 0 let R2D2 roll away slowly.
        if any(velocities):
            self.body.set_joint_velocities(self._wheel_indices, velocities,
                                           self._wheel_forces)
        else:
            self.body.hold_joints(self._wheel_indices, self._wheel_forces)

    def _wheel_positions(self) -> List[float]:
        return list(self.body.joint_states(self._wheel_indices).positions)
