"""
Real serialized messages of a short drive, for the live-view, recording, replay and browser tests.

Built with the rclpy message classes and ``serialize_message``, as the node
builds its own. TFMessage comes from tf2_msgs when it is built in this venv,
and otherwise from rosbags' serializer (its CDR bytes are the same), so no
test has to leave ``/tf`` out.
"""

import itertools
import math
from pathlib import Path
from typing import Dict, Iterator, List, NamedTuple, Optional, Tuple

from builtin_interfaces.msg import Time
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Image, JointState, LaserScan
from std_msgs.msg import String

URDF_PATH = Path(__file__).resolve().parent.parent / 'urdf' / 'r2d2.urdf'
# The URDF's body colour (material "blue", rgba 0 0 0.8 1).
ROBOT_RGB = (0, 0, 204)
BASE_HEIGHT_M = 0.47
ROOM_HALF_SIZE_M = 2.0

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# Topic: (ROS type, the QoS the node publishes it with).
TOPICS: Dict[str, Tuple[str, QoSProfile]] = {
    '/clock': ('rosgraph_msgs/msg/Clock', QoSProfile(depth=10)),
    '/robot_description': ('std_msgs/msg/String', LATCHED),
    '/tf_static': ('tf2_msgs/msg/TFMessage', LATCHED),
    '/tf': ('tf2_msgs/msg/TFMessage', QoSProfile(depth=100)),
    '/odom': ('nav_msgs/msg/Odometry', QoSProfile(depth=10)),
    '/ground_truth': ('nav_msgs/msg/Odometry', QoSProfile(depth=10)),
    '/joint_states': ('sensor_msgs/msg/JointState', QoSProfile(depth=10)),
    '/scan': ('sensor_msgs/msg/LaserScan', QoSProfile(depth=5)),
    '/camera/image_raw': ('sensor_msgs/msg/Image', QoSProfile(depth=2)),
}


class Sample(NamedTuple):
    """One serialized message and the simulated time it was logged at."""

    topic: str
    type_name: str
    time_ns: int
    data: bytes


def stamp(time_ns: int) -> Time:
    """Return a builtin_interfaces/Time."""
    return Time(sec=time_ns // 10**9, nanosec=time_ns % 10**9)


def transform(parent, child, time_ns, x=0.0, y=0.0, z=0.0, yaw=0.0) -> TransformStamped:
    transform = TransformStamped()
    transform.header.stamp = stamp(time_ns)
    transform.header.frame_id = parent
    transform.child_frame_id = child
    transform.transform.translation.x = x
    transform.transform.translation.y = y
    transform.transform.translation.z = z
    transform.transform.rotation.z = math.sin(yaw / 2.0)
    transform.transform.rotation.w = math.cos(yaw / 2.0)
    return transform


def tf_message_bytes(transforms: List[TransformStamped]) -> bytes:
    """Serialize a TFMessage: with tf2_msgs when built, else with rosbags (same bytes)."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError:
        return _tf_message_bytes_rosbags(transforms)
    return serialize_message(TFMessage(transforms=transforms))


def _tf_message_bytes_rosbags(transforms: List[TransformStamped]) -> bytes:
    from rosbags.typesys import get_typestore, Stores
    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types

    def convert(t):
        header = types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](
                sec=t.header.stamp.sec, nanosec=t.header.stamp.nanosec),
            frame_id=t.header.frame_id)
        v, q = t.transform.translation, t.transform.rotation
        return types['geometry_msgs/msg/TransformStamped'](
            header=header, child_frame_id=t.child_frame_id,
            transform=types['geometry_msgs/msg/Transform'](
                translation=types['geometry_msgs/msg/Vector3'](x=v.x, y=v.y, z=v.z),
                rotation=types['geometry_msgs/msg/Quaternion'](x=q.x, y=q.y, z=q.z, w=q.w)))
    message = types['tf2_msgs/msg/TFMessage'](transforms=[convert(t) for t in transforms])
    return bytes(store.serialize_cdr(message, 'tf2_msgs/msg/TFMessage'))


def pose_at(time_s: float) -> Tuple[float, float, float]:
    """Return the true (x, y, yaw) of the drive: 0.3 m/s on a left circle of radius 1 m."""
    yaw = 0.3 * time_s
    return math.sin(yaw), 1.0 - math.cos(yaw), yaw


def _odometry(time_ns, frame, child, x, y, yaw) -> Odometry:
    msg = Odometry()
    msg.header.stamp = stamp(time_ns)
    msg.header.frame_id = frame
    msg.child_frame_id = child
    msg.pose.pose.position.x = x
    msg.pose.pose.position.y = y
    msg.pose.pose.orientation.z = math.sin(yaw / 2.0)
    msg.pose.pose.orientation.w = math.cos(yaw / 2.0)
    msg.twist.twist.linear.x = 0.3
    msg.twist.twist.angular.z = 0.3
    return msg


def _scan(time_ns, x, y, yaw, beams=180) -> LaserScan:
    """Return a scan of the square room's walls from (x, y, yaw), in base_link."""
    msg = LaserScan()
    msg.header.stamp = stamp(time_ns)
    msg.header.frame_id = 'base_link'
    msg.angle_min = -math.pi
    msg.angle_increment = 2 * math.pi / beams
    msg.angle_max = msg.angle_min + msg.angle_increment * (beams - 1)
    msg.range_min = 0.05
    msg.range_max = 10.0
    ranges = []
    for i in range(beams):
        angle = yaw + msg.angle_min + i * msg.angle_increment
        dx, dy = math.cos(angle), math.sin(angle)
        hits = [(math.copysign(ROOM_HALF_SIZE_M, d) - p) / d
                for d, p in ((dx, x), (dy, y)) if abs(d) > 1e-9]
        ranges.append(min(hits))
    msg.ranges = ranges
    return msg


def _image(time_ns, width=64, height=48) -> Image:
    msg = Image()
    msg.header.stamp = stamp(time_ns)
    msg.header.frame_id = 'head_camera'
    msg.width, msg.height, msg.encoding, msg.step = width, height, 'rgb8', width * 3
    shift = time_ns // 10**8
    msg.data = bytes((x * 4 + shift) % 256 if c == 0 else (y * 5) % 256 if c == 1 else 128
                     for y in range(height) for x in range(width) for c in range(3))
    return msg


def robot_description() -> bytes:
    """Return ``/robot_description``: the package's URDF in a std_msgs/String."""
    return serialize_message(String(data=URDF_PATH.read_text()))


def static_transforms() -> bytes:
    """Return ``/tf_static``: base_footprint -> base_link, the body's height."""
    return tf_message_bytes([transform('base_footprint', 'base_link', 0, z=BASE_HEIGHT_M)])


def drive(duration_s: Optional[float] = 1.0, clock_hz: int = 50, scan_hz: int = 10,
          image_hz: int = 5, start_ns: int = 0) -> Iterator[Sample]:
    """
    Yield a drive of ``duration_s`` (None: endless) as the node would log it, in time order.

    The latched topics come first (at ``start_ns``); then at each clock tick
    /clock, /tf (odom -> base_footprint), /odom, /ground_truth and
    /joint_states, with /scan and the camera at their own rates.
    """
    yield Sample('/robot_description', TOPICS['/robot_description'][0], start_ns,
                 robot_description())
    yield Sample('/tf_static', TOPICS['/tf_static'][0], start_ns, static_transforms())
    period_ns = 10**9 // clock_hz
    ticks = itertools.count() if duration_s is None else range(round(duration_s * clock_hz) + 1)
    for tick in ticks:
        time_ns = start_ns + tick * period_ns
        x, y, yaw = pose_at(time_ns * 1e-9)
        odom_x, odom_y = 0.97 * x, 0.95 * y  # wheel odometry drifts from the truth

        def sample(topic, data):
            return Sample(topic, TOPICS[topic][0], time_ns, data)
        yield sample('/clock', serialize_message(Clock(clock=stamp(time_ns))))
        yield sample('/tf', tf_message_bytes(
            [transform('odom', 'base_footprint', time_ns, odom_x, odom_y, yaw=yaw)]))
        yield sample('/odom', serialize_message(
            _odometry(time_ns, 'odom', 'base_footprint', odom_x, odom_y, yaw)))
        yield sample('/ground_truth', serialize_message(
            _odometry(time_ns, 'world', 'base_footprint', x, y, yaw)))
        joints = JointState(name=['left_wheel', 'right_wheel'], position=[tick * 0.1, tick * 0.12])
        joints.header.stamp = stamp(time_ns)
        yield sample('/joint_states', serialize_message(joints))
        if tick % (clock_hz // scan_hz) == 0:
            yield sample('/scan', serialize_message(_scan(time_ns, odom_x, odom_y, yaw)))
        if tick % (clock_hz // image_hz) == 0:
            yield sample('/camera/image_raw', serialize_message(_image(time_ns)))


def samples(duration_s: float = 1.0, **rates) -> List[Sample]:
    """Return :func:`drive` of ``duration_s`` as a list."""
    return list(drive(duration_s, **rates))


def message_class(type_name: str):
    """Import the rclpy class of ``pkg/msg/Type`` (ImportError when its package is missing)."""
    import importlib
    package, namespace, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{namespace}'), name)
