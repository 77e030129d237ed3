"""
The node's sensor outputs: one small class per sensor, translating a reading and its time.

The camera (colour, depth, and the depth camera's point cloud), the laser
scan, the IMU, the 3D lidar and the battery: each turns a reading the
simulation measured at its own rate into a message and publishes it, as
:mod:`r2d2_sim.ros.outputs`' state outputs do with a robot's frame (that
module holds them with the state outputs in :class:`~r2d2_sim.ros.outputs.RobotOutputs`
and exports their names). Each keeps its message serialized once
(:class:`~r2d2_sim.ros.serialization.MessageTemplate`) and patches only the
bytes that move, but for the camera's images: a render costs milliseconds,
so the typed conversion does not matter there. Point clouds
(:class:`PointCloudTemplate`) are templates too: their points are copied
into the serialized bytes, which spares rclpy converting a million-element
``uint8[]`` each time.
"""

import math
from typing import Any, Dict, Optional, Tuple

import numpy
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from sensor_msgs.msg import (
    BatteryState, CameraInfo, Image, Imu, LaserScan, PointCloud2, PointField)

from r2d2_sim.model import battery, camera
from r2d2_sim.model.camera import CameraIntrinsics
from r2d2_sim.model.sensors import ImuModel, ImuReading, LidarGeometry, ScanGeometry
from r2d2_sim.model.timing import stamp_of
from r2d2_sim.ros.mirror import demand
from r2d2_sim.ros.serialization import FieldSlot, MessageTemplate, StampSlot
from r2d2_sim.sim.settings.config import SimConfig
from r2d2_sim.sim.robots.sensors import (
    CameraImage, HEAD_CAMERA_FRAME_ID, IMU_FRAME_ID, ImuSensor, LASER_FRAME_ID,
    LIDAR3D_FRAME_ID)

__all__ = ['CAMERA_QOS', 'SENSOR_QOS', 'HeadCameraOutput', 'ScanOutput', 'ImuOutput',
           'Lidar3dOutput', 'PointCloudTemplate', 'BatteryOutput']

CAMERA_QOS = QoSProfile(depth=2)
SENSOR_QOS = QoSProfile(depth=5)


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
        # The depth image, its publisher and its CameraInfo's, with camera_depth.
        self._depth: Optional[Tuple[Any, Publisher, Publisher]] = None
        self._cloud: Optional[PointCloudTemplate] = None
        if config.camera_point_cloud:
            self._cloud_pub = node.create_publisher(PointCloud2, 'camera/depth/points',
                                                    CAMERA_QOS)
            self._cloud = PointCloudTemplate(frame_id, k.height_px, k.width_px, XYZ)
            self._rays = camera.pixel_rays(k)
        if config.camera_depth:
            depth_pub = node.create_publisher(Image, 'camera/depth/image_raw', CAMERA_QOS)
            depth_info_pub = node.create_publisher(
                CameraInfo, 'camera/depth/camera_info', CAMERA_QOS)
            depth_image = Image(height=k.height_px, width=k.width_px, encoding='32FC1',
                                is_bigendian=0, step=4 * k.width_px)
            depth_image.header.frame_id = frame_id
            self._depth = depth_image, depth_pub, depth_info_pub
        publishers = [self._image_pub, self._info_pub]
        if self._cloud is not None:
            publishers.append(self._cloud_pub)
        if self._depth is not None:
            publishers += self._depth[1:]
        self._demands = [demand(publisher) for publisher in publishers]

    def publish(self, time_ns: int, image: CameraImage) -> None:
        """Publish an image and its CameraInfo (and depth), stamped ``time_ns``."""
        if not any(taken() for taken in self._demands):
            return
        stamp = stamp_of(time_ns)
        info = self._info
        info.header.stamp.sec, info.header.stamp.nanosec = stamp
        _publish_image(self._image, image.rgb, stamp, self._image_pub, info, self._info_pub)
        if self._depth is None and self._cloud is None:
            return
        depth = image.depth
        # The robot renders depth when either is on (camera_depth or camera_point_cloud).
        assert depth is not None, 'the camera publishes depth but rendered none'
        if self._depth is not None:
            depth_image, depth_pub, depth_info_pub = self._depth
            _publish_image(depth_image, depth.astype('<f4').tobytes(), stamp, depth_pub,
                           info, depth_info_pub)
        if self._cloud is not None:
            cloud = self._cloud
            cloud.stamp.set_nanoseconds(time_ns)
            cloud.data.set(camera.depth_points(depth, self._rays))
            self._cloud_pub.publish(cloud.template.to_bytes())


def _publish_image(image: Any, data: bytes, stamp: Tuple[int, int], publisher: Publisher,
                   info: Any, info_publisher: Publisher) -> None:
    """Publish an Image of ``data`` and its (stamped) CameraInfo, the image stamped ``stamp``."""
    image.header.stamp.sec, image.header.stamp.nanosec = stamp
    image.data = data
    publisher.publish(image)
    info_publisher.publish(info)


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
        self._demand = demand(self._publisher)
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
        if not self._demand():
            return
        self._stamp.set_nanoseconds(time_ns)
        self._ranges.set(ranges)
        self._publisher.publish(self._template.to_bytes())


class ImuOutput:
    """
    ``imu`` (sensor_msgs/Imu) at ``imu_rate``, in frame imu_link (REP-145).

    The covariances are the sensor's noise model's: a new model (new noise,
    ``Simulation.restart_noise``) brings its own into the next message.
    """

    def __init__(self, node: Node, config: SimConfig, sensor: ImuSensor) -> None:
        self._publisher = node.create_publisher(Imu, 'imu', SENSOR_QOS)
        self._demand = demand(self._publisher)
        msg = Imu()
        msg.header.frame_id = config.frame(IMU_FRAME_ID)
        self._template = MessageTemplate(msg)
        self._stamp = self._template.stamp()
        self._orientation = self._template.field('orientation')
        self._angular = self._template.field('angular_velocity')
        self._linear = self._template.field('linear_acceleration')
        self._covariances = [self._template.field(f'{quantity}_covariance') for quantity in
                             ('orientation', 'angular_velocity', 'linear_acceleration')]
        self._sensor = sensor
        self._model: Optional[ImuModel] = None  # whose covariances the template holds

    def publish(self, time_ns: int, reading: ImuReading) -> None:
        """Publish a reading taken at ``time_ns``, with the covariances of the noise now."""
        if not self._demand():
            return
        model = self._sensor.model
        if model is not self._model:  # start-up, or restarted noise: maybe another noise
            for slot, covariance in zip(self._covariances, (
                    model.orientation_covariance, model.angular_velocity_covariance,
                    model.linear_acceleration_covariance)):
                slot.set(covariance)
            self._model = model
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
        layout, names = dtype.fields, dtype.names
        if layout is None or names is None:
            raise ValueError(f'a point cloud is laid out as a structured dtype, not {dtype}')
        fields = [PointField(name=name, offset=layout[name][1],
                             datatype=_DATATYPES[layout[name][0].str], count=1)
                  for name in names]
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
        self._demand = demand(self._publisher)
        self._cloud = PointCloudTemplate(config.frame(LIDAR3D_FRAME_ID), geometry.rings,
                                         geometry.samples, XYZIRT)
        self._points = numpy.zeros((geometry.rings, geometry.samples), XYZIRT)
        self._points['ring'] = numpy.arange(geometry.rings, dtype=numpy.uint16)[:, None]

    def publish(self, time_ns: int, points: numpy.ndarray) -> None:
        """Publish a scan's points, (rings, samples, 3), measured at ``time_ns``."""
        if not self._demand():
            return
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
        self._demand = demand(self._publisher)
        # Per status: the template, its stamp, voltage, current, charge, percentage.
        self._templates: Dict[int, Tuple[MessageTemplate, StampSlot, FieldSlot, FieldSlot,
                                         FieldSlot, FieldSlot]] = {}
        for status in (battery.CHARGING, battery.DISCHARGING, battery.FULL):
            msg = BatteryState(temperature=math.nan, capacity=capacity_ah,
                               design_capacity=capacity_ah, power_supply_status=status,
                               power_supply_health=BatteryState.POWER_SUPPLY_HEALTH_GOOD,
                               power_supply_technology=BatteryState.POWER_SUPPLY_TECHNOLOGY_LION,
                               present=True)
            msg.header.frame_id = config.frame(config.base_frame_id)
            template = MessageTemplate(msg)
            self._templates[status] = (
                template, template.stamp(), template.field('voltage'), template.field('current'),
                template.field('charge'), template.field('percentage'))

    def publish(self, time_ns: int, reading: battery.BatteryReading) -> None:
        """Publish the battery as read at ``time_ns``."""
        if not self._demand():
            return
        template, stamp, voltage, current, charge, percentage = self._templates[reading.status]
        stamp.set_nanoseconds(time_ns)
        voltage.set((reading.voltage_v,))
        current.set((reading.current_a,))
        charge.set((reading.charge_ah,))
        percentage.set((reading.percentage,))
        self._publisher.publish(template.to_bytes())
