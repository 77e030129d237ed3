"""
The rigid-transform math of model/test_transforms.py against PyBullet's URDF link frames.

This proves that the conventions (rpy order, quaternion layout, origin *
motion, axis normalisation) are the ones the simulator uses.
"""

import pytest

from common import (
    assert_same_transform, classic_urdf_path, PACKAGE_URDF, read, robot)
from r2d2_sim.model.link_tree import LinkTransforms
from r2d2_sim.model.transforms import (
    compose, IDENTITY, inverse, quaternion_from_rpy, Transform)


# Every convention at once: rotated origins, tilted and (for rotations) unnormalised
# axes, a base whose inertial frame is offset and turned, a child inertial frame too.
CONVENTIONS_URDF = """<robot name="conventions">
  <link name="base">
    <inertial><origin xyz="0.1 -0.2 0.3" rpy="0.4 0.5 0.6"/><mass value="2"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.2" iyz="0" izz="0.3"/></inertial>
  </link>
  <link name="upper">
    <inertial><origin xyz="0 0.2 0" rpy="0.3 0 0"/><mass value="1"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
  </link>
  <link name="slider">
    <inertial><mass value="1"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
  </link>
  <link name="spinner">
    <inertial><mass value="1"/>
      <inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
  </link>
  <link name="sensor">
    <inertial><mass value="0.1"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="hinge" type="revolute">
    <parent link="base"/><child link="upper"/>
    <origin xyz="0.5 -0.25 1.0" rpy="0.3 -1.1 2.0"/><axis xyz="1 2 2"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/>
  </joint>
  <joint name="rail" type="prismatic">
    <parent link="upper"/><child link="slider"/>
    <origin xyz="0 0.4 -0.1" rpy="-0.7 0.2 0.9"/><axis xyz="0 -0.6 0.8"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="spin" type="continuous">
    <parent link="slider"/><child link="spinner"/>
    <origin xyz="0.1 0.1 0.1" rpy="1.5 0.1 -2.5"/><axis xyz="-1 0 1"/>
  </joint>
  <joint name="mount" type="fixed">
    <parent link="spinner"/><child link="sensor"/>
    <origin xyz="0.05 0 0.02" rpy="0.2 1.3 -0.4"/>
  </joint>
</robot>
"""


# getLinkState's frames come back rounded to float32 (-0.22 is -0.2199999988079071),
# so agreement stops near 1e-7; each wrong convention we tried was off by far more.
PYBULLET_TOL = 1e-6


def pybullet_matches(urdf_path, positions, base_pose=IDENTITY):
    """Check link_poses against PyBullet's URDF link frames, every link, to PYBULLET_TOL."""
    pybullet = pytest.importorskip('pybullet')
    from pybullet_utils.bullet_client import BulletClient

    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        body = client.loadURDF(urdf_path, flags=pybullet.URDF_USE_INERTIA_FROM_FILE)
        # PyBullet places a base by its inertial frame: put the URDF frame at base_pose.
        inertial = Transform(*client.getDynamicsInfo(body, -1)[3:5])
        client.resetBasePositionAndOrientation(body, *compose(base_pose, inertial))
        joint_index = {}
        link_of_index = {}
        for index in range(client.getNumJoints(body)):
            info = client.getJointInfo(body, index)
            joint_name, link_name = info[1].decode(), info[12].decode()
            joint_index[joint_name] = index
            link_of_index[index] = link_name
        for name, position in positions.items():
            client.resetJointState(body, joint_index[name], position)

        links = LinkTransforms(read(urdf_path), list(positions))
        poses = links.link_poses(list(positions.values()))
        # The base pose PyBullet reports is its inertial frame; undo that offset.
        world_from_root = compose(Transform(*client.getBasePositionAndOrientation(body)),
                                  inverse(inertial))
        assert_same_transform(world_from_root, base_pose, tol=1e-12)
        for index, link_name in link_of_index.items():
            state = client.getLinkState(body, index, computeForwardKinematics=True)
            frame_position, frame_orientation = state[4:6]  # URDF link frame in the world
            assert_same_transform(compose(world_from_root, poses[link_name]),
                                  Transform(frame_position, frame_orientation),
                                  tol=PYBULLET_TOL)
        assert len(poses) == client.getNumJoints(body) + 1
    finally:
        client.disconnect()


def test_package_r2d2_matches_pybullet():
    pybullet_matches(PACKAGE_URDF, {
        'head_swivel': 0.7, 'gripper_extension': -0.1, 'left_front_wheel_joint': 1.3,
        'right_back_wheel_joint': -2.2, 'left_gripper_joint': 0.4,
        'right_gripper_joint': 0.3})


def test_classic_r2d2_matches_pybullet():
    # Its wheels sit on pitched origins and its gripper on a yawed one.
    pybullet_matches(classic_urdf_path(), {
        'head_swivel': 0.7, 'gripper_extension': -0.1, 'left_front_wheel_joint': 1.3,
        'right_gripper_joint': 0.3, 'left_back_wheel_joint': 0.0})


def test_every_convention_matches_pybullet(tmp_path):
    path = tmp_path / 'conventions.urdf'
    path.write_text(CONVENTIONS_URDF)
    pybullet_matches(str(path), {'hinge': 0.9, 'rail': 0.35, 'spin': -2.4},
                     Transform((0.3, -1.0, 0.5), quaternion_from_rpy(0.2, -0.3, 1.9)))


def test_pybullet_scales_prismatic_motion_by_an_unnormalised_axis(tmp_path):
    # We normalise every axis, as KDL (robot_state_publisher) does, but PyBullet moves
    # a prismatic joint by position * axis: with axis (0, 0, 2) and 0.25 m it puts the
    # child at z = 0.5 where we (and TF from robot_state_publisher) say 0.25.
    pybullet = pytest.importorskip('pybullet')
    from pybullet_utils.bullet_client import BulletClient

    inertial = ('<inertial><mass value="1"/>'
                '<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>')
    xml = robot(f'<link name="a">{inertial}</link><link name="b">{inertial}</link>',
                '<joint name="rail" type="prismatic"><parent link="a"/><child link="b"/>'
                '<axis xyz="0 0 2"/><limit lower="-1" upper="1" effort="1" velocity="1"/>'
                '</joint>')
    path = tmp_path / 'rail.urdf'
    path.write_text(xml)
    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        body = client.loadURDF(str(path))
        client.resetJointState(body, 0, 0.25)
        pybullet_z_m = client.getLinkState(body, 0, computeForwardKinematics=True)[4][2]
    finally:
        client.disconnect()
    (edge,) = LinkTransforms(xml).moving([0.25])
    assert edge.transform.translation == (0.0, 0.0, 0.25)
    assert pybullet_z_m == pytest.approx(0.5, abs=PYBULLET_TOL)
