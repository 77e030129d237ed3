"""The transform buffer of model/test_tf_buffer.py fed a real tf2_msgs message."""

import math

import pytest

from common import approx, yaw
from r2d2_sim.model.tf_buffer import TransformBuffer


def test_a_real_tf2_msgs_message_feeds_the_buffer():
    """tf2_msgs/msg/TFMessage itself (built by tools/build_tf2_msgs.sh on pip-only machines)."""
    tf2_msgs = pytest.importorskip('tf2_msgs.msg')
    from geometry_msgs.msg import TransformStamped
    t = TransformStamped()
    t.header.frame_id, t.child_frame_id = 'odom', 'base_footprint'
    t.header.stamp.sec, t.header.stamp.nanosec = 2, 250_000_000
    t.transform.translation.x = 1.5
    t.transform.rotation.z, t.transform.rotation.w = yaw(math.pi)[2:]
    buffer = TransformBuffer()
    assert buffer.add_tf_message(tf2_msgs.TFMessage(transforms=[t])) == 1
    assert buffer.transform_point('odom', 'base_footprint', (1.0, 0.0, 0.0)) == \
        approx((0.5, 0.0, 0.0))
    assert buffer.lookup_transform('odom', 'base_footprint').stamp_ns == 2_250_000_000
