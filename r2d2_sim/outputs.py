"""
The node's published outputs: one small class per published thing.

State outputs (clock, joint states, odometry, ground truth) publish from the
:class:`~r2d2_sim.simulation.Frame` that the simulation reads once per state
publication. Sensor outputs (the head camera) have their own rate and their
own :class:`~r2d2_sim.timing.StepSchedule`, and take what they measure from the
simulation when they are due. Each keeps its message serialized once
(:class:`~r2d2_sim.serialization.MessageTemplate`), patches only the bytes that
move and publishes the bytes: rclpy then skips the Python-to-C conversion and
serialization (an Odometry: 11-21 us typed, 2-9 us as bytes, measured here).
"""

from typing import Sequence

from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState

from r2d2_sim import camera
from r2d2_sim.kinematics import yaw_to_quaternion
from r2d2_sim.parameters import SimConfig
from r2d2_sim.robot import HEAD_CAMERA_FRAME_ID, HeadCamera
from r2d2_sim.serialization import MessageTemplate
from r2d2_sim.simulation import Frame, Simulation
from r2d2_sim.timing import StepSchedule
from r2d2_sim.world import JointRecord

# Reliable with a modest queue: default subscribers and sensor-data (best
# effort) subscribers both match it.
STATE_QOS = QoSProfile(depth=10)
CAMERA_QOS = QoSProfile(depth=2)


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
        msg.child_frame_id = config.base_frame_id
        self._msg = _OdometryTemplate(msg)

    def publish(self, frame: Frame) -> None:
        """Publish the frame's true base state."""
        msg, base = self._msg, frame.base
        msg.stamp.set(*frame.stamp)
        msg.pose.set(base.position + base.orientation)
        msg.twist.set(base.linear_velocity + base.angular_velocity)
        self._publisher.publish(msg.template.to_bytes())


class OdometryOutput:
    """``odom``: wheel odometry, pose in the odom frame and twist in the body frame."""

    def __init__(self, node: Node, config: SimConfig) -> None:
        self._publisher = node.create_publisher(Odometry, 'odom', STATE_QOS)
        msg = Odometry()
        msg.header.frame_id = config.odom_frame_id
        msg.child_frame_id = config.base_frame_id
        for i, variance in enumerate(config.pose_covariance_diagonal):
            msg.pose.covariance[7 * i] = variance
        for i, variance in enumerate(config.twist_covariance_diagonal):
            msg.twist.covariance[7 * i] = variance
        self._msg = _OdometryTemplate(msg)

    def publish(self, frame: Frame) -> None:
        """Publish the frame's wheel odometry."""
        msg, odometry = self._msg, frame.odometry
        msg.stamp.set(*frame.stamp)
        msg.pose.set((odometry.x_m, odometry.y_m, 0.0) + yaw_to_quaternion(odometry.yaw_rad))
        msg.twist.set((odometry.linear_m_s, 0.0, 0.0, 0.0, 0.0, odometry.angular_rad_s))
        self._publisher.publish(msg.template.to_bytes())


class HeadCameraOutput:
    """``camera/image_raw`` (rgb8) and ``camera/camera_info`` at ``camera_rate``."""

    def __init__(self, node: Node, config: SimConfig, head_camera: HeadCamera) -> None:
        self.schedule = StepSchedule(config.physics_rate_hz, config.camera_rate_hz)
        self._camera = head_camera
        self._image_pub = node.create_publisher(Image, 'camera/image_raw', CAMERA_QOS)
        self._info_pub = node.create_publisher(CameraInfo, 'camera/camera_info', CAMERA_QOS)
        k = head_camera.intrinsics
        self._image = Image(height=k.height_px, width=k.width_px, encoding='rgb8',
                            is_bigendian=0, step=3 * k.width_px)
        self._image.header.frame_id = HEAD_CAMERA_FRAME_ID
        info = self._info = CameraInfo(height=k.height_px, width=k.width_px,
                                       distortion_model='plumb_bob')
        info.header.frame_id = HEAD_CAMERA_FRAME_ID
        info.d = [0.0] * 5
        info.k = k.k
        info.r = camera.IDENTITY_3X3
        info.p = k.p

    def publish(self, simulation: Simulation) -> None:
        """Render and publish an image and its CameraInfo, stamped now."""
        stamp = divmod(simulation.time_ns, 10**9)
        image, info = self._image, self._info
        image.header.stamp.sec, image.header.stamp.nanosec = stamp
        image.data = self._camera.render_rgb()
        self._image_pub.publish(image)
        info.header.stamp.sec, info.header.stamp.nanosec = stamp
        self._info_pub.publish(info)
