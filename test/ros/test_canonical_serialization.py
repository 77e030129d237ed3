"""
serialize(): rclpy's bytes with every CDR padding byte zero, so one message is one byte string.

rclpy's serializer leaves alignment padding (and a few bytes past the end)
as whatever its buffer held: the bytes of one message changed with what was
serialized before, and two recordings of one run differed. Here the bytes
that are data are the serializer's own (the message reads back equal), and
the rest are zeros whatever came before.
"""

from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import CameraInfo, Image, Imu, JointState, LaserScan
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from r2d2_sim.ros.cdr import serialize
from r2d2_sim.ros.serialization import MessageTemplate

MESSAGES = [
    JointState(name=['a', 'bcd'], position=[1.0, 2.0], velocity=[], effort=[3.0]),
    JointState(name=['a'], position=[], velocity=[2.0], effort=[]),
    LaserScan(ranges=[1.0] * 7, intensities=[]), Imu(), CameraInfo(d=[0.0] * 5),
    Odometry(child_frame_id='x'), String(data='hello'), Image(data=b'abc', encoding='rgb8'),
    MarkerArray(markers=[Marker(ns='box_1', text='t'), Marker(ns='b')]),
    TFMessage(transforms=[TransformStamped(child_frame_id='ab'), TransformStamped()]),
]


def dirty_the_serializer():
    """Serialize messages full of non-zero bytes: what the next buffer may inherit."""
    for size in (1, 5, 9, 33):
        serialize_message(String(data='\x7f' * size))
        serialize_message(Image(data=b'\xff' * (size * 16)))


@pytest.mark.parametrize('msg', MESSAGES, ids=lambda m: type(m).__name__)
def test_a_message_serializes_to_the_same_bytes_whatever_came_before(msg):
    """Equal bytes after dirtying, the serializer's length, and the message reads back."""
    first = serialize(msg)
    dirty_the_serializer()
    assert serialize(msg) == first
    assert len(first) == len(serialize_message(msg))
    assert deserialize_message(first, type(msg)) == msg


def test_padding_is_where_cdr_puts_it():
    """JointState(name=['a'], position=[1.0]): 3 bytes before the names, 2 before position."""
    data = serialize(JointState(name=['a'], position=[1.0]))[4:]  # after the header
    assert data[13:16] == bytes(3)   # after frame_id '' (4 + 1 bytes from offset 8)
    assert data[26:28] == bytes(2)   # after 'a\\0': the next count aligns to 4
    assert data[48:] == bytes(len(data) - 48)  # past the last count


def test_templates_start_from_the_zeroed_bytes():
    """A MessageTemplate's bytes are serialize()'s: the same in every process."""
    msg = MarkerArray(markers=[Marker(ns='wall', text='x')])
    dirty_the_serializer()
    assert MessageTemplate(msg).to_bytes() == serialize(msg)
