"""
The point clouds on the wire: the depth camera's and the 3D lidar's sensor_msgs/PointCloud2.

Both are pre-serialized templates whose point bytes are copied in; here
the messages a subscriber receives are read back field by field: layout
(organised, fields, offsets, steps), frames, stamps, the depth cloud agreeing
with the depth image and its CameraInfo as depth_image_proc would project
them, the lidar's rings, and both QoS kinds of subscriber receiving them.
"""

import numpy
import pytest
from rclpy.qos import DurabilityPolicy, qos_profile_sensor_data, QoSProfile
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import CameraInfo, Image, PointCloud2, PointField

from helpers import make_sim
from r2d2_sim.ros.serialization import FieldError, MessageTemplate
from r2d2_sim.testing import wait_for

ROOM = 'package://r2d2_sim/urdf/room.urdf'


def listen(ros, topics):
    """Return {topic: received list}, each subscribed on a listener node with its QoS."""
    node = ros.create_node('cloud_listener', use_sim_time=False)
    seen = {}
    for topic, (msg_type, qos) in topics.items():
        seen[topic] = []
        node.create_subscription(msg_type, topic, seen[topic].append, qos)
    return seen


def cloud_array(msg):
    """Return a PointCloud2's points as a structured array shaped (height, width)."""
    types = {PointField.FLOAT32: '<f4', PointField.UINT16: '<u2'}
    dtype = numpy.dtype({'names': [f.name for f in msg.fields],
                         'formats': [types[f.datatype] for f in msg.fields],
                         'offsets': [f.offset for f in msg.fields], 'itemsize': msg.point_step})
    return numpy.frombuffer(bytes(msg.data), dtype).reshape(msg.height, msg.width)


def depth_outputs(ros, width, height):
    """Return the depth camera's cloud, image and CameraInfo of the room after 24 steps."""
    sim = make_sim(ros, world=ROOM, camera_rate=10.0, camera_depth=True,
                   camera_point_cloud=True, camera_width=width, camera_height=height)
    seen = listen(ros, {'camera/depth/points': (PointCloud2, 10),
                        'camera/depth/image_raw': (Image, 10),
                        'camera/depth/camera_info': (CameraInfo, 10)})
    sim.advance(24)
    assert wait_for(lambda: all(seen.values()))
    return tuple(seen[t][-1] for t in ('camera/depth/points', 'camera/depth/image_raw',
                                       'camera/depth/camera_info'))


def test_the_depth_cloud_is_the_depth_image_projected_with_its_camera_info(ros):
    cloud, depth, info = depth_outputs(ros, 64, 48)
    assert (cloud.height, cloud.width, cloud.point_step, cloud.row_step) == (48, 64, 12, 768)
    assert [(f.name, f.offset, f.datatype, f.count) for f in cloud.fields] == [
        ('x', 0, PointField.FLOAT32, 1), ('y', 4, PointField.FLOAT32, 1),
        ('z', 8, PointField.FLOAT32, 1)]
    assert not cloud.is_dense and not cloud.is_bigendian
    assert cloud.header == depth.header and cloud.header.frame_id == 'head_camera_optical'
    points = cloud_array(cloud)
    z = numpy.frombuffer(bytes(depth.data), '<f4').reshape(48, 64)
    finite = numpy.isfinite(z)
    assert 0 < finite.sum() < z.size  # the wall, and the sky above it
    assert numpy.array_equal(points['z'][finite], z[finite])
    assert numpy.isnan(points['x'][~finite]).all() and numpy.isnan(points['z'][~finite]).all()
    fx, cx, fy, cy = info.k[0], info.k[2], info.k[4], info.k[5]
    v, u = numpy.nonzero(finite)
    assert points['x'][finite] == pytest.approx((u - cx) / fx * z[finite], rel=1e-6, abs=1e-6)
    assert points['y'][finite] == pytest.approx((v - cy) / fy * z[finite], rel=1e-6, abs=1e-6)


def test_no_point_cloud_unless_asked(ros):
    sim = make_sim(ros, camera_rate=10.0, camera_depth=True, camera_width=16, camera_height=12)
    topics = [name for name, _ in sim.get_topic_names_and_types()]
    assert '/camera/depth/image_raw' in topics and '/camera/depth/points' not in topics


def test_a_point_cloud_without_the_depth_image(ros):
    """camera_point_cloud alone renders depth for the cloud and publishes no depth image."""
    sim = make_sim(ros, world=ROOM, camera_rate=10.0, camera_point_cloud=True,
                   camera_width=16, camera_height=12)
    seen = listen(ros, {'camera/depth/points': (PointCloud2, qos_profile_sensor_data)})
    sim.advance(24)
    assert wait_for(lambda: seen['camera/depth/points'])
    assert numpy.isfinite(cloud_array(seen['camera/depth/points'][-1])['z']).any()
    topics = [name for name, _ in sim.get_topic_names_and_types()]
    assert '/camera/depth/image_raw' not in topics


def test_the_lidar_cloud_is_laid_out_as_velodyne_drivers_publish(ros):
    sim = make_sim(ros, world=ROOM, lidar3d_rate=10.0, lidar3d_rings=16, lidar3d_samples=900)
    seen = listen(ros, {'points': (PointCloud2, 10)})
    best_effort = listen(ros, {'points': (PointCloud2, qos_profile_sensor_data)})
    sim.advance(24)
    assert wait_for(lambda: seen['points'] and best_effort['points'])
    cloud = seen['points'][-1]
    assert cloud.header.frame_id == 'lidar_3d'
    assert (cloud.header.stamp.sec, cloud.header.stamp.nanosec) == (0, 100_000_000)
    assert (cloud.height, cloud.width) == (16, 900)
    assert (cloud.point_step, cloud.row_step) == (22, 22 * 900)
    assert [(f.name, f.offset, f.datatype) for f in cloud.fields] == [
        ('x', 0, PointField.FLOAT32), ('y', 4, PointField.FLOAT32),
        ('z', 8, PointField.FLOAT32), ('intensity', 12, PointField.FLOAT32),
        ('ring', 16, PointField.UINT16), ('time', 18, PointField.FLOAT32)]
    points = cloud_array(cloud)
    assert (points['ring'] == numpy.arange(16)[:, None]).all()
    assert (points['time'] == 0.0).all() and (points['intensity'] == 0.0).all()
    expected = sim.simulation.robot.lidar.scan()  # nothing moved: the same scan again
    for axis, name in enumerate('xyz'):
        assert numpy.array_equal(points[name], expected[..., axis], equal_nan=True)
    # The rings below the horizon see the room's walls or floor; the highest pass over.
    assert numpy.isfinite(points['x'][0]).all() and numpy.isnan(points['x'][15]).any()


def test_the_lidar_frame_hangs_from_the_body_on_tf_static(ros):
    from tf2_msgs.msg import TFMessage
    sim = make_sim(ros, lidar3d_rate=10.0, lidar3d_samples=90)
    seen = listen(ros, {'/tf_static': (TFMessage, QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))})
    assert wait_for(lambda: seen['/tf_static'])
    mounts = {t.child_frame_id: t for t in seen['/tf_static'][-1].transforms}
    mount = mounts['lidar_3d']
    assert mount.header.frame_id == 'base_link'
    height = sim.simulation.robot.lidar.height_m - sim.simulation.robot.footprint_height_m
    assert mount.transform.translation.z == pytest.approx(height)
    assert mount.transform.rotation.w == 1.0


def test_a_byte_array_template_round_trips_and_refuses_what_it_cannot_find():
    msg = PointCloud2(height=2, width=8, point_step=12, row_step=96)
    msg.data = bytes(192)
    template = MessageTemplate(msg)
    data = template.bytes_field('data')
    values = numpy.arange(48, dtype='<f4').reshape(2, 8, 3)
    data.set(values)
    back = deserialize_message(template.to_bytes(), PointCloud2)
    assert numpy.array_equal(numpy.frombuffer(bytes(back.data), '<f4').reshape(2, 8, 3), values)
    assert back.height == 2 and back.row_step == 96
    with pytest.raises(ValueError, match='expected 192 bytes'):
        data.set(b'\0' * 191)
    with pytest.raises(FieldError, match='not a byte array'):
        template.bytes_field('height')


@pytest.mark.parametrize('count', [0, 1, 12, 15])
def test_a_byte_array_of_a_few_bytes_is_found_too(count):
    """A 1x1 camera's cloud is 12 bytes: too few for a sentinel once, found all the same."""
    msg = PointCloud2(height=1, width=1, point_step=count, row_step=count, is_dense=True)
    msg.data = bytes(count)
    template = MessageTemplate(msg)
    data = template.bytes_field('data')
    values = bytes(range(200, 200 + count))
    data.set(values)
    back = deserialize_message(template.to_bytes(), PointCloud2)
    assert bytes(back.data) == values
    assert back.point_step == count and back.is_dense


def test_a_one_pixel_camera_publishes_its_one_point(ros):
    """camera_width 1 x camera_height 1 with the cloud: one point, the depth pixel projected."""
    cloud, depth, info = depth_outputs(ros, 1, 1)
    assert (cloud.height, cloud.width, cloud.row_step) == (1, 1, 12)
    assert cloud.header == depth.header
    point = cloud_array(cloud)[0, 0]
    z = float(numpy.frombuffer(bytes(depth.data), '<f4')[0])
    assert numpy.isfinite(z)  # the room's wall ahead
    fx, cx, fy, cy = info.k[0], info.k[2], info.k[4], info.k[5]
    assert (point['x'], point['y'], point['z']) == pytest.approx(
        (-cx / fx * z, -cy / fy * z, z), rel=1e-6, abs=1e-6)
