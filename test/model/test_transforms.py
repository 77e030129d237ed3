"""
Rigid-transform math and the URDF link tree, checked by hand.

The hand checks use right angles, where every number is 0, 1 or a simple sum;
the cross-check against PyBullet, which proves that the conventions (rpy order,
quaternion layout, origin * motion, axis normalisation) are the ones the
simulator uses, is in physics/test_transforms_physics.py.
"""

import math

import pytest

from common import (
    assert_same_transform, classic_urdf_path, matrix_of, PACKAGE_URDF, read, robot)
from r2d2_sim.model.transforms import (
    apply, compose, IDENTITY, inverse, joint_transform, JointModel, LinkTransforms,
    parse_joints, quaternion_from_axis_angle, quaternion_from_rpy, quaternion_multiply,
    root_link, rotate, rotate_inverse, rotation_matrix, split_yaw, Transform, yaw_of,
)

HALF_SQRT2 = math.sqrt(0.5)
R2D2_MOVING = {
    'left_front_wheel_joint', 'left_back_wheel_joint', 'right_front_wheel_joint',
    'right_back_wheel_joint', 'head_swivel', 'gripper_extension', 'left_gripper_joint',
    'right_gripper_joint',
}


def matmul(a, b):
    return [[sum(a[r][k] * b[k][c] for k in range(3)) for c in range(3)] for r in range(3)]


# --------------------------------------------------------------------------- quaternions


def test_quaternion_multiply_unit_axes():
    # i j = k, j i = -k, i i = -1 in (x, y, z, w) layout.
    i, j = (1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0)
    assert quaternion_multiply(i, j) == (0.0, 0.0, 1.0, 0.0)
    assert quaternion_multiply(j, i) == (0.0, 0.0, -1.0, 0.0)
    assert quaternion_multiply(i, i) == (0.0, 0.0, 0.0, -1.0)


def test_quaternion_multiply_applies_right_factor_first():
    # Roll 90 then yaw 90 (= yaw * roll): y -> z -> z, x -> x -> y.
    roll = quaternion_from_rpy(math.pi / 2, 0.0, 0.0)
    yaw = quaternion_from_rpy(0.0, 0.0, math.pi / 2)
    q = quaternion_multiply(yaw, roll)
    assert rotate(q, (0.0, 1.0, 0.0)) == pytest.approx((0.0, 0.0, 1.0), abs=1e-15)
    assert rotate(q, (1.0, 0.0, 0.0)) == pytest.approx((0.0, 1.0, 0.0), abs=1e-15)


@pytest.mark.parametrize('rpy, vector, image', [
    ((math.pi / 2, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),   # roll 90: y -> z
    ((0.0, math.pi / 2, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0)),   # pitch 90: z -> x
    ((0.0, 0.0, math.pi / 2), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),   # yaw 90: x -> y
])
def test_single_rpy_angles(rpy, vector, image):
    assert rotate(quaternion_from_rpy(*rpy), vector) == pytest.approx(image, abs=1e-15)


def test_rpy_is_fixed_axis_roll_first():
    # rpy (90, 0, 90): roll about fixed x, then yaw about fixed z.
    #   x -> x -> y,  y -> z -> z,  z -> -y -> x.
    # (Intrinsic X-Y-Z, the wrong reading, would send x -> y -> z instead.)
    q = quaternion_from_rpy(math.pi / 2, 0.0, math.pi / 2)
    assert matrix_of(q) == [pytest.approx(row, abs=1e-15)
                            for row in ([0, 0, 1], [1, 0, 0], [0, 1, 0])]


def test_rpy_matches_hand_built_matrix():
    roll, pitch, yaw = 0.1, -0.7, 2.3
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rx = [[1, 0, 0], [0, cr, -sr], [0, sr, cr]]
    ry = [[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]]
    rz = [[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]]
    expected = matmul(rz, matmul(ry, rx))
    q = quaternion_from_rpy(roll, pitch, yaw)
    assert math.fsum(c * c for c in q) == pytest.approx(1.0, abs=1e-15)
    for row, expected_row in zip(matrix_of(q), expected):
        assert row == pytest.approx(expected_row, abs=1e-15)


def test_axis_angle_normalises_axis():
    # 90 degrees about (0, 0, 2): (0, 0, sin 45, cos 45).
    assert quaternion_from_axis_angle((0.0, 0.0, 2.0), math.pi / 2) == pytest.approx(
        (0.0, 0.0, HALF_SQRT2, HALF_SQRT2), abs=1e-15)
    # 120 degrees about (1, 1, 1) cycles the axes: x -> y -> z -> x.
    q = quaternion_from_axis_angle((1.0, 1.0, 1.0), 2 * math.pi / 3)
    assert rotate(q, (1.0, 0.0, 0.0)) == pytest.approx((0.0, 1.0, 0.0), abs=1e-15)


@pytest.mark.parametrize('axis', [(0.0, 0.0, 0.0), (math.nan, 0.0, 1.0)])
def test_axis_angle_refuses_degenerate_axis(axis):
    with pytest.raises(ValueError, match='axis'):
        quaternion_from_axis_angle(axis, 1.0)


def test_yaw_of_ignores_roll_pitch_and_scale():
    q = quaternion_from_rpy(0.3, -0.4, 0.7)
    assert yaw_of(q) == pytest.approx(0.7, abs=1e-15)
    assert yaw_of(tuple(-3.0 * c for c in q)) == pytest.approx(0.7, abs=1e-15)
    assert yaw_of(quaternion_from_rpy(0.0, 0.0, math.pi)) == pytest.approx(math.pi)


@pytest.mark.parametrize('rpy', [
    (0.0, 0.0, 0.0), (0.3, -0.2, 0.7), (-1.0, 0.5, -2.9), (0.0, 0.0, math.pi), (3.0, 1.2, 1.0),
])
def test_split_yaw_reconstructs_with_level_tilt(rpy):
    q = quaternion_from_rpy(*rpy)
    yaw_q, tilt_q = split_yaw(q)
    assert yaw_q[:2] == (0.0, 0.0)  # about z only
    assert yaw_of(tilt_q) == pytest.approx(0.0, abs=1e-15)
    assert_same_transform(Transform((0, 0, 0), quaternion_multiply(yaw_q, tilt_q)),
                          Transform((0, 0, 0), q), tol=1e-15)


def test_split_yaw_hand_values():
    # rpy (0.3, 0.2, 0.7) = yaw 0.7 * rpy (0.3, 0.2, 0): the tilt is the roll and pitch.
    yaw_q, tilt_q = split_yaw(quaternion_from_rpy(0.3, 0.2, 0.7))
    assert yaw_q == pytest.approx((0.0, 0.0, math.sin(0.35), math.cos(0.35)), abs=1e-15)
    assert tilt_q == pytest.approx(quaternion_from_rpy(0.3, 0.2, 0.0), abs=1e-15)


# --------------------------------------------------------------------------- transforms

# Child 1 m along the parent's x and turned 90 degrees about z.
ONE_X_YAW90 = Transform((1.0, 0.0, 0.0), quaternion_from_rpy(0.0, 0.0, math.pi / 2))


def test_apply_rotates_then_translates():
    # Child x is parent y: child (1, 0, 3) -> (0, 1, 3) + (1, 0, 0) = (1, 1, 3).
    assert apply(ONE_X_YAW90, (1.0, 0.0, 3.0)) == pytest.approx((1.0, 1.0, 3.0), abs=1e-15)


def test_compose_expresses_b_in_a_child_frame():
    # Twice "1 m forward, turn left": (1, 0) then 1 m along the new heading +y -> (1, 1),
    # heading 180 degrees.
    twice = compose(ONE_X_YAW90, ONE_X_YAW90)
    assert_same_transform(twice, Transform((1.0, 1.0, 0.0), (0.0, 0.0, 1.0, 0.0)))
    assert apply(twice, (1.0, 0.0, 0.0)) == pytest.approx(
        apply(ONE_X_YAW90, apply(ONE_X_YAW90, (1.0, 0.0, 0.0))), abs=1e-15)


def test_inverse_hand_value():
    # Parent origin seen from the child: 1 m behind along parent x = child -y.
    assert_same_transform(inverse(ONE_X_YAW90),
                          Transform((0.0, 1.0, 0.0), quaternion_from_rpy(0.0, 0.0, -math.pi / 2)))


@pytest.mark.parametrize('t', [
    ONE_X_YAW90,
    Transform((0.3, -1.2, 2.5), quaternion_from_rpy(0.4, -1.1, 2.9)),
    IDENTITY,
])
def test_compose_inverse_round_trips(t):
    other = Transform((-0.5, 0.25, 4.0), quaternion_from_rpy(-2.0, 0.3, 0.1))
    assert_same_transform(compose(t, inverse(t)), IDENTITY)
    assert_same_transform(compose(inverse(t), t), IDENTITY)
    assert_same_transform(compose(inverse(t), compose(t, other)), other)
    assert apply(inverse(t), apply(t, (0.7, -0.1, 0.2))) == pytest.approx((0.7, -0.1, 0.2))


def test_compose_is_associative():
    a = Transform((1.0, 2.0, 3.0), quaternion_from_rpy(0.1, 0.2, 0.3))
    b = Transform((-1.0, 0.5, 0.0), quaternion_from_rpy(-0.4, 0.8, 1.5))
    c = Transform((0.0, 0.0, 2.0), quaternion_from_rpy(2.0, -0.1, -0.6))
    assert_same_transform(compose(compose(a, b), c), compose(a, compose(b, c)))


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


def test_rotation_matrix_and_inverse_rotation_agree_with_rotate():
    """R v equals rotate(q, v); rotate_inverse undoes it (yaw 90: x -> y -> x)."""
    q = quaternion_from_rpy(0.3, -0.2, 1.1)
    v = (0.5, -1.0, 2.0)
    rows = rotation_matrix(q)
    by_matrix = tuple(sum(r[i] * v[i] for i in range(3)) for r in rows)
    assert by_matrix == pytest.approx(rotate(q, v), abs=1e-12)
    assert rotate_inverse(q, rotate(q, v)) == pytest.approx(v, abs=1e-12)
    yaw_90 = quaternion_from_rpy(0.0, 0.0, math.pi / 2)
    assert rotate_inverse(yaw_90, (0.0, 1.0, 0.0)) == pytest.approx((1.0, 0.0, 0.0), abs=1e-12)
