"""
A URDF's links and the node's own TF frames: one tree, each frame with one parent.

robot_state_publisher (or ``publish_link_tf``) hangs every URDF link but the
root from its parent; the node publishes odom, base_footprint, the body
frame and its sensors' frames. A TurtleBot3-like URDF names several of
those itself (a review found duplicated children and a loop), and the
classic R2D2's root is turned from the body frame: every link hung off a
turned base_link. Here, in process, what TF then holds.
"""

import math

import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile

from common import classic_params
from r2d2_sim.model.link_tree import LinkTransforms
from r2d2_sim.model.transforms import rotation_matrix
from r2d2_sim.testing import HarnessError, SimHarness, StartupError, wait_for

LATCHED_QOS = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
INERTIA = '<inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="1e-4"/>'


def _link(name, geometry='', mass=0.1):
    collision = f'<collision><geometry>{geometry}</geometry></collision>' if geometry else ''
    return (f'<link name="{name}">{collision}<inertial><mass value="{mass}"/>{INERTIA}'
            '</inertial></link>')


def _joint(name, kind, parent, child, xyz, rpy='0 0 0', axis=''):
    limit = '<limit effort="1.0" velocity="10.0"/>' if kind == 'continuous' else ''
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{xyz}" rpy="{rpy}"/>{axis}{limit}</joint>')


# As a TurtleBot3's URDF: root base_footprint, base_link 1 cm up, base_scan and imu_link on it.
TB3_LIKE = ''.join([
    '<?xml version="1.0"?><robot name="tb3ish">',
    _link('base_footprint'),
    _joint('base_joint', 'fixed', 'base_footprint', 'base_link', '0 0 0.010'),
    _link('base_link', '<box size="0.14 0.14 0.14"/>', 0.8).replace(
        '<geometry>', '<origin xyz="-0.032 0 0.07"/><geometry>'),
    _joint('wheel_left_joint', 'continuous', 'base_link', 'wheel_left_link', '0 0.08 0.023',
           '-1.57 0 0', '<axis xyz="0 0 1"/>'),
    _link('wheel_left_link', '<cylinder length="0.018" radius="0.033"/>', 0.03),
    _joint('wheel_right_joint', 'continuous', 'base_link', 'wheel_right_link', '0 -0.08 0.023',
           '-1.57 0 0', '<axis xyz="0 0 1"/>'),
    _link('wheel_right_link', '<cylinder length="0.018" radius="0.033"/>', 0.03),
    _joint('caster_back_joint', 'fixed', 'base_link', 'caster_back_link', '-0.081 0 -0.004'),
    _link('caster_back_link', '<sphere radius="0.006"/>', 0.005),
    _joint('imu_joint', 'fixed', 'base_link', 'imu_link', '-0.032 0 0.068'),
    _link('imu_link'),
    _joint('scan_joint', 'fixed', 'base_link', 'base_scan', '-0.032 0 0.172'),
    _link('base_scan', '<cylinder length="0.0315" radius="0.055"/>', 0.114),
    '</robot>'])
TB3_DRIVE = {'robot_description': TB3_LIKE, 'left_wheel_names': ['wheel_left_joint'],
             'right_wheel_names': ['wheel_right_joint'], 'cmd_vel_timeout': 0.0}


def static_children(harness):
    """Return every child frame on /tf_static, once per time it is published."""
    from tf2_msgs.msg import TFMessage
    got = []
    harness.create_node('static_listener').create_subscription(
        TFMessage, '/tf_static', got.append, LATCHED_QOS)
    harness.advance()
    return [t.child_frame_id for msg in got for t in msg.transforms]


@pytest.mark.parametrize('publish_link_tf', [False, True])
def test_a_urdf_naming_the_nodes_frames_is_refused_in_one_line(publish_link_tf):
    """TurtleBot3's names: each clash and the parameter to change, not two trees in one."""
    with pytest.raises(StartupError) as refused:
        SimHarness(**TB3_DRIVE, publish_link_tf=publish_link_tf)
    text = str(refused.value)
    assert '\n' not in text
    for clash in ("'base_footprint' (parameter footprint_frame_id)",
                  "'base_link' (parameter base_frame_id)",
                  "'base_scan' (the laser's frame: scan_rate > 0)",
                  "'imu_link' (the IMU's frame: imu_rate > 0)",
                  "base_frame_id may name the URDF's root link 'base_footprint'"):
        assert clash in text


def test_the_urdf_root_as_base_frame_id_gives_one_tree():
    """The refusal's advice taken: the URDF's links below the node's, each frame once."""
    with SimHarness(**TB3_DRIVE, footprint_frame_id='footprint',
                    base_frame_id='base_footprint', scan_rate=0.0, imu_rate=0.0,
                    publish_link_tf=True) as harness:
        children = static_children(harness)
        assert len(children) == len(set(children))
        assert {'base_footprint', 'base_link', 'base_scan', 'imu_link'} <= set(children)
        scan = harness.lookup_transform('base_footprint', 'base_scan')
        assert scan.translation == pytest.approx((-0.032, 0.0, 0.182))
        harness.lookup_transform('odom', 'base_scan')  # one tree: odom to the URDF's links


def test_a_turned_urdf_root_named_as_base_frame_id_is_refused_in_one_line():
    """The classic R2D2 with base_frame_id base_link: its root, turned 90 deg; TF has one."""
    params = {**classic_params(), 'base_frame_id': 'base_link'}
    with pytest.raises(StartupError, match=r"parameter base_frame_id names the URDF's root "
                       r"link 'base_link', which base_forward_axis y turns") as refused:
        SimHarness(**params)
    assert '\n' not in str(refused.value)


def publish_like_robot_state_publisher(harness):
    """Publish the URDF's joints at the joint readout's positions, as robot_state_publisher."""
    from tf2_msgs.msg import TFMessage
    from r2d2_sim.ros.tf_outputs import _transform_stamped
    joints = harness.joint_states()
    links = LinkTransforms(harness.sim.simulation.robot.description, list(joints.name))
    edges = links.fixed() + links.moving(list(joints.position))
    node = harness.create_node('robot_state_publisher_like')
    publisher = node.create_publisher(TFMessage, '/tf_static', LATCHED_QOS)
    publisher.publish(TFMessage(transforms=[
        _transform_stamped(e.parent_link, e.child_link, e.transform) for e in edges]))
    return node


def test_the_classic_r2d2s_camera_looks_forward_through_robot_state_publishers_tf():
    """
    classic_r2d2.yaml, robot_state_publisher's links: the optical axis is the robot's forward.

    The node hangs the URDF's turned root (base_link) from its body frame
    (base_body), link transforms or not; the links once hung off a base_link
    that was the body frame, 90 deg off, camera and depth cloud too.
    """
    with SimHarness(**classic_params(), camera_rate=5.0) as harness:
        harness.advance()
        listener = harness.listen_tf()
        publish_like_robot_state_publisher(harness)
        # The simulator's /tf_static and robot_state_publisher's, each taken: by deadline.
        assert wait_for(lambda: listener.static_received >= 2, 5.0)
        optical = harness.lookup_transform('odom', 'head_camera_optical')
        axis = [row[2] for row in rotation_matrix(optical.rotation)]  # its z in odom
        assert axis == pytest.approx([1.0, 0.0, 0.0], abs=0.02)  # it faces +x (REP-103)
        root = harness.lookup_transform('base_body', 'base_link')
        assert root.rotation == pytest.approx((0.0, 0.0, -math.sqrt(0.5), math.sqrt(0.5)))


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
