"""
One driven robot in the world: its body, drive train and controller, its sensors and their rates.

No ROS here. A :class:`Robot` takes commands (:meth:`Robot.command`), turns
the latest into wheel motor targets before each physics step
(:meth:`Robot.drive`), and after the step measures what is due
(:meth:`Robot.measure`): its state for a publication (joints, base, wheel
odometry, and with ``publish_contacts`` what it touches) and each sensor at
its own rate. Measurements are plain data in a
:class:`Measurement`; a robot whose physics blew up is put back where it
started, alone.
"""

from typing import Callable, List, NamedTuple, Optional, Sequence, Tuple

import numpy

from r2d2_sim.physics.body import Body
from r2d2_sim.model.transforms import BaseState
from r2d2_sim.physics.records import JointRecord, JointStates
from r2d2_sim.model.drive_controller import (
    CommandVerdict, DriveController, NO_WHEELS, timeout_steps)
from r2d2_sim.sim.drive_train import DriveTrain, find_drive_train
from r2d2_sim.model.kinematics import OdometryState
from r2d2_sim.sim.oracles import Touch, touching
from r2d2_sim.sim.parameters import ConfigError, SimConfig
from r2d2_sim.sim.sensor_mounts import CameraImage, HeadCamera, ImuSensor, LaserScanner
from r2d2_sim.model.sensors import ImuReading
from r2d2_sim.model.timing import stamp_of, StepSchedule
from r2d2_sim.physics.world import SimWorld, SPAWN_CLEARANCE_M

__all__ = ['Frame', 'Measurement', 'Robot', 'DriveTrain']


class Frame(NamedTuple):
    """A robot's state after one physics step, read once for every output of that step."""

    step: int
    time_ns: int
    joints: JointStates                  # the movable joints, in joint index order
    base: BaseState                      # true pose of the body frame, its twist in that frame
    odometry: Optional[OdometryState]    # wheel odometry (None without wheels)

    @property
    def stamp(self):
        """Return (sec, nanosec) of the frame's simulated time."""
        return stamp_of(self.time_ns)


class Measurement(NamedTuple):
    """What one robot measured at one step: each field None unless due then."""

    time_ns: int
    frame: Optional[Frame]               # the state, when a state publication is due
    image: Optional[CameraImage]         # the head camera, at camera_rate
    scan: Optional[numpy.ndarray]        # REP-117 ranges (float32), at scan_rate
    imu: Optional[ImuReading]            # at imu_rate
    # With publish_contacts, what the robot touches, beside each frame (empty: nothing).
    contacts: Optional[Tuple[Touch, ...]] = None


def _ignore(text: str) -> None:
    pass


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
        self._error = error
        self._resources = list(resources)
        self.laser: Optional[LaserScanner] = None
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
        self._wheel_forces: List[float] = []
        self._wheel_slots: List[int] = []  # where the wheels sit in the joint readout
        if self.drive is not None:
            self._build_controller(self.drive)
        rate, step = config.physics_rate_hz, world.step_count
        self.camera = HeadCamera(world, body, config) if config.camera_rate_hz else None
        self.laser = (LaserScanner(world, body, config, self.footprint_height_m)
                      if config.scan_rate_hz else None)
        self.imu = ImuSensor(body, config) if config.imu_rate_hz else None
        self._camera_due = StepSchedule(rate, config.camera_rate_hz, step) if self.camera else None
        self._scan_due = StepSchedule(rate, config.scan_rate_hz, step) if self.laser else None
        self._imu_due = StepSchedule(rate, config.imu_rate_hz, step) if self.imu else None
        self._time_step_s = 1.0 / rate

    def _build_controller(self, drive: DriveTrain) -> None:
        config = self.config
        self.body.set_wheel_lateral_friction(drive.wheel_indices,
                                             config.wheel_lateral_friction_ratio)
        self._wheel_forces = [drive.max_force_n_m] * len(drive.wheel_indices)
        slot = {index: i for i, index in enumerate(self.movable_indices)}
        self._wheel_slots = [slot[index] for index in drive.wheel_indices]
        self.controller = DriveController(
            drive.geometry, drive.limits, 1.0 / config.physics_rate_hz,
            timeout_steps(config.cmd_vel_timeout_s, config.physics_rate_hz),
            len(drive.left_indices), len(drive.right_indices),
            config.wheel_velocity_sign, config.initial_pose)
        self._set_wheels(self.controller.reset(self.world.step_count, self._wheel_positions()))

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
            if targets is not None:
                self._set_wheels(targets)

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
        camera = self._camera_due is not None and self._camera_due.due(step)
        scan = self._scan_due is not None and self._scan_due.due(step)
        imu = self._imu_due is not None and self._imu_due.due(step)
        frame = contacts = None
        if state_due:
            frame = self.read_frame(step, time_ns)
            if self.config.publish_contacts:
                contacts = tuple(touching(self.world, self.body))
        else:
            body = self.body
            if camera or scan or imu:
                problem = body.state_problem()
                if problem is None and camera:  # the camera rides on the head's joint
                    indices = self.movable_indices
                    problem = body.joint_problem(indices, body.joint_states(indices))
            else:
                problem = body.twist_problem()
            if problem is not None:
                self._recover(problem, time_ns)
            if not (camera or scan or imu):
                return None
        return Measurement(
            time_ns, frame,
            self.camera.render(depth=self.config.camera_depth) if camera else None,
            self.laser.scan() if scan else None,
            self.imu.read(time_ns / 1e9) if imu else None, contacts)

    def read_frame(self, step: int, time_ns: int) -> Frame:
        """Read the robot once (resetting it first if the state is absurd); integrate odometry."""
        body = self.body
        joints = body.joint_states(self.movable_indices)
        base = body.base_state()
        problem = body.joint_problem(self.movable_indices, joints) or body.state_problem(base)
        if problem is not None:
            self._recover(problem, time_ns)
            joints = body.joint_states(self.movable_indices)
            base = body.base_state()
        odometry = None
        if self.controller is not None:
            positions = joints.positions
            self.controller.update_odometry([positions[s] for s in self._wheel_slots], step)
            odometry = self.controller.odometry.state()
        return Frame(step, time_ns, joints, base, odometry)

    def restart_time(self, steps_back: int) -> None:
        """Start the sensor rates afresh: the step count went back ``steps_back`` (a reset)."""
        step = self.world.step_count
        for schedule in (self._camera_due, self._scan_due, self._imu_due):
            if schedule is not None:
                schedule.restart(step)
        if self.controller is not None:
            self.controller.shift_time(-steps_back)
        if self.imu is not None:
            self.imu.reset()  # its time went back: no acceleration from the jump

    def restart_noise(self) -> None:
        """Start the laser's and the IMU's noise streams again from the seed (a full reset)."""
        for sensor in (self.laser, self.imu):
            if sensor is not None:
                sensor.restart_noise()

    def teleported(self) -> None:
        """Forget the motion so far: the body was placed, and the IMU must not read the jump."""
        if self.imu is not None:
            self.imu.reset()

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
        if self.imu is not None:
            self.imu.reset()
        if self.controller is not None:
            self._set_wheels(self.controller.reset(self.world.step_count,
                                                   self._wheel_positions()))

    def close(self) -> None:
        """Give back what the robot holds in the world (its ray group) and close its files."""
        if self.laser is not None:
            self.laser.close()
        for resource in self._resources:
            resource.close()
        self._resources.clear()

    def _recover(self, problem: str, time_ns: int) -> None:
        self.blow_ups += 1
        self._error(f'physics blew up at t={time_ns / 1e9:.6f} s ({problem}): '
                    f'resetting the robot {self.name} to its initial pose')
        self.reset()

    def _set_wheels(self, velocities: Sequence[float]) -> None:
        self.body.set_joint_velocities(self.drive.wheel_indices, velocities, self._wheel_forces)

    def _wheel_positions(self) -> List[float]:
        return list(self.body.joint_states(self.drive.wheel_indices).positions)
