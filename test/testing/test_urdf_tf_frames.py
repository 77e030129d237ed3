"""
A URDF's links and the node's own TF frames: one tree, each frame with one parent.

robot_state_publisher (or ``publish_link_tf``) hangs every URDF link but the
root from its parent; the node publishes odom, base_footprint, the body
frame and its sensors' frames. A TurtleBot3-like URDF names several of
those itself (a review found duplicated children and a loop), and the
classic R2D2's root is turned from the body frame: every link hung off a
turned base_link. Here, in process, what TF then holds.
"""

import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile

from r2d2_sim.testing import HarnessError, SimHarness, wait_for

LATCHED_QOS = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def test_a_transform_that_would_close_a_loop_is_a_harness_error():
    """Someone publishes base_link -> odom: lookup_transform says so, as HarnessError."""
    from tf2_msgs.msg import TFMessage
    from r2d2_sim.model.transforms import IDENTITY
    from r2d2_sim.ros.tf_outputs import _transform_stamped
    with SimHarness(cmd_vel_timeout=0.0) as harness:
        node = harness.create_node('looping_publisher')
        node.create_publisher(TFMessage, '/tf_static', LATCHED_QOS).publish(
            TFMessage(transforms=[_transform_stamped('base_link', 'odom', IDENTITY)]))
        listener = harness.listen_tf()
        # The simulator's /tf_static and this one, each matched and taken: by deadline.
        assert wait_for(lambda: listener.static_received >= 2, 5.0)
        with pytest.raises(HarnessError, match='would make a loop') as raised:
            harness.lookup_transform('odom', 'base_link')
        assert '\n' not in str(raised.value)
