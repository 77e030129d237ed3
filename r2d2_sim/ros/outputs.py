"""
The node's published outputs: one small class per published thing, translating measurements.

Every output turns plain data the simulation measured into a message and
publishes it; none of them measures. State outputs (joint states, odometry,
ground truth, and TF in :mod:`r2d2_sim.ros.tf_outputs`) publish a robot's
:class:`~r2d2_sim.sim.robots.robot.Frame`, and the contacts what it touched at the
same steps: they are here. Sensor outputs
(camera, scan, IMU, 3D lidar, battery) publish a reading and its time and
are in :mod:`r2d2_sim.ros.sensor_outputs` (this module exports their names
too). :class:`RobotOutputs` holds one robot's outputs and hands each
:class:`~r2d2_sim.sim.robots.robot.Measurement` out. Each keeps its message serialized
once (:class:`~r2d2_sim.ros.serialization.MessageTemplate`), patches only the
bytes that move and publishes the bytes: rclpy then skips the Python-to-C
conversion and serialization (an Odometry: 11-21 us typed, 2-9 us as bytes,
measured here).
"""

from collections import OrderedDict
from typing import List, Optional, Sequence, Tuple

from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker, MarkerArray

from r2d2_sim.physics.records import JointRecord
from r2d2_sim.sim.oracles import Touch
from r2d2_sim.sim.settings.config import SimConfig
from r2d2_sim.sim.robots.robot import Frame, Measurement, Robot
from r2d2_sim.ros.sensor_outputs import (
    BatteryOutput, CAMERA_QOS, HeadCameraOutput, ImuOutput, Lidar3dOutput, PointCloudTemplate,
    ScanOutput, SENSOR_QOS)
from r2d2_sim.ros.mirror import demand
from r2d2_sim.ros.serialization import MessageTemplate, StampSlot
from r2d2_sim.ros.tf_outputs import (  # noqa: F401 (TF's QoS here too)
    start_tf, TF_QOS, TF_STATIC_QOS)
from r2d2_sim.model.transforms import yaw_to_quaternion

__all__ = ['STATE_QOS', 'CAMERA_QOS', 'SENSOR_QOS', 'ClockOutput', 'JointStateOutput',
           'GroundTruthOutput', 'OdometryOutput', 'HeadCameraOutput', 'ScanOutput', 'ImuOutput',
           'Lidar3dOutput', 'PointCloudTemplate', 'BatteryOutput', 'ContactsOutput',
           'RobotOutputs']

# Reliable with a modest queue: default subscribers and sensor-data (best
# effort) subscribers both match it.
STATE_QOS = QoSProfile(depth=10)


class ClockOutput:
    """``/clock``: the simulated time of each state publication (one per world)."""

    def __init__(self, node: Node) -> None:
        self._publisher = node.create_publisher(Clock, '/clock', STATE_QOS)
        self._demand = demand(self._publisher)
        self._template = MessageTemplate(Clock())
        self._clock = self._template.stamp('clock')

    def publish(self, time_ns: int) -> None:
        """Publish the time."""
        if not self._demand():
            return
        self._clock.set_nanoseconds(time_ns)
        self._publisher.publish(self._template.to_bytes())


class JointStateOutput:
    """``joint_states``: position, velocity and applied effort of every movable joint."""

    def __init__(self, node: Node, joints: Sequence[JointRecord]) -> None:
        self._publisher = node.create_publisher(JointState, 'joint_states', STATE_QOS)
        self._demand = demand(self._publisher)
        zeros = [0.0] * len(joints)
        self._template = MessageTemplate(JointState(
            name=[j.name for j in joints], position=zeros, velocity=zeros, effort=zeros))
        self._stamp = self._template.stamp()
        # A robot without movable joints publishes empty arrays: nothing to patch.
        self._arrays = [self._template.field(name) for name in ('position', 'velocity', 'effort')
                        ] if joints else []

    def publish(self, frame: Frame) -> None:
        """Publish the frame's joint readout."""
        if not self._demand():
            return
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
        self._demand = demand(self._publisher)
        msg = Odometry()
        msg.header.frame_id = config.world_frame_id
        msg.child_frame_id = config.frame(config.base_frame_id)
        self._msg = _OdometryTemplate(msg)

    def publish(self, frame: Frame) -> None:
        """Publish the frame's true base state."""
        if not self._demand():
            return
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
    the message and the transform tree agree on where base_link is. The
    covariances are the configured diagonals; when the encoders err
    (``encoder_noise_*``), the entries of x, y and yaw (pose) and of the
    linear and angular velocity (twist), their cross terms included, are
    those the encoders' noise gives (:class:`~r2d2_sim.model.encoders.OdometryCovariance`).
    """

    # Where (x, y, yaw) and (vx, wz) sit in a 6 x 6 covariance (x y z roll pitch yaw).
    _POSE_AXES = (0, 1, 5)
    _TWIST_AXES = (0, 5)

    def __init__(self, node: Node, config: SimConfig, footprint_height_m: float) -> None:
        self._publisher = node.create_publisher(Odometry, 'odom', STATE_QOS)
        self._demand = demand(self._publisher)
        msg = Odometry()
        msg.header.frame_id = config.frame(config.odom_frame_id)
        msg.child_frame_id = config.frame(config.base_frame_id)
        for i, variance in enumerate(config.pose_covariance_diagonal):
            msg.pose.covariance[7 * i] = variance
        for i, variance in enumerate(config.twist_covariance_diagonal):
            msg.twist.covariance[7 * i] = variance
        self._pose_covariance = list(msg.pose.covariance)
        self._twist_covariance = list(msg.twist.covariance)
        self._msg = _OdometryTemplate(msg)
        self._covariances = (self._msg.template.field('pose.covariance'),
                             self._msg.template.field('twist.covariance'))
        self._height_m = footprint_height_m
        self._patched = [False, False]  # pose, twist: holds an encoder covariance

    def publish(self, frame: Frame) -> None:
        """Publish the frame's wheel odometry."""
        if not self._demand():
            return
        msg, odometry = self._msg, frame.odometry
        assert odometry is not None, 'a robot with wheels (this output) measures odometry'
        msg.stamp.set(*frame.stamp)
        msg.pose.set((odometry.x_m, odometry.y_m, self._height_m)
                     + yaw_to_quaternion(odometry.yaw_rad))
        msg.twist.set((odometry.linear_m_s, 0.0, 0.0, 0.0, 0.0, odometry.angular_rad_s))
        # The encoders' covariance when they err, else the configured diagonal (written
        # back once when the noise is switched off: the template keeps the last one set).
        for slot, (base, axes, block) in enumerate((
                (self._pose_covariance, self._POSE_AXES, odometry.pose_covariance),
                (self._twist_covariance, self._TWIST_AXES, odometry.twist_covariance))):
            if block is not None:
                self._covariances[slot].set(_embedded(base, axes, block))
                self._patched[slot] = True
            elif self._patched[slot]:
                self._covariances[slot].set(base)
                self._patched[slot] = False
        self._publisher.publish(msg.template.to_bytes())


def _embedded(base: List[float], axes: Sequence[int], block: Sequence[float]) -> List[float]:
    """Return a 6 x 6 covariance (row by row): ``base`` with the ``axes`` block set."""
    full = list(base)
    n = len(axes)
    for i, row in enumerate(axes):
        for j, column in enumerate(axes):
            full[6 * row + column] = block[n * i + j]
    return full


class ContactsOutput:
    """
    ``contacts`` (visualization_msgs/MarkerArray): where the robot touches other bodies.

    With ``publish_contacts``, at each state publication while the robot
    touches anything, and once more when it stops: a DELETEALL marker (so a
    viewer drops the last contacts) and then, per touched body, a red sphere
    at the strongest contact point, in ``world_frame_id``, ``ns`` the other
    entity's name, ``text`` the two links ("robot link -> other link"). rviz
    and Foxglove draw it as it is. A message per set of touching links is
    serialized once and kept (the last ``TEMPLATES_KEPT`` sets); only its
    stamps and points are patched.
    """

    TEMPLATES_KEPT = 32
    SPHERE_M = 0.06

    def __init__(self, node: Node, config: SimConfig) -> None:
        self._publisher = node.create_publisher(MarkerArray, 'contacts', STATE_QOS)
        self._demand = demand(self._publisher)
        self._frame_id = config.world_frame_id
        self._templates: 'OrderedDict[Tuple, Tuple]' = OrderedDict()
        self._touching = False

    def publish(self, time_ns: int, touches: Sequence[Touch]) -> None:
        """Publish what the robot touches at ``time_ns`` (nothing while it touched nothing)."""
        if not touches and not self._touching:
            return
        self._touching = bool(touches)
        if not self._demand():
            return
        key = tuple((t.other, t.link, t.other_link) for t in touches)
        template, stamps, points = self._template(key)
        for stamp in stamps:
            stamp.set_nanoseconds(time_ns)
        for point, touch in zip(points, touches):
            point.set(touch.position)
        self._publisher.publish(template.to_bytes())

    def _template(self, key: Tuple) -> Tuple[MessageTemplate, List[StampSlot], List]:
        found = self._templates.get(key)
        if found is not None:
            self._templates.move_to_end(key)
            return found
        markers = [Marker(action=Marker.DELETEALL)]
        for index, (other, link, other_link) in enumerate(key):
            marker = Marker(ns=other, id=index, type=Marker.SPHERE, action=Marker.ADD,
                            text=f'{link} -> {other_link}')
            marker.pose.orientation.w = 1.0
            marker.scale.x = marker.scale.y = marker.scale.z = self.SPHERE_M
            marker.color.r, marker.color.a = 1.0, 1.0
            markers.append(marker)
        for marker in markers:
            marker.header.frame_id = self._frame_id
        template = MessageTemplate(MarkerArray(markers=markers))
        found = (template, [template.stamp(f'markers[{i}].header.stamp')
                            for i in range(len(markers))],
                 [template.field(f'markers[{i}].pose.position', count=3)
                  for i in range(1, len(markers))])
        self._templates[key] = found
        if len(self._templates) > self.TEMPLATES_KEPT:
            self._templates.popitem(last=False)
        return found


class RobotOutputs:
    """
    Everything one robot publishes, built from its configuration; hands each measurement out.

    State outputs take the measurement's frame, sensor outputs their reading.
    TF is started here too (``/tf_static`` published once, at ``time_ns``).
    """

    def __init__(self, node: Node, config: SimConfig, robot: Robot, time_ns: int) -> None:
        self.state: List = [JointStateOutput(node, robot.movable),
                            GroundTruthOutput(node, config)]
        if robot.controller is not None:
            self.state.append(OdometryOutput(node, config, robot.footprint_height_m))
        self.camera = (HeadCameraOutput(node, config, robot.camera.intrinsics)
                       if robot.camera is not None else None)
        self.scan = (ScanOutput(node, config, robot.laser.geometry)
                     if robot.laser is not None else None)
        self.imu = ImuOutput(node, config, robot.imu) if robot.imu is not None else None
        self.lidar = (Lidar3dOutput(node, config, robot.lidar.geometry)
                      if robot.lidar is not None else None)
        self.battery = (BatteryOutput(node, config, robot.battery.spec.capacity_ah)
                        if robot.battery is not None else None)
        self.contacts: Optional[ContactsOutput] = (ContactsOutput(node, config)
                                                   if config.publish_contacts else None)
        self.tf = start_tf(node, config, robot, time_ns) if config.publish_tf else None
        if self.tf is not None:
            self.state.append(self.tf)

    def publish(self, measurement: Measurement) -> None:
        """Publish what was measured: the frame to every state output, each reading to its own."""
        frame = measurement.frame
        if frame is not None:
            for output in self.state:
                output.publish(frame)
        # A reading comes only from a sensor the robot has, which has its output.
        if measurement.image is not None and self.camera is not None:
            self.camera.publish(measurement.time_ns, measurement.image)
        if measurement.scan is not None and self.scan is not None:
            self.scan.publish(measurement.time_ns, measurement.scan)
        if measurement.imu is not None and self.imu is not None:
            self.imu.publish(measurement.time_ns, measurement.imu)
        if measurement.lidar is not None and self.lidar is not None:
            self.lidar.publish(measurement.time_ns, measurement.lidar)
        if measurement.battery is not None and self.battery is not None:
            self.battery.publish(measurement.time_ns, measurement.battery)
        if measurement.contacts is not None and self.contacts is not None:
            self.contacts.publish(measurement.time_ns, measurement.contacts)
