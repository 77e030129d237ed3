"""
The node's published outputs: one small class per published thing.

State outputs (clock, joint states, odometry, ground truth, TF) publish from
the :class:`~r2d2_sim.simulation.Frame` that the simulation reads once per
state publication. Sensor outputs (camera, scan, IMU) have their own rates:
the simulation says when they are due, and they measure then. Each keeps its
message serialized once (:class:`~r2d2_sim.serialization.MessageTemplate`),
patches only the bytes that move and publishes the bytes: rclpy then skips
the Python-to-C conversion and serialization (an Odometry: 11-21 us typed,
2-9 us as bytes, measured here). The camera's images are typed messages: a
render costs milliseconds, so the conversion does not matter there.
"""

from typing import List, Optional, Sequence, Tuple

from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState, LaserScan

from r2d2_sim import camera
from r2d2_sim.kinematics import yaw_to_quaternion
from r2d2_sim.parameters import ConfigError, SimConfig
from r2d2_sim.robot import (
    HEAD_CAMERA_FRAME_ID, HeadCamera, IMU_FRAME_ID, ImuSensor, LASER_FRAME_ID, LaserScanner)
from r2d2_sim.serialization import MessageTemplate
from r2d2_sim.simulation import Frame, Simulation
from r2d2_sim.transforms import (
    compose, IDENTITY, inverse, LinkTransforms, split_yaw, Transform)
from r2d2_sim.world import JointRecord

# Reliable with a modest queue: default subscribers and sensor-data (best
# effort) subscribers both match it.
STATE_QOS = QoSProfile(depth=10)
CAMERA_QOS = QoSProfile(depth=2)
SENSOR_QOS = QoSProfile(depth=5)
# As tf2's TransformBroadcaster and StaticTransformBroadcaster set them.
TF_QOS = QoSProfile(depth=100)
TF_STATIC_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class ClockOutput:
    """``/clock``: the frame's simulated time."""

    def __init__(self, node: Node) -> None:
        self._publisher = node.create_publisher(Clock, '/clock', STATE_QOS)
        self._template = MessageTemplate(Clock())
        self._clock = self._template.stamp('clock')

    def publish(self, frame: Frame) -> None:
        """Publish the frame's time."""
        self._clock.set(*frame.stamp)
        self._publisher.publish(self._template.to_bytes())


class JointStateOutput:
    """``joint_states``: position, velocity and applied effort of every movable joint."""

    def __init__(self, node: Node, joints: Sequence[JointRecord]) -> None:
        self._publisher = node.create_publisher(JointState, 'joint_states', STATE_QOS)
        zeros = [0.0] * len(joints)
        self._template = MessageTemplate(JointState(
            name=[j.name for j in joints], position=zeros, velocity=zeros, effort=zeros))
        self._stamp = self._template.stamp()
        # A robot without movable joints publishes empty arrays: nothing to patch.
        self._arrays = [self._template.field(name) for name in ('position', 'velocity', 'effort')
                        ] if joints else []

    def publish(self, frame: Frame) -> None:
        """Publish the frame's joint readout."""
        self._stamp.set(*frame.stamp)
        joints = frame.joints
        for slot, values in zip(self._arrays,
                                (joints.positions, joints.velocities, joints.efforts)):
            slot.set(values)
        self._publisher.publish(self._template.to_bytes())


class _OdometryTemplate:
    """An Odometry message whose stamp, pose (7 numbers) and twist (6) are patched."""

    def __init__(self, msg: Odometry) -> None:
        self.template = MessageTemplate(msg)
        self.stamp = self.template.stamp()
        self.pose = self.template.field('pose.pose')    # x y z, qx qy qz qw
        self.twist = self.template.field('twist.twist')  # vx vy vz, wx wy wz


class GroundTruthOutput:
    """``ground_truth``: the true pose of the body frame in the world, its twist in the body."""

    def __init__(self, node: Node, config: SimConfig) -> None:
        self._publisher = node.create_publisher(Odometry, 'ground_truth', STATE_QOS)
        msg = Odometry()
        msg.header.frame_id = config.world_frame_id
        msg.child_frame_id = config.frame(config.base_frame_id)
        self._msg = _OdometryTemplate(msg)

    def publish(self, frame: Frame) -> None:
        """Publish the frame's true base state."""
        msg, base = self._msg, frame.base
        msg.stamp.set(*frame.stamp)
        msg.pose.set(base.position + base.orientation)
        msg.twist.set(base.linear_velocity + base.angular_velocity)
        self._publisher.publish(msg.template.to_bytes())


class OdometryOutput:
    """
    ``odom``: wheel odometry, the body frame's pose in the odom frame and its twist in the body.

    The pose's z is the body frame's height at rest, as TF has it (odom ->
    base_footprint on the ground, base_footprint -> base_link above it), so
    the message and the transform tree agree on where base_link is.
    """

    def __init__(self, node: Node, config: SimConfig, simulation: Simulation) -> None:
        self._publisher = node.create_publisher(Odometry, 'odom', STATE_QOS)
        msg = Odometry()
        msg.header.frame_id = config.frame(config.odom_frame_id)
        msg.child_frame_id = config.frame(config.base_frame_id)
        for i, variance in enumerate(config.pose_covariance_diagonal):
            msg.pose.covariance[7 * i] = variance
        for i, variance in enumerate(config.twist_covariance_diagonal):
            msg.twist.covariance[7 * i] = variance
        self._msg = _OdometryTemplate(msg)
        self._height_m = simulation.footprint_height_m

    def publish(self, frame: Frame) -> None:
        """Publish the frame's wheel odometry."""
        msg, odometry = self._msg, frame.odometry
        msg.stamp.set(*frame.stamp)
        msg.pose.set((odometry.x_m, odometry.y_m, self._height_m)
                     + yaw_to_quaternion(odometry.yaw_rad))
        msg.twist.set((odometry.linear_m_s, 0.0, 0.0, 0.0, 0.0, odometry.angular_rad_s))
        self._publisher.publish(msg.template.to_bytes())


class HeadCameraOutput:
    """
    ``camera/image_raw`` (rgb8) and ``camera/camera_info`` at ``camera_rate``.

    With ``camera_depth``, also ``camera/depth/image_raw`` (32FC1, metres along
    the optical axis, REP-118) and ``camera/depth/camera_info`` from the same
    render, so depth and colour pixels line up.
    """

    def __init__(self, node: Node, config: SimConfig, head_camera: HeadCamera) -> None:
        self._camera = head_camera
        k = head_camera.intrinsics
        frame_id = config.frame(HEAD_CAMERA_FRAME_ID)
        self._image_pub = node.create_publisher(Image, 'camera/image_raw', CAMERA_QOS)
        self._info_pub = node.create_publisher(CameraInfo, 'camera/camera_info', CAMERA_QOS)
        self._image = Image(height=k.height_px, width=k.width_px, encoding='rgb8',
                            is_bigendian=0, step=3 * k.width_px)
        self._image.header.frame_id = frame_id
        self._info = _camera_info(k, frame_id)
        self._depth = self._depth_pub = self._depth_info_pub = None
        if config.camera_depth:
            self._depth_pub = node.create_publisher(Image, 'camera/depth/image_raw', CAMERA_QOS)
            self._depth_info_pub = node.create_publisher(
                CameraInfo, 'camera/depth/camera_info', CAMERA_QOS)
            self._depth = Image(height=k.height_px, width=k.width_px, encoding='32FC1',
                                is_bigendian=0, step=4 * k.width_px)
            self._depth.header.frame_id = frame_id

    def publish(self, simulation: Simulation) -> None:
        """Render and publish an image and its CameraInfo (and depth), stamped now."""
        stamp = divmod(simulation.time_ns, 10**9)
        rgb, depth = self._camera.render(depth=self._depth is not None)
        info = self._info
        info.header.stamp.sec, info.header.stamp.nanosec = stamp
        for image, data, publisher, info_publisher in (
                (self._image, rgb, self._image_pub, self._info_pub),
                (self._depth, depth, self._depth_pub, self._depth_info_pub)):
            if image is None:
                continue
            image.header.stamp.sec, image.header.stamp.nanosec = stamp
            image.data = data if isinstance(data, bytes) else data.astype('<f4').tobytes()
            publisher.publish(image)
            info_publisher.publish(info)


def _camera_info(k, frame_id: str) -> CameraInfo:
    info = CameraInfo(height=k.height_px, width=k.width_px, distortion_model='plumb_bob')
    info.header.frame_id = frame_id
    info.d = [0.0] * 5
    info.k = k.k
    info.r = camera.IDENTITY_3X3
    info.p = k.p
    return info


class TfOutput:
    """
    ``/tf`` each state publication: odom -> base_footprint from wheel odometry.

    Optionally world -> odom (so world -> base_footprint is the true pose) and
    the robot's moving joints (parent -> child link, as robot_state_publisher
    would publish them). All transforms carry the frame's stamp: the same as
    that step's odom message, so no sensor message is newer than its transform.
    """

    def __init__(self, node: Node, config: SimConfig, simulation: Simulation,
                 links: Optional[LinkTransforms]) -> None:
        from tf2_msgs.msg import TFMessage  # optional: the node checks it is importable
        self._publisher = node.create_publisher(TFMessage, '/tf', TF_QOS)
        frame = config.frame
        pairs = []
        self._odometry = simulation.controller is not None
        if self._odometry:
            pairs.append((frame(config.odom_frame_id), frame(config.footprint_frame_id)))
        self._truth = config.publish_ground_truth_tf and self._odometry
        if self._truth:
            pairs.append((config.world_frame_id, frame(config.odom_frame_id)))
        self._links = links
        self._joint_slots = []
        if links is not None:
            index = {j.name: i for i, j in enumerate(simulation.movable)}
            self._joint_slots = [index[name] for name in links.moving_joint_names]
            pairs += [(frame(j.parent_link), frame(j.child_link))
                      for j in links.moving([0.0] * len(self._joint_slots))]
        msg = TFMessage(transforms=[_transform_stamped(parent, child, IDENTITY)
                                    for parent, child in pairs])
        self._template = MessageTemplate(msg)
        self._stamps = [self._template.stamp(f'transforms[{i}].header.stamp')
                        for i in range(len(pairs))]
        self._transforms = [self._template.field(f'transforms[{i}].transform')
                            for i in range(len(pairs))]
        self.empty = not pairs

    def publish(self, frame: Frame) -> None:
        """Publish the frame's transforms."""
        stamp = frame.stamp
        for slot in self._stamps:
            slot.set(*stamp)
        slots = iter(self._transforms)
        if self._odometry:
            odometry = frame.odometry
            odom = Transform((odometry.x_m, odometry.y_m, 0.0),
                             yaw_to_quaternion(odometry.yaw_rad))
            next(slots).set(odom.translation + odom.rotation)
            if self._truth:
                base = frame.base
                yaw, _ = split_yaw(base.orientation)
                truth = Transform((base.position[0], base.position[1], 0.0), yaw)
                world_odom = compose(truth, inverse(odom))
                next(slots).set(world_odom.translation + world_odom.rotation)
        if self._links is not None:
            positions = frame.joints.positions
            for joint in self._links.moving([positions[i] for i in self._joint_slots]):
                next(slots).set(joint.transform.translation + joint.transform.rotation)
        self._publisher.publish(self._template.to_bytes())


def start_tf(node: Node, config: SimConfig, simulation: Simulation) -> Optional[TfOutput]:
    """
    Publish /tf_static once and return the /tf output (None if it has nothing to publish).

    tf2_msgs is in every ROS install but not on PyPI: without it, say so once
    and return None; everything else works.
    """
    try:
        import tf2_msgs.msg  # noqa: F401  (a pip-only venv: tools/build_tf2_msgs.sh)
    except ImportError:
        node.get_logger().warning(
            'tf2_msgs is not installed: /tf and /tf_static are off (a pip-only venv gets '
            'it from tools/build_tf2_msgs.sh VENV); everything else works')
        return None
    links = link_transforms(simulation) if config.publish_link_tf else None
    publish_static_transforms(node, static_transforms(config, simulation, links),
                              divmod(simulation.time_ns, 10**9))
    tf = TfOutput(node, config, simulation, links)
    return None if tf.empty else tf


def link_transforms(simulation: Simulation) -> LinkTransforms:
    """
    Return the robot's link transforms from its URDF, moving joints as the joint readout has them.

    The URDF's root link must be the body frame: a robot whose URDF base is
    turned (base_forward_axis other than x) would publish two different
    frames of one name.
    """
    config, world = simulation.config, simulation.world
    try:
        links = LinkTransforms(world.robot_description, [j.name for j in simulation.movable])
    except ValueError as exc:
        raise ConfigError(f'publish_link_tf: {exc}') from None
    if config.body_yaw_offset_rad and links.root_link == config.base_frame_id:
        raise ConfigError(
            f'publish_link_tf: the URDF base {links.root_link!r} is turned from the body frame '
            f'(base_forward_axis {config.base_forward_axis}): give base_frame_id another name')
    return links


def static_transforms(config: SimConfig, simulation: Simulation,
                      links: Optional[LinkTransforms]) -> List[Tuple[str, str, Transform]]:
    """
    Return the frames that never move, for ``/tf_static``: (parent, child, transform).

    base_footprint -> base_link (the body frame's height at rest; a frame of
    the node's own, not a URDF link, so the robot keeps the tutorial's 15
    joints and PyBullet gets no extra body), the sensor mounts, the URDF's
    fixed joints when link transforms are on, and the head camera's optical
    frame (z forward, x right, y down) on the head link.
    """
    frame = config.frame
    base = frame(config.base_frame_id)
    result = [(frame(config.footprint_frame_id), base,
               Transform((0.0, 0.0, simulation.footprint_height_m), IDENTITY.rotation))]
    if simulation.laser is not None:
        result.append((base, frame(LASER_FRAME_ID), simulation.laser.mount))
    if simulation.imu is not None:
        result.append((base, frame(IMU_FRAME_ID), IDENTITY))
    if links is not None:
        if links.root_link != config.base_frame_id:  # the URDF base, turned from the body
            result.append((base, frame(links.root_link), Transform(
                (0.0, 0.0, 0.0), yaw_to_quaternion(-config.body_yaw_offset_rad))))
        result += [(frame(j.parent_link), frame(j.child_link), j.transform) for j in links.fixed()]
    if simulation.camera is not None:
        # Not a URDF link, so robot_state_publisher never publishes it: always ours.
        result.append((frame(simulation.camera.link_name), frame(HEAD_CAMERA_FRAME_ID),
                       simulation.camera.optical_mount))
    return result


def publish_static_transforms(node: Node, transforms: Sequence[Tuple[str, str, Transform]],
                              stamp: Tuple[int, int]):
    """Publish ``/tf_static`` once, transient local for late subscribers; return its publisher."""
    # The publisher stays alive with the node (rclpy keeps it), so late joiners get it.
    from tf2_msgs.msg import TFMessage
    publisher = node.create_publisher(TFMessage, '/tf_static', TF_STATIC_QOS)
    msg = TFMessage(transforms=[_transform_stamped(p, c, t, stamp) for p, c, t in transforms])
    publisher.publish(msg)
    return publisher


def _transform_stamped(parent: str, child: str, transform: Transform,
                       stamp: Tuple[int, int] = (0, 0)) -> TransformStamped:
    msg = TransformStamped()
    msg.header.frame_id, msg.child_frame_id = parent, child
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    t, r = msg.transform.translation, msg.transform.rotation
    t.x, t.y, t.z = transform.translation
    r.x, r.y, r.z, r.w = transform.rotation
    return msg


class ScanOutput:
    """``scan`` (sensor_msgs/LaserScan) at ``scan_rate``, in frame base_scan (REP-117)."""

    def __init__(self, node: Node, config: SimConfig, laser: LaserScanner) -> None:
        self._laser = laser
        self._publisher = node.create_publisher(LaserScan, 'scan', SENSOR_QOS)
        geometry = laser.geometry
        msg = LaserScan(angle_min=geometry.angle_min_rad, angle_max=geometry.last_angle_rad,
                        angle_increment=geometry.angle_increment_rad,
                        # All beams are cast at one instant: no motion between them,
                        # so laser projection must not spread them over time.
                        time_increment=0.0, scan_time=1.0 / config.scan_rate_hz,
                        range_min=geometry.range_min_m, range_max=geometry.range_max_m,
                        ranges=[0.0] * geometry.samples)
        msg.header.frame_id = config.frame(LASER_FRAME_ID)
        self._template = MessageTemplate(msg)
        self._stamp = self._template.stamp()
        self._ranges = self._template.field('ranges')

    def publish(self, simulation: Simulation) -> None:
        """Scan now and publish, stamped with the step's simulated time."""
        self._stamp.set_nanoseconds(simulation.time_ns)
        self._ranges.set(self._laser.scan())
        self._publisher.publish(self._template.to_bytes())


class ImuOutput:
    """``imu`` (sensor_msgs/Imu) at ``imu_rate``, in frame imu_link (REP-145)."""

    def __init__(self, node: Node, config: SimConfig, imu: ImuSensor) -> None:
        self._imu = imu
        self._publisher = node.create_publisher(Imu, 'imu', SENSOR_QOS)
        msg = Imu()
        msg.header.frame_id = config.frame(IMU_FRAME_ID)
        model = imu.model
        msg.orientation_covariance = model.orientation_covariance
        msg.angular_velocity_covariance = model.angular_velocity_covariance
        msg.linear_acceleration_covariance = model.linear_acceleration_covariance
        self._template = MessageTemplate(msg)
        self._stamp = self._template.stamp()
        self._orientation = self._template.field('orientation')
        self._angular = self._template.field('angular_velocity')
        self._linear = self._template.field('linear_acceleration')

    def publish(self, simulation: Simulation) -> None:
        """Read the IMU now and publish, stamped with the step's simulated time."""
        time_ns = simulation.time_ns
        reading = self._imu.read(time_ns / 1e9)
        self._stamp.set_nanoseconds(time_ns)
        self._orientation.set(reading.orientation_xyzw)
        self._angular.set(reading.angular_velocity_rad_s)
        self._linear.set(reading.linear_acceleration_m_s2)
        self._publisher.publish(self._template.to_bytes())
