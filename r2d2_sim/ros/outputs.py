"""
The node's published outputs: one small class per published thing, translating measurements.

Every output turns plain data the simulation measured into a message and
publishes it; none of them measures. State outputs (joint states, odometry,
ground truth, and TF in :mod:`r2d2_sim.ros.tf_outputs`) publish a robot's
:class:`~r2d2_sim.sim.robot.Frame`; sensor outputs (camera, scan, IMU) a reading
and its time. :class:`RobotOutputs` holds one robot's outputs and hands each
:class:`~r2d2_sim.sim.robot.Measurement` out. Each keeps its message serialized
once (:class:`~r2d2_sim.ros.serialization.MessageTemplate`), patches only the
bytes that move and publishes the bytes: rclpy then skips the Python-to-C
conversion and serialization (an Odometry: 11-21 us typed, 2-9 us as bytes,
measured here). The camera's images are typed messages: a render costs
milliseconds, so the conversion does not matter there. Point clouds (the
depth camera's, the 3D lidar's) are templates too: their points are copied
into the serialized bytes, which spares rclpy converting a million-element
``uint8[]`` each time.
"""

from collections import OrderedDict
import math
from typing import List, Optional, Sequence, Tuple

import numpy
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import (
    BatteryState, CameraInfo, Image, Imu, JointState, LaserScan, PointCloud2, PointField)
from visualization_msgs.msg import Marker, MarkerArray

from r2d2_sim.model import battery, camera
from r2d2_sim.physics.records import JointRecord
from r2d2_sim.model.camera import CameraIntrinsics
from r2d2_sim.sim.oracles import Touch
from r2d2_sim.sim.parameters import SimConfig
from r2d2_sim.sim.robot import Frame, Measurement, Robot
from r2d2_sim.sim.sensor_mounts import (
    CameraImage, HEAD_CAMERA_FRAME_ID, IMU_FRAME_ID, LASER_FRAME_ID, LIDAR3D_FRAME_ID)
from r2d2_sim.model.sensors import ImuModel, ImuReading, LidarGeometry, ScanGeometry
from r2d2_sim.ros.serialization import MessageTemplate, StampSlot
from r2d2_sim.ros.tf_outputs import (  # noqa: F401 (TF's QoS here too)
    start_tf, TF_QOS, TF_STATIC_QOS)
from r2d2_sim.model.timing import stamp_of
from r2d2_sim.model.transforms import yaw_to_quaternion

__all__ = ['STATE_QOS', 'CAMERA_QOS', 'SENSOR_QOS', 'ClockOutput', 'JointStateOutput',
           'GroundTruthOutput', 'OdometryOutput', 'HeadCameraOutput', 'ScanOutput', 'ImuOutput',
           'Lidar3dOutput', 'PointCloudTemplate', 'BatteryOutput', 'ContactsOutput',
           'RobotOutputs']

# Reliable with a modest queue: default subscribers and sensor-data (best
# effort) subscribers both match it.
STATE_QOS = QoSProfile(depth=10)
CAMERA_QOS = QoSProfile(depth=2)
SENSOR_QOS = QoSProfile(depth=5)


class ClockOutput:
    """``/clock``: the simulated time of each state publication (one per world)."""

    def __init__(self, node: Node) -> None:
        self._publisher = node.create_publisher(Clock, '/clock', STATE_QOS)
        self._template = MessageTemplate(Clock())
        self._clock = self._template.stamp('clock')

    def publish(self, time_ns: int) -> None:
        """Publish the time."""
        self._clock.set_nanoseconds(time_ns)
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

    def publish(self, frame: Frame) -> None:
        """Publish the frame's wheel odometry."""
        msg, odometry = self._msg, frame.odometry
        msg.stamp.set(*frame.stamp)
        msg.pose.set((odometry.x_m, odometry.y_m, self._height_m)
                     + yaw_to_quaternion(odometry.yaw_rad))
        msg.twist.set((odometry.linear_m_s, 0.0, 0.0, 0.0, 0.0, odometry.angular_rad_s))
        if odometry.pose_covariance is not None:
            self._covariances[0].set(_embedded(self._pose_covariance, self._POSE_AXES,
                                               odometry.pose_covariance))
            self._covariances[1].set(_embedded(self._twist_covariance, self._TWIST_AXES,
                                               odometry.twist_covariance))
        self._publisher.publish(msg.template.to_bytes())


def _embedded(base: List[float], axes: Sequence[int], block: Sequence[float]) -> List[float]:
    """Return a 6 x 6 covariance (row by row): ``base`` with the ``axes`` block set."""
    full = list(base)
    n = len(axes)
    for i, row in enumerate(axes):
        for j, column in enumerate(axes):
            full[6 * row + column] = block[n * i + j]
    return full


class HeadCameraOutput:
    """
    ``camera/image_raw`` (rgb8) and ``camera/camera_info`` at ``camera_rate``.

    With ``camera_depth``, also ``camera/depth/image_raw`` (32FC1, metres along
    the optical axis, REP-118) and ``camera/depth/camera_info`` from the same
    render, so depth and colour pixels line up.
    """

    def __init__(self, node: Node, config: SimConfig, k: CameraIntrinsics) -> None:
        frame_id = config.frame(HEAD_CAMERA_FRAME_ID)
        self._image_pub = node.create_publisher(Image, 'camera/image_raw', CAMERA_QOS)
        self._info_pub = node.create_publisher(CameraInfo, 'camera/camera_info', CAMERA_QOS)
        self._image = Image(height=k.height_px, width=k.width_px, encoding='rgb8',
                            is_bigendian=0, step=3 * k.width_px)
        self._image.header.frame_id = frame_id
        self._info = _camera_info(k, frame_id)
        self._depth = self._depth_pub = self._depth_info_pub = None
        self._cloud: Optional[PointCloudTemplate] = None
        if config.camera_point_cloud:
            self._cloud_pub = node.create_publisher(PointCloud2, 'camera/depth/points',
                                                    CAMERA_QOS)
            self._cloud = PointCloudTemplate(frame_id, k.height_px, k.width_px, XYZ)
            self._rays = camera.pixel_rays(k)
        if config.camera_depth:
            self._depth_pub = node.create_publisher(Image, 'camera/depth/image_raw', CAMERA_QOS)
            self._depth_info_pub = node.create_publisher(
                CameraInfo, 'camera/depth/camera_info', CAMERA_QOS)
            self._depth = Image(height=k.height_px, width=k.width_px, encoding='32FC1',
                                is_bigendian=0, step=4 * k.width_px)
            self._depth.header.frame_id = frame_id

    def publish(self, time_ns: int, image: CameraImage) -> None:
        """Publish an image and its CameraInfo (and depth), stamped ``time_ns``."""
        stamp = stamp_of(time_ns)
        rgb, depth = image
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
        if self._cloud is not None:
            cloud = self._cloud
            cloud.stamp.set_nanoseconds(time_ns)
            cloud.data.set(camera.depth_points(depth, self._rays))
            self._cloud_pub.publish(cloud.template.to_bytes())


def _camera_info(k: CameraIntrinsics, frame_id: str) -> CameraInfo:
    info = CameraInfo(height=k.height_px, width=k.width_px, distortion_model='plumb_bob')
    info.header.frame_id = frame_id
    info.d = [0.0] * 5
    info.k = k.k
    info.r = camera.IDENTITY_3X3
    info.p = k.p
    return info


class ScanOutput:
    """``scan`` (sensor_msgs/LaserScan) at ``scan_rate``, in frame base_scan (REP-117)."""

    def __init__(self, node: Node, config: SimConfig, geometry: ScanGeometry) -> None:
        self._publisher = node.create_publisher(LaserScan, 'scan', SENSOR_QOS)
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

    def publish(self, time_ns: int, ranges: numpy.ndarray) -> None:
        """Publish REP-117 ranges measured at ``time_ns``."""
        self._stamp.set_nanoseconds(time_ns)
        self._ranges.set(ranges)
        self._publisher.publish(self._template.to_bytes())


class ImuOutput:
    """``imu`` (sensor_msgs/Imu) at ``imu_rate``, in frame imu_link (REP-145)."""

    def __init__(self, node: Node, config: SimConfig, model: ImuModel) -> None:
        self._publisher = node.create_publisher(Imu, 'imu', SENSOR_QOS)
        msg = Imu()
        msg.header.frame_id = config.frame(IMU_FRAME_ID)
        msg.orientation_covariance = model.orientation_covariance
        msg.angular_velocity_covariance = model.angular_velocity_covariance
        msg.linear_acceleration_covariance = model.linear_acceleration_covariance
        self._template = MessageTemplate(msg)
        self._stamp = self._template.stamp()
        self._orientation = self._template.field('orientation')
        self._angular = self._template.field('angular_velocity')
        self._linear = self._template.field('linear_acceleration')

    def publish(self, time_ns: int, reading: ImuReading) -> None:
        """Publish a reading taken at ``time_ns``."""
        self._stamp.set_nanoseconds(time_ns)
        self._orientation.set(reading.orientation_xyzw)
        self._angular.set(reading.angular_velocity_rad_s)
        self._linear.set(reading.linear_acceleration_m_s2)
        self._publisher.publish(self._template.to_bytes())


# PointField datatypes (sensor_msgs/PointField constants).
_FLOAT32, _UINT16 = PointField.FLOAT32, PointField.UINT16
# x y z float32: a depth camera's cloud, as depth_image_proc makes it (12 bytes a point).
XYZ = numpy.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4')])
# As Velodyne drivers publish (velodyne_pointcloud's XYZIRT): 22 bytes, packed.
XYZIRT = numpy.dtype([('x', '<f4'), ('y', '<f4'), ('z', '<f4'), ('intensity', '<f4'),
                      ('ring', '<u2'), ('time', '<f4')])
_DATATYPES = {'<f4': _FLOAT32, '<u2': _UINT16}


class PointCloudTemplate:
    """
    An organised sensor_msgs/PointCloud2 of ``height`` x ``width`` points laid out as ``dtype``.

    The fields follow the dtype (names, offsets, datatypes); only the stamp
    and the point bytes change (:attr:`stamp`, :attr:`data`). Not dense: a
    point that measured nothing is NaN.
    """

    def __init__(self, frame_id: str, height: int, width: int, dtype: numpy.dtype) -> None:
        fields = [PointField(name=name, offset=dtype.fields[name][1],
                             datatype=_DATATYPES[dtype.fields[name][0].str], count=1)
                  for name in dtype.names]
        msg = PointCloud2(height=height, width=width, fields=fields, is_bigendian=False,
                          point_step=dtype.itemsize, row_step=dtype.itemsize * width,
                          is_dense=False)
        msg.header.frame_id = frame_id
        msg.data = bytes(height * width * dtype.itemsize)
        self.template = MessageTemplate(msg)
        self.stamp = self.template.stamp()
        self.data = self.template.bytes_field('data')


class Lidar3dOutput:
    """
    ``points`` (sensor_msgs/PointCloud2) at ``lidar3d_rate``, in frame lidar_3d.

    Organised as Velodyne drivers organise it: one row per ring (ring 0 the
    lowest), one column per beam around the turn; fields x y z intensity
    (float32) ring (uint16) time (float32), 22 bytes a point. Intensity is 0
    (no reflectivity model) and time 0 (every beam at the scan's instant, as
    the LaserScan's time_increment). A beam without a return is a NaN point.
    """

    def __init__(self, node: Node, config: SimConfig, geometry: LidarGeometry) -> None:
        self._publisher = node.create_publisher(PointCloud2, 'points', CAMERA_QOS)
        self._cloud = PointCloudTemplate(config.frame(LIDAR3D_FRAME_ID), geometry.rings,
                                         geometry.samples, XYZIRT)
        self._points = numpy.zeros((geometry.rings, geometry.samples), XYZIRT)
        self._points['ring'] = numpy.arange(geometry.rings, dtype=numpy.uint16)[:, None]

    def publish(self, time_ns: int, points: numpy.ndarray) -> None:
        """Publish a scan's points, (rings, samples, 3), measured at ``time_ns``."""
        cloud, packed = self._cloud, self._points
        packed['x'], packed['y'], packed['z'] = points[..., 0], points[..., 1], points[..., 2]
        cloud.stamp.set_nanoseconds(time_ns)
        cloud.data.set(packed)
        self._publisher.publish(cloud.template.to_bytes())


class BatteryOutput:
    """
    ``battery_state`` (sensor_msgs/BatteryState) at ``battery_rate``, in the robot's base frame.

    Voltage, current (negative discharging), charge, capacity and percentage
    from :class:`~r2d2_sim.model.battery.Battery`; power_supply_status
    CHARGING, DISCHARGING or FULL; no temperature (NaN), health GOOD,
    technology LION, present. One template per status (a status is a single
    byte, too short to locate): the reading's status picks the one to patch.
    """

    def __init__(self, node: Node, config: SimConfig, capacity_ah: float) -> None:
        self._publisher = node.create_publisher(BatteryState, 'battery_state', SENSOR_QOS)
        self._templates = {}
        for status in (battery.CHARGING, battery.DISCHARGING, battery.FULL):
            msg = BatteryState(temperature=math.nan, capacity=capacity_ah,
                               design_capacity=capacity_ah, power_supply_status=status,
                               power_supply_health=BatteryState.POWER_SUPPLY_HEALTH_GOOD,
                               power_supply_technology=BatteryState.POWER_SUPPLY_TECHNOLOGY_LION,
                               present=True)
            msg.header.frame_id = config.frame(config.base_frame_id)
            template = MessageTemplate(msg)
            self._templates[status] = (template, template.stamp(), *(
                template.field(name) for name in ('voltage', 'current', 'charge',
                                                  'percentage')))

    def publish(self, time_ns: int, reading: battery.BatteryReading) -> None:
        """Publish the battery as read at ``time_ns``."""
        template, stamp, voltage, current, charge, percentage = self._templates[reading.status]
        stamp.set_nanoseconds(time_ns)
        voltage.set((reading.voltage_v,))
        current.set((reading.current_a,))
        charge.set((reading.charge_ah,))
        percentage.set((reading.percentage,))
        self._publisher.publish(template.to_bytes())


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
        self._frame_id = config.world_frame_id
        self._templates: 'OrderedDict[Tuple, Tuple]' = OrderedDict()
        self._touching = False

    def publish(self, time_ns: int, touches: Sequence[Touch]) -> None:
        """Publish what the robot touches at ``time_ns`` (nothing while it touched nothing)."""
        if not touches and not self._touching:
            return
        self._touching = bool(touches)
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
        self.imu = ImuOutput(node, config, robot.imu.model) if robot.imu is not None else None
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
        if measurement.image is not None:
            self.camera.publish(measurement.time_ns, measurement.image)
        if measurement.scan is not None:
            self.scan.publish(measurement.time_ns, measurement.scan)
        if measurement.imu is not None:
            self.imu.publish(measurement.time_ns, measurement.imu)
        if measurement.lidar is not None:
            self.lidar.publish(measurement.time_ns, measurement.lidar)
        if measurement.battery is not None:
            self.battery.publish(measurement.time_ns, measurement.battery)
        if measurement.contacts is not None and self.contacts is not None:
            self.contacts.publish(measurement.time_ns, measurement.contacts)
