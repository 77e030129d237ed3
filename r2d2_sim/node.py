"""
The ``r2d2_sim`` ROS 2 node: translation between ROS and the simulated world.

The node owns a :class:`~r2d2_sim.world.SimWorld` and advances it only when
asked (:meth:`SimNode.advance`); it has no timers of its own. ``main()`` paces
it against the wall clock in the main thread while an executor serves topics
and services in another, and tests can drive it step by step in-process.
"""

import difflib
import json
import math
import sys
import threading
import time
from typing import List, Optional, Sequence

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.clock import Clock as RclpyClock, ClockType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger

from r2d2_sim import camera
from r2d2_sim.parameters import (
    Bounds, ConfigError, Parameter as ParameterSpec, PARAMETERS, parse_config, SimConfig,
    WHEEL_FORCE, WHEEL_RADIUS, WHEEL_SEPARATION, WHEEL_VELOCITY)
from r2d2_sim.drive import (
    DiffDriveGeometry, DiffDriveOdometry, DriveConfigError, limit_twist, ramp_twist,
    twist_to_wheel_velocities, TwistLimits, yaw_to_quaternion)
from r2d2_sim.launcher import sim_node, stop_on_signals
from r2d2_sim.pacing import DeadlinePacer, exact_rate, StepSchedule
from r2d2_sim.world import ExtraModel, SimWorld, WorldError

NODE_NAME = 'r2d2_sim'
ROS_TYPES = {'double': Parameter.Type.DOUBLE, 'integer': Parameter.Type.INTEGER,
             'bool': Parameter.Type.BOOL, 'string': Parameter.Type.STRING,
             'double_array': Parameter.Type.DOUBLE_ARRAY,
             'string_array': Parameter.Type.STRING_ARRAY}
# Warnings about rejected commands repeat at most this often per kind of problem.
WARNING_PERIOD_S = 5.0
# How often (wall-clock seconds) to look for cmd_vel publishers of a wrong type.
GRAPH_CHECK_PERIOD_S = 1.0
CMD_VEL_TYPE = 'geometry_msgs/msg/Twist'
# The executor thread checks for a stop request at least this often (s).
SPIN_POLL_S = 0.1
# Follow the robot with the GUI camera this many times per simulated second.
GUI_CAMERA_RATE_HZ = 30.0
# The head camera: its link, image frame, clipping planes, and the gap between
# the link's bounding box and the lens (so the head itself is not in view).
HEAD_CAMERA_LINK = 'head'
HEAD_CAMERA_FRAME_ID = 'head_camera_optical'
HEAD_CAMERA_NEAR_M = 0.01
HEAD_CAMERA_FAR_M = 100.0
HEAD_CAMERA_CLEARANCE_M = 0.01


class StartupError(RuntimeError):
    """The node cannot start with the given parameters or files."""


def _describe_twist_problem(msg: Twist) -> Optional[str]:
    """Name what is wrong with a Twist (None if it is usable)."""
    values = (msg.linear.x, msg.linear.y, msg.linear.z,
              msg.angular.x, msg.angular.y, msg.angular.z)
    if any(math.isnan(v) for v in values):
        return 'NaN'
    if any(math.isinf(v) for v in values):
        return 'infinite value'
    return None


class SimNode(Node):
    """
    Simulates R2D2 in PyBullet and exposes it through standard ROS interfaces.

    Publishes ``joint_states``, ``odom`` (wheel odometry), ``ground_truth``,
    ``/clock``, the latched ``robot_description`` and, with ``camera_rate``,
    ``camera/image_raw`` and ``camera/camera_info``; subscribes ``cmd_vel``;
    serves ``~/get_joint_info``, ``~/pause``, ``~/step`` and ``~/reset``.
    Raises :class:`StartupError` when its parameters or URDF are unusable.
    """

    def __init__(self, node_name: str = NODE_NAME, **node_kwargs) -> None:
        super().__init__(node_name, **node_kwargs)
        self._lock = threading.RLock()
        self._warned_at = {}
        self.commands_received = 0
        self.commands_rejected = 0
        self.blow_ups = 0
        self._last_publish_step = 0
        self.world: Optional[SimWorld] = None
        try:
            self.config = self._declare_parameters()
            self._build_world()
        except (ConfigError, WorldError, DriveConfigError) as exc:
            if self.world is not None:
                self.world.close()
            raise StartupError(str(exc)) from exc
        self._build_interfaces()
        self._paused = self.config.start_paused
        self._publish_state()
        self._publish_description()

    # -- set-up ---------------------------------------------------------------

    def _declare_parameters(self) -> SimConfig:
        """
        Validate the overrides, then declare every parameter with its type and that value.

        Validation comes first so a wrong value or type is one ConfigError line
        (rclpy would raise its own exception for a type mismatch). The values
        are declared converted to the table's type (an integer given for a
        double becomes a double), so ``ros2 param describe`` shows the type.
        """
        overrides = getattr(self, '_parameter_overrides', {})
        raw = {spec.name: overrides[spec.name].value if spec.name in overrides else spec.default
               for spec in PARAMETERS}
        config = parse_config(raw)
        for spec in PARAMETERS:
            self._declare_typed(spec, raw[spec.name])
        self._warn_unknown_overrides()
        return config

    def _declare_typed(self, spec: ParameterSpec, value) -> None:
        ros_type = ROS_TYPES[spec.ros_type]
        descriptor = ParameterDescriptor(description=spec.description, read_only=True)
        bounds = spec.bounds
        if bounds is not None and bounds.zero is None and spec.ros_type == 'double':
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(bounds.low), to_value=float(bounds.high))]
        # The raw value passed validation: only its Python type may differ.
        convert = {'double': float, 'integer': int,
                   'double_array': lambda v: [float(x) for x in v],
                   'string_array': lambda v: list(v or [])}.get(spec.ros_type)
        if convert is not None:
            value = convert(value)
        if isinstance(value, list) and not value:
            # rclpy types an empty list as a byte array: declare the type, with no value.
            self.declare_parameter(spec.name, ros_type, descriptor, ignore_override=True)
        else:
            self.declare_parameter(spec.name, value, descriptor, ignore_override=True)

    def _warn_unknown_overrides(self) -> None:
        """Name parameters given on the command line or in a file that nothing reads."""
        # ROS ignores overrides nobody declares, so a typo would run on the default.
        overrides = getattr(self, '_parameter_overrides', {})
        known = list(self._parameters)
        for name in sorted(set(overrides) - set(known)):
            if name.startswith('qos_overrides.'):
                continue
            close = difflib.get_close_matches(name, known, n=1)
            hint = f' (did you mean {close[0]}?)' if close else ''
            self.get_logger().warning(f'ignoring unknown parameter {name}{hint}')

    def _build_world(self) -> None:
        config = self.config
        self.time_step_s = 1.0 / config.physics_rate_hz
        self.world = SimWorld(
            config.urdf or None, robot_description=config.robot_description,
            gui=config.gui, time_step_s=self.time_step_s,
            gravity_m_s2=config.gravity_m_s2, ground_plane=config.ground_plane,
            initial_pose=config.initial_pose,
            body_yaw_offset_rad=config.body_yaw_offset_rad,
            extra_models=[ExtraModel(name, position)
                          for name, position in config.extra_models])
        problem = self.world.state_problem()
        if problem is not None:
            raise ConfigError(f'the robot cannot start there: {problem}')
        self.robot_description = self.world.robot_description
        self.description_source = ('the robot_description parameter'
                                   if config.robot_description else self.world.urdf_path)
        self._movable = self.world.movable_joints()
        self._movable_indices = [j.index for j in self._movable]
        self._setup_wheels()
        rate = exact_rate(config.physics_rate_hz)
        self._step_ns_num, self._step_ns_den = 10**9 * rate.denominator, rate.numerator
        self._publish_schedule = StepSchedule(config.physics_rate_hz, config.publish_rate_hz)
        timeout_steps = config.cmd_vel_timeout_s * config.physics_rate_hz
        # A timeout beyond any run (1e308 s) is as good as none: 0 disables it.
        self._timeout_steps = math.ceil(timeout_steps) if timeout_steps < 2.0**62 else 0
        self.steps_per_gui_frame = gui_frame_steps(config)
        self._setup_head_camera()

    def _setup_head_camera(self) -> None:
        config = self.config
        self.head_camera_enabled = config.camera_rate_hz > 0.0
        if not self.head_camera_enabled:
            return
        try:
            self._head_link = self.world.link_index(HEAD_CAMERA_LINK)
        except WorldError as exc:
            raise ConfigError(f'camera_rate > 0 needs a link named {HEAD_CAMERA_LINK!r}: '
                              f'{exc}') from None
        self._head_lens_offset_m = (self.world.link_half_extent_m(self._head_link)
                                    + HEAD_CAMERA_CLEARANCE_M)
        width, height, fov = (config.camera_width_px, config.camera_height_px,
                              config.camera_fov_deg)
        self.head_camera_intrinsics = camera.intrinsics(width, height, fov)
        self._head_projection = camera.projection_matrix(
            width, height, fov, HEAD_CAMERA_NEAR_M, HEAD_CAMERA_FAR_M)
        self._image_schedule = StepSchedule(config.physics_rate_hz, config.camera_rate_hz)

    def _setup_wheels(self) -> None:
        config, world = self.config, self.world
        names = config.left_wheel_names + config.right_wheel_names
        missing = [n for n in names if n not in world.joints]
        if names and len(missing) == len(names) and config.wheel_names_are_default:
            self.get_logger().warning(
                f'{self.description_source} has none of the default wheel joints: '
                'cmd_vel is ignored')
            names = ()
        elif missing:
            raise ConfigError(
                f'wheel joint(s) {", ".join(missing)} not in the URDF; it has: '
                f'{", ".join(world.joints)}')
        elif not names:
            wheels = [j.name for j in world.joints.values()
                      if j.type_name == 'revolute' and 'wheel' in j.name.lower()]
            if wheels:
                raise ConfigError(
                    'left_wheel_names and right_wheel_names are empty, but the robot drives '
                    f'on wheel joints {", ".join(wheels)}: list them as left and right wheels')
        self.has_wheels = bool(names)
        self._pending_command = None
        self._command_step = 0
        self.target_twist = (0.0, 0.0)
        self.ramped_twist = (0.0, 0.0)
        self._wheel_targets = (0.0, 0.0)
        if not self.has_wheels:
            self.geometry = None
            self.odometry = None
            return
        wheels = [world.joint(n) for n in names]
        for wheel in wheels:
            if wheel.type_name != 'revolute':
                raise ConfigError(f'wheel joint {wheel.name} is {wheel.type_name}, '
                                  'not a revolute/continuous joint')
        self._left = [world.joint(n).index for n in config.left_wheel_names]
        self._right = [world.joint(n).index for n in config.right_wheel_names]
        self._wheel_indices = self._left + self._right
        # Where the wheels sit in the joint_states readout, which odometry reuses.
        movable_slot = {index: slot for slot, index in enumerate(self._movable_indices)}
        self._wheel_slots = [movable_slot[index] for index in self._wheel_indices]
        world.set_wheel_lateral_friction(self._wheel_indices, config.wheel_lateral_friction_ratio)
        radius = config.wheel_radius_m or _from_urdf(
            'wheel_radius', world.wheel_radius_m(self._left[0]), WHEEL_RADIUS)
        separation = config.wheel_separation_m or _from_urdf(
            'wheel_separation', self._derive_separation(), WHEEL_SEPARATION)
        urdf_velocity = min(w.max_velocity for w in wheels)
        urdf_force = min(w.max_force for w in wheels)
        if not urdf_velocity > 0.0 and not config.max_wheel_velocity_rad_s:
            raise ConfigError(
                'the URDF gives the wheels no velocity limit: set max_wheel_velocity')
        if not urdf_force > 0.0 and not config.max_wheel_force_n_m:
            raise ConfigError('the URDF gives the wheels no effort limit: set max_wheel_force')
        max_velocity = config.max_wheel_velocity_rad_s or _from_urdf(
            'max_wheel_velocity', urdf_velocity, WHEEL_VELOCITY)
        max_force = config.max_wheel_force_n_m or _from_urdf(
            'max_wheel_force', urdf_force, WHEEL_FORCE)
        self.geometry = DiffDriveGeometry(
            wheel_radius_m=radius,
            wheel_separation_m=separation * config.wheel_separation_multiplier,
            max_wheel_velocity_rad_s=max_velocity)
        self.limits = TwistLimits(
            max_linear_m_s=config.max_linear_velocity_m_s,
            max_angular_rad_s=config.max_angular_velocity_rad_s,
            max_linear_acceleration_m_s2=config.max_linear_acceleration_m_s2,
            max_angular_acceleration_rad_s2=config.max_angular_acceleration_rad_s2)
        x, y, yaw = config.initial_pose
        self.odometry = DiffDriveOdometry(self.geometry, x, y, yaw)
        self._wheel_forces = [max_force] * len(self._wheel_indices)
        self._apply_wheel_targets(0.0, 0.0)
        self._odometry_step = 0
        self._update_odometry(self._read_wheel_positions())

    def _derive_separation(self) -> float:
        """Track width: distance along base y between the left and right wheel centres."""
        positions = self.world.link_positions_in_base(self._left + self._right)
        left_y = [p[1] for p in positions[:len(self._left)]]
        right_y = [p[1] for p in positions[len(self._left):]]
        separation = sum(left_y) / len(left_y) - sum(right_y) / len(right_y)
        if separation <= 0.0:
            raise ConfigError(
                f'left wheels are not to the left of the right wheels (track {separation:.3f} m '
                'along base y): check left_wheel_names/right_wheel_names')
        return separation

    def _build_interfaces(self) -> None:
        state_qos = QoSProfile(depth=10)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        self._joint_pub = self.create_publisher(JointState, 'joint_states', state_qos)
        self._odom_pub = self.create_publisher(Odometry, 'odom', state_qos)
        self._truth_pub = self.create_publisher(Odometry, 'ground_truth', state_qos)
        self._clock_pub = self.create_publisher(Clock, '/clock', state_qos)
        self._description_pub = self.create_publisher(String, 'robot_description', latched)
        self.create_subscription(Twist, 'cmd_vel', self._on_cmd_vel, 10)
        # The middleware never delivers a publisher of another type (say
        # TwistStamped) on cmd_vel; look at the graph now and then to say so.
        self.create_timer(GRAPH_CHECK_PERIOD_S, self._check_cmd_vel_publishers,
                          clock=RclpyClock(clock_type=ClockType.STEADY_TIME))
        self.create_service(Trigger, '~/get_joint_info', self._on_get_joint_info)
        self.create_service(SetBool, '~/pause', self._on_pause)
        self.create_service(Trigger, '~/step', self._on_step)
        self.create_service(Trigger, '~/reset', self._on_reset)

        config = self.config
        self._joint_msg = JointState()
        self._joint_msg.name = [j.name for j in self._movable]
        self._odom_msg = Odometry()
        self._odom_msg.header.frame_id = config.odom_frame_id
        self._odom_msg.child_frame_id = config.base_frame_id
        for i, variance in enumerate(config.pose_covariance_diagonal):
            self._odom_msg.pose.covariance[7 * i] = variance
        for i, variance in enumerate(config.twist_covariance_diagonal):
            self._odom_msg.twist.covariance[7 * i] = variance
        self._truth_msg = Odometry()
        self._truth_msg.header.frame_id = config.world_frame_id
        self._truth_msg.child_frame_id = config.base_frame_id
        self._clock_msg = Clock()
        if self.head_camera_enabled:
            self._build_camera_interfaces()

    def _build_camera_interfaces(self) -> None:
        camera_qos = QoSProfile(depth=2)
        self._image_pub = self.create_publisher(Image, 'camera/image_raw', camera_qos)
        self._camera_info_pub = self.create_publisher(CameraInfo, 'camera/camera_info',
                                                      camera_qos)
        k = self.head_camera_intrinsics
        self._image_msg = Image(height=k.height_px, width=k.width_px, encoding='rgb8',
                                is_bigendian=0, step=3 * k.width_px)
        self._image_msg.header.frame_id = HEAD_CAMERA_FRAME_ID
        info = CameraInfo(height=k.height_px, width=k.width_px, distortion_model='plumb_bob')
        info.header.frame_id = HEAD_CAMERA_FRAME_ID
        info.d = [0.0] * 5
        info.k = k.k
        info.r = camera.IDENTITY_3X3
        info.p = k.p
        self._camera_info_msg = info

    # -- time -----------------------------------------------------------------

    @property
    def step_count(self) -> int:
        """Return the number of physics steps taken since start."""
        return self.world.step_count

    @property
    def sim_time_ns(self) -> int:
        """Return simulated time in integer nanoseconds (exact, no drift)."""
        return self.world.step_count * self._step_ns_num // self._step_ns_den

    def steps_to_next_publish(self) -> int:
        """Return the number of physics steps until the next state publication."""
        return self._publish_schedule.next_step - self.world.step_count

    @property
    def paused(self) -> bool:
        """Return True while physics is stopped."""
        return self._paused

    # -- stepping -------------------------------------------------------------

    def advance(self, steps: int = 1) -> None:
        """
        Step the physics ``steps`` times, applying commands and publishing on schedule.

        This is the in-process API for tests: it ignores pause and pacing, so a
        test can advance simulated time deterministically between its own spins.
        """
        with self._lock:
            world = self.world
            for _ in range(steps):
                if self.has_wheels:
                    self._update_command()
                world.step(1)
                step = world.step_count
                if self._publish_schedule.due(step):
                    self._publish_state(*self._checked_state())
                else:
                    problem = world.state_problem()
                    if problem is not None:
                        self._recover(problem)
                if self.head_camera_enabled and self._image_schedule.due(step):
                    self._publish_head_camera()
                if world.gui and step % self.steps_per_gui_frame == 0:
                    world.follow_camera()

    def advance_to_next_publish(self) -> int:
        """Advance one control period: to and including the next publication."""
        steps = self.steps_to_next_publish()
        self.advance(steps)
        return steps

    def advance_if_running(self, steps: Optional[int] = None) -> bool:
        """
        Advance ``steps`` (default: one control period) unless paused; return whether it did.

        The check and the steps hold the lock that ``~/pause`` takes, so once a
        pause is answered no further step runs and the reply's time is final.
        """
        with self._lock:
            if self._paused:
                return False
            if steps is None:
                self.advance_to_next_publish()
            else:
                self.advance(steps)
            return True

    def _update_command(self) -> None:
        """Take a new command (or the timeout's stop) and ramp the wheels towards it."""
        pending = self._pending_command
        step = self.world.step_count
        if pending is not None:
            self._pending_command = None
            self._command_step = step
            self.target_twist = pending
        elif (self._timeout_steps and self.target_twist != (0.0, 0.0)
              and step - self._command_step >= self._timeout_steps):
            self.target_twist = (0.0, 0.0)
        if self.ramped_twist != self.target_twist:
            self.ramped_twist = ramp_twist(self.ramped_twist, self.target_twist, self.limits,
                                           self.time_step_s)
            self._apply_wheel_targets(
                *twist_to_wheel_velocities(self.geometry, *self.ramped_twist))

    def _apply_wheel_targets(self, left: float, right: float) -> None:
        self._wheel_targets = (left, right)
        sign = self.config.wheel_velocity_sign
        velocities = [sign * left] * len(self._left) + [sign * right] * len(self._right)
        self.world.set_joint_velocities(self._wheel_indices, velocities, self._wheel_forces)

    def _checked_state(self):
        """Read the joints and the base for a publication; reset the robot if they are absurd."""
        world = self.world
        states = world.joint_states(self._movable_indices)
        base = world.base_state()
        problem = (world.joint_problem(self._movable_indices, states)
                   or world.state_problem(base))
        if problem is not None:
            self._recover(problem)
            states = world.joint_states(self._movable_indices)
            base = world.base_state()
        return states, base

    def _recover(self, problem: str) -> None:
        """Reset the robot to its initial pose after the physics produced an absurd state."""
        self.blow_ups += 1
        self._log_throttled(
            'blow-up', self.get_logger().error,
            f'physics blew up at t={self.sim_time_ns / 1e9:.6f} s ({problem}): '
            'resetting the robot to its initial pose')
        self._reset_locked(publish=False)

    # -- publishing -----------------------------------------------------------

    def _read_wheel_positions(self) -> List[float]:
        """Query the wheel encoders (left wheels, then right) outside a publication."""
        return list(self.world.joint_states(self._wheel_indices).positions)

    def _update_odometry(self, wheel_positions: Sequence[float]) -> None:
        """Integrate odometry from wheel angles ordered as ``_wheel_indices``."""
        step = self.world.step_count
        n_left = len(self._left)
        sign = self.config.wheel_velocity_sign
        left = sign * sum(wheel_positions[:n_left]) / n_left
        right = sign * sum(wheel_positions[n_left:]) / (len(wheel_positions) - n_left)
        dt = (step - self._odometry_step) * self.time_step_s
        self.odometry.update_from_positions(left, right, dt)
        self._odometry_step = step

    def _publish_state(self, states=None, base=None) -> None:
        self._last_publish_step = self.world.step_count
        ns = self.sim_time_ns
        sec, nanosec = divmod(ns, 10**9)
        self._clock_msg.clock.sec = sec
        self._clock_msg.clock.nanosec = nanosec
        self._clock_pub.publish(self._clock_msg)

        if states is None:
            states = self.world.joint_states(self._movable_indices)
        msg = self._joint_msg
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
        msg.position = states.positions
        msg.velocity = states.velocities
        msg.effort = states.efforts
        self._joint_pub.publish(msg)

        if base is None:
            base = self.world.base_state()
        truth = self._truth_msg
        truth.header.stamp.sec, truth.header.stamp.nanosec = sec, nanosec
        pose = truth.pose.pose
        pose.position.x, pose.position.y, pose.position.z = base.position
        (pose.orientation.x, pose.orientation.y, pose.orientation.z,
         pose.orientation.w) = base.orientation
        twist = truth.twist.twist
        twist.linear.x, twist.linear.y, twist.linear.z = base.linear_velocity
        twist.angular.x, twist.angular.y, twist.angular.z = base.angular_velocity
        self._truth_pub.publish(truth)

        if self.has_wheels:
            positions = states.positions
            self._update_odometry([positions[slot] for slot in self._wheel_slots])
            odom = self._odom_msg
            odometry = self.odometry
            odom.header.stamp.sec, odom.header.stamp.nanosec = sec, nanosec
            pose = odom.pose.pose
            pose.position.x, pose.position.y = odometry.x_m, odometry.y_m
            (pose.orientation.x, pose.orientation.y, pose.orientation.z,
             pose.orientation.w) = yaw_to_quaternion(odometry.yaw_rad)
            odom.twist.twist.linear.x = odometry.linear_m_s
            odom.twist.twist.angular.z = odometry.angular_rad_s
            self._odom_pub.publish(odom)

    def render_head_camera(self) -> bytes:
        """Render the head camera now (camera_rate > 0): rgb8 rows, top row first."""
        world = self.world
        position, orientation = world.link_pose(self._head_link)
        forward, up = camera.link_camera_axes(orientation, world.body_yaw_offset_rad)
        offset = self._head_lens_offset_m
        eye = [position[i] + offset * forward[i] for i in range(3)]
        k = self.head_camera_intrinsics
        return world.render_rgb(k.width_px, k.height_px, camera.view_matrix(eye, forward, up),
                                self._head_projection)

    def _publish_head_camera(self) -> None:
        sec, nanosec = divmod(self.sim_time_ns, 10**9)
        image = self._image_msg
        image.header.stamp.sec, image.header.stamp.nanosec = sec, nanosec
        image.data = self.render_head_camera()
        self._image_pub.publish(image)
        info = self._camera_info_msg
        info.header.stamp.sec, info.header.stamp.nanosec = sec, nanosec
        self._camera_info_pub.publish(info)

    def _publish_description(self) -> None:
        self._description_pub.publish(String(data=self.robot_description))

    # -- callbacks ------------------------------------------------------------

    def _log_throttled(self, kind: str, log, text: str) -> None:
        """Log ``text`` with ``log`` at most once per WARNING_PERIOD_S for each kind."""
        now = time.monotonic()
        last, suppressed = self._warned_at.get(kind, (None, 0))
        if last is not None and now - last < WARNING_PERIOD_S:
            self._warned_at[kind] = (last, suppressed + 1)
            return
        extra = f' ({suppressed} more since the last one)' if suppressed else ''
        log(text + extra)
        self._warned_at[kind] = (now, 0)

    def _warn(self, kind: str, text: str) -> None:
        self._log_throttled(kind, self.get_logger().warning, text)

    def _on_cmd_vel(self, msg: Twist) -> None:
        self.commands_received += 1
        problem = _describe_twist_problem(msg)
        if problem is not None:
            self.commands_rejected += 1
            self._warn(f'cmd_vel {problem}',
                       f'rejected cmd_vel with {problem}; keeping the last valid command')
            return
        if not self.has_wheels:
            self._warn('cmd_vel no wheels',
                       'cmd_vel ignored: the robot has no wheels configured')
            return
        ignored = [name for name, value in (
            ('linear.y', msg.linear.y), ('linear.z', msg.linear.z),
            ('angular.x', msg.angular.x), ('angular.y', msg.angular.y)) if value != 0.0]
        if ignored:
            self._warn('cmd_vel ignored axes',
                       f'cmd_vel {", ".join(ignored)} ignored: a differential drive follows '
                       'linear.x and angular.z only')
        linear, angular = msg.linear.x, msg.angular.z
        limited = limit_twist(self.geometry, linear, angular, self.limits)
        if max(map(abs, limited)) < max(abs(linear), abs(angular)) * (1.0 - 1e-9):
            self._warn('cmd_vel clamped',
                       f'cmd_vel (linear.x {linear:.4g}, angular.z {angular:.4g}) exceeds '
                       f'the speed limits: scaled to ({limited[0]:.4g}, {limited[1]:.4g})')
        # Picked up by the physics loop at its next step (a single assignment,
        # so no lock is needed against the stepping thread).
        self._pending_command = limited

    def _check_cmd_vel_publishers(self) -> None:
        topic = self.resolve_topic_name('cmd_vel')
        for info in self.get_publishers_info_by_topic('cmd_vel'):
            if info.topic_type != CMD_VEL_TYPE:
                publisher = f'{info.node_namespace.rstrip("/")}/{info.node_name}'
                self._warn(f'cmd_vel type {info.topic_type}',
                           f'{publisher} publishes {info.topic_type} on {topic}, which ROS '
                           f'does not deliver: this node takes {CMD_VEL_TYPE}')

    def _on_get_joint_info(self, request, response):
        with self._lock:
            info = self.world.joint_info()
        response.success = True
        response.message = json.dumps({'robot': self.world.base_link_name,
                                       'urdf': self.description_source,
                                       'joints': info})
        return response

    def status(self, **facts) -> str:
        """
        Return the simulation's state as the JSON text the control services reply with.

        Keys: ``paused``, ``step`` (physics steps since start), ``sim_time_ns``
        and ``sim_time`` (s) of the last step, ``commands_received`` (cmd_vel
        messages taken so far, so a client can confirm its command arrived),
        plus the service's own ``facts`` (``steps`` advanced, an ``error``).
        """
        ns = self.sim_time_ns
        state = {'paused': self._paused, 'step': self.world.step_count, 'sim_time_ns': ns,
                 'sim_time': ns / 1e9, 'commands_received': self.commands_received}
        state.update(facts)
        return json.dumps(state)

    def _on_pause(self, request, response):
        with self._lock:  # no step runs between the change and the reply's time
            if request.data and not self._paused:
                # Stop where a client sees the state: finish the control period
                # up to the step that publishes, so the reply's time is the last
                # /clock and every ~/step after it is one whole period.
                if self.world.step_count != self._last_publish_step:
                    self.advance_to_next_publish()
            self._paused = bool(request.data)
            response.message = self.status()
        response.success = True
        return response

    def _on_step(self, request, response):
        with self._lock:
            if not self._paused:
                response.success = False
                response.message = self.status(
                    steps=0, error='the simulation is running: pause it (~/pause true) to step')
                return response
            steps = self.advance_to_next_publish()
            response.message = self.status(steps=steps)
        response.success = True
        return response

    def _on_reset(self, request, response):
        with self._lock:
            self._reset_locked()
            response.message = self.status()
        response.success = True
        return response

    def _reset_locked(self, publish: bool = True) -> None:
        self.world.reset()
        if self.has_wheels:
            self._pending_command = None
            self.target_twist = self.ramped_twist = (0.0, 0.0)
            self._apply_wheel_targets(0.0, 0.0)
            self.odometry.reset(*self.config.initial_pose)
            self._odometry_step = self.world.step_count
            self._update_odometry(self._read_wheel_positions())
        if publish:
            self._publish_state()

    def destroy_node(self) -> None:
        """Disconnect the physics client, then destroy the ROS node."""
        if self.world is not None:
            with self._lock:
                self.world.close()
        super().destroy_node()


def _from_urdf(name: str, value: float, bounds: Bounds) -> float:
    """Hold a value derived from the URDF to the bounds of the parameter that overrides it."""
    try:
        return bounds.check(name, value)
    except ConfigError:
        raise ConfigError(f'the URDF gives {name.replace("_", " ")} {value:g} {bounds.unit}, '
                          f'outside [{bounds.low:g}, {bounds.high:g}]: set {name}') from None


def gui_frame_steps(config: SimConfig) -> int:
    """Return the physics steps per GUI frame (camera follow, paced batches)."""
    return max(1, round(config.physics_rate_hz / GUI_CAMERA_RATE_HZ))


def run_paced(node: SimNode, stop: threading.Event) -> None:
    """
    Step ``node`` against the wall clock until ``stop`` is set.

    Real time (``real_time_factor`` > 0): one physics step per absolute
    deadline, or with a GUI one batch of steps per frame. As fast as
    possible: whole control periods back to back.
    """
    config = node.config
    rate = config.physics_rate_hz * config.real_time_factor
    # With a window, PyBullet renders whenever the client is idle and makes the
    # next call wait for that frame (measured under Xvfb: 6 s for 240 paced
    # steps). Stepping in batches, one per GUI frame, keeps real time.
    batch = node.steps_per_gui_frame if config.gui else 1
    pacer = DeadlinePacer(batch / rate) if rate > 0.0 else None
    while not stop.is_set():
        if not node.advance_if_running(None if pacer is None else batch):
            stop.wait(0.005)
            if pacer is not None:
                pacer.reanchor()
        elif pacer is not None:
            pacer.wait()


def main(args: Optional[Sequence[str]] = None,
         stop: Optional[threading.Event] = None) -> int:
    """
    Run the simulator node until SIGINT or SIGTERM, or until ``stop`` is set.

    Returns the exit status: 0 after a stop request, 2 when the node cannot
    start. ``stop`` defaults to a new event set by SIGINT and SIGTERM.
    """
    if stop is None:
        stop = stop_on_signals()
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # rclpy reports bad --ros-args as assorted errors
        print(f'{NODE_NAME}: error: cannot initialise ROS: {exc}', file=sys.stderr)
        return 2
    if stop.is_set():  # stopped while rclpy and PyBullet were still loading
        rclpy.try_shutdown()
        return 0
    node = None
    executor = SingleThreadedExecutor()
    spinner = None
    try:
        node = SimNode()
        executor.add_node(node)
        spinner = threading.Thread(target=_spin, args=(executor, stop), daemon=True)
        spinner.start()
        node.get_logger().info(
            f'simulating {node.description_source} at {node.config.physics_rate_hz:g} Hz, '
            f'real time factor {node.config.real_time_factor:g}'
            + (', paused' if node.paused else ''))
        run_paced(node, stop)
        return 0
    except StartupError as exc:
        print(f'{NODE_NAME}: error: {exc}', file=sys.stderr)
        return 2
    finally:
        stop.set()
        if spinner is not None:
            spinner.join(timeout=1.0)
        # Only now, with no thread spinning: shutting an executor down under a
        # spinning thread races in rclpy 7.1 (a callback handler made during
        # shutdown fails with AttributeError on the destroyed guard condition).
        executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


def _spin(executor, stop: threading.Event) -> None:
    """Serve callbacks until ``stop`` is set (checked at least every SPIN_POLL_S)."""
    try:
        while not stop.is_set():
            executor.spin_once(timeout_sec=SPIN_POLL_S)
    except ExternalShutdownException:
        pass
    finally:
        stop.set()


if __name__ == '__main__':
    sim_node()
