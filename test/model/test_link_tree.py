"""
The URDF link tree (joints as parent -> child transforms), checked by hand.

The cross-check against PyBullet's own link poses is in
physics/test_transforms_physics.py.
"""

import math

import pytest

from common import assert_same_transform, classic_urdf_path, PACKAGE_URDF, read, robot
from r2d2_sim.model.link_tree import (
    joint_transform, JointModel, LinkTransforms, parse_joints, root_link)
from r2d2_sim.model.transforms import apply, IDENTITY, quaternion_from_rpy, Transform

HALF_SQRT2 = math.sqrt(0.5)
ONE_X_YAW90 = Transform((1.0, 0.0, 0.0), quaternion_from_rpy(0.0, 0.0, math.pi / 2))
R2D2_MOVING = {
    'left_front_wheel_joint', 'left_back_wheel_joint', 'right_front_wheel_joint',
    'right_back_wheel_joint', 'head_swivel', 'gripper_extension', 'left_gripper_joint',
    'right_gripper_joint',
}


# --------------------------------------------------------------------------- joints


def joint(joint_type, axis=(0.0, 0.0, 1.0), origin=Transform((1.0, 0.0, 0.0), IDENTITY.rotation)):
    return JointModel('j', joint_type, 'parent', 'child', origin, axis)


@pytest.mark.parametrize('joint_type', ['revolute', 'continuous'])
def test_revolute_about_z(joint_type):
    # Origin (1, 0, 0), 90 degrees about z: child (1, 0, 0) -> (0, 1, 0) + (1, 0, 0).
    t = joint_transform(joint(joint_type), math.pi / 2)
    assert apply(t, (1.0, 0.0, 0.0)) == pytest.approx((1.0, 1.0, 0.0), abs=1e-15)


def test_prismatic_moves_along_axis_in_joint_frame():
    # Origin (1, 0, 0) turned 90 degrees about z; axis (0, 0.6, 0.8); 0.5 m moves
    # (0, 0.3, 0.4) in the joint frame = (-0.3, 0, 0.4) in the parent: (0.7, 0, 0.4).
    t = joint_transform(joint('prismatic', (0.0, 0.6, 0.8), ONE_X_YAW90), 0.5)
    assert t.translation == pytest.approx((0.7, 0.0, 0.4), abs=1e-15)
    assert t.rotation == pytest.approx(ONE_X_YAW90.rotation, abs=1e-15)


@pytest.mark.parametrize('joint_type', ['fixed', 'planar', 'floating'])
def test_other_joints_stay_at_origin(joint_type):
    assert joint_transform(joint(joint_type), 0.8) == joint(joint_type).origin


def test_parse_defaults_and_normalised_axis():
    joints = parse_joints(robot(
        '<joint name="a" type="revolute"><parent link="p"/><child link="c"/></joint>',
        '<joint name="b" type="prismatic"><parent link="c"/><child link="d"/>'
        '<origin xyz="1 2 3" rpy="0 0 1.5707963267948966"/><axis xyz="0 3 -4"/></joint>',
        # A transmission names a joint without being one.
        '<transmission name="t"><joint name="a"/></transmission>'))
    assert [j.name for j in joints] == ['a', 'b']
    assert joints[0] == JointModel('a', 'revolute', 'p', 'c', IDENTITY, (1.0, 0.0, 0.0))
    assert joints[1].origin.translation == (1.0, 2.0, 3.0)
    assert joints[1].origin.rotation == pytest.approx((0, 0, HALF_SQRT2, HALF_SQRT2))
    assert joints[1].axis == pytest.approx((0.0, 0.6, -0.8), abs=1e-15)
    assert root_link(joints) == 'p'


def test_fixed_joint_axis_is_not_read():
    # urdfdom ignores <axis> on fixed joints, so a zero one there is no error.
    (fixed,) = parse_joints(robot(
        '<joint name="f" type="fixed"><parent link="p"/><child link="c"/>'
        '<axis xyz="0 0 0"/></joint>'))
    assert fixed.axis == (1.0, 0.0, 0.0)


@pytest.mark.parametrize('body, message', [
    ('<origin xyz="1 2"/>', 'xyz="1 2"'),
    ('<origin xyz="1 2 x"/>', 'xyz="1 2 x"'),
    ('<origin rpy="0 nan 0"/>', 'rpy="0 nan 0"'),
    ('<axis xyz="0 0 0"/>', 'axis'),
    ('<axis xyz="1,0,0"/>', 'xyz="1,0,0"'),
])
def test_parse_names_the_joint_with_a_malformed_number(body, message):
    xml = robot(f'<joint name="elbow" type="revolute"><parent link="p"/><child link="c"/>'
                f'{body}</joint>')
    with pytest.raises(ValueError, match="'elbow'") as error:
        parse_joints(xml)
    assert message in str(error.value)


@pytest.mark.parametrize('xml, message', [
    (robot('<joint name="j" type="fixed"><child link="c"/></joint>'), 'parent'),
    (robot('<joint name="j"><parent link="p"/><child link="c"/></joint>'), 'type'),
    (robot('<joint type="fixed"/>'), 'without a name'),
    ('<robot><joint</robot>', 'well-formed'),
])
def test_parse_refuses_incomplete_joints(xml, message):
    with pytest.raises(ValueError, match=message):
        parse_joints(xml)


def fixed_joint(name, parent, child):
    return (f'<joint name="{name}" type="fixed">'
            f'<parent link="{parent}"/><child link="{child}"/></joint>')


@pytest.mark.parametrize('joints, message', [
    ([], 'no joints'),
    ([fixed_joint('a', 'p', 'c'), fixed_joint('b', 'q', 'd')], "roots \\['p', 'q'\\]"),
    ([fixed_joint('a', 'p', 'c'), fixed_joint('b', 'q', 'c')], 'child of two joints'),
    ([fixed_joint('a', 'p', 'c'), fixed_joint('a', 'c', 'd')], 'two joints are named'),
    ([fixed_joint('a', 'p', 'c'), fixed_joint('b', 'd', 'e'), fixed_joint('c', 'e', 'd')],
     'cycle'),
])
def test_root_link_refuses_what_is_not_a_tree(joints, message):
    with pytest.raises(ValueError, match=message):
        root_link(parse_joints(robot(*joints)))


# --------------------------------------------------------------------------- LinkTransforms

ARM = robot(
    fixed_joint('mount', 'base', 'shoulder'),
    '<joint name="elbow" type="revolute"><parent link="shoulder"/><child link="forearm"/>'
    '<origin xyz="1 0 0"/><axis xyz="0 0 1"/></joint>',
    '<joint name="slide" type="prismatic"><parent link="forearm"/><child link="hand"/>'
    '<origin xyz="1 0 0"/><axis xyz="1 0 0"/></joint>',
    '<joint name="wobble" type="planar"><parent link="base"/><child link="tray"/>'
    '<origin xyz="0 0 2"/></joint>')


def test_link_transforms_default_split_and_order():
    links = LinkTransforms(ARM)
    assert links.root_link == 'base'
    assert links.moving_joint_names == ('elbow', 'slide')
    # Elbow 90 degrees: forearm turned left; slide 0.5 m: hand 1.5 m along forearm x.
    elbow, slide = links.moving([math.pi / 2, 0.5])
    assert (elbow.parent_link, elbow.child_link) == ('shoulder', 'forearm')
    assert_same_transform(elbow.transform, ONE_X_YAW90)
    assert (slide.parent_link, slide.child_link) == ('forearm', 'hand')
    assert slide.transform == Transform((1.5, 0.0, 0.0), IDENTITY.rotation)
    # The planar joint stays at its origin and is published with the fixed ones.
    assert [(e.parent_link, e.child_link, e.transform.translation) for e in links.fixed()] == [
        ('base', 'shoulder', (0.0, 0.0, 0.0)), ('base', 'tray', (0.0, 0.0, 2.0))]


def test_link_transforms_follows_the_given_order():
    links = LinkTransforms(ARM, ['slide', 'wobble', 'elbow'])
    edges = links.moving([0.5, 123.0, math.pi / 2])
    assert [e.child_link for e in edges] == ['hand', 'tray', 'forearm']
    assert edges[1].transform.translation == (0.0, 0.0, 2.0)  # planar: position ignored
    assert [e.child_link for e in links.fixed()] == ['shoulder']


def test_link_poses_compose_from_the_root():
    # Elbow at (1, 0, 0) turned 90 degrees; the hand 1.5 m along the forearm's x = parent y.
    poses = LinkTransforms(ARM).link_poses([math.pi / 2, 0.5])
    assert poses['base'] == IDENTITY
    assert poses['hand'].translation == pytest.approx((1.0, 1.5, 0.0), abs=1e-15)
    assert poses['tray'].translation == (0.0, 0.0, 2.0)
    assert set(poses) == {'base', 'shoulder', 'forearm', 'hand', 'tray'}


@pytest.mark.parametrize('names, message', [
    (['elbow', 'knee'], "\\['knee'\\] are not in the URDF"),
    (['elbow', 'elbow'], 'repeat'),
])
def test_link_transforms_refuses_bad_names(names, message):
    with pytest.raises(ValueError, match=message):
        LinkTransforms(ARM, names)


def test_moving_refuses_wrong_number_of_positions():
    with pytest.raises(ValueError, match='expected 2 joint positions'):
        LinkTransforms(ARM).moving([0.0])


def test_urdf_without_joints():
    links = LinkTransforms('<robot name="box"><link name="box"/></robot>')
    assert links.root_link is None
    assert (links.moving([]), links.fixed(), links.link_poses([])) == ([], [], {})


# --------------------------------------------------------------------------- R2D2


@pytest.mark.parametrize('path', [PACKAGE_URDF, 'classic'])
def test_r2d2_tree(path):
    xml = read(classic_urdf_path() if path == 'classic' else path)
    joints = parse_joints(xml)
    assert len(joints) == 15
    assert root_link(joints) == 'base_link'
    links = LinkTransforms(xml)
    assert set(links.moving_joint_names) == R2D2_MOVING
    assert len(links.moving([0.0] * 8)) == 8
    assert len(links.fixed()) == 7
    # Every link but the root has exactly one parent transform.
    children = [e.child_link for e in links.moving([0.0] * 8) + links.fixed()]
    assert sorted(children) == sorted(j.child_link for j in joints)
