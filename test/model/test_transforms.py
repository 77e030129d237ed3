"""
Rigid-transform math, checked by hand (the URDF link tree: test_link_tree.py).

The hand checks use right angles, where every number is 0, 1 or a simple sum;
the cross-check against PyBullet, which proves that the conventions (rpy order,
quaternion layout, origin * motion, axis normalisation) are the ones the
simulator uses, is in physics/test_transforms_physics.py.
"""

import math

import pytest

from common import assert_same_transform, matrix_of
from r2d2_sim.model.transforms import (
    apply, compose, IDENTITY, inverse, normalised, quaternion_from_axis_angle, quaternion_from_rpy,
    quaternion_multiply, rotate, rotate_inverse, rotation_matrix, split_yaw, Transform, yaw_of,
)

HALF_SQRT2 = math.sqrt(0.5)


def matmul(a, b):
    return [[sum(a[r][k] * b[k][c] for k in range(3)) for c in range(3)] for r in range(3)]


# --------------------------------------------------------------------------- quaternions


def test_quaternion_multiply_unit_axes():
    # i j = k, j i = -k, i i = -1 in (x, y, z, w) layout.
    i, j = (1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0)
    assert quaternion_multiply(i, j) == (0.0, 0.0, 1.0, 0.0)
    assert quaternion_multiply(j, i) == (0.0, 0.0, -1.0, 0.0)
    assert quaternion_multiply(i, i) == (0.0, 0.0, 0.0, -1.0)


def test_normalised_scales_to_unit_length_and_leaves_a_zero_alone():
    assert normalised((0.0, 0.0, 3.0, 4.0)) == (0.0, 0.0, 0.6, 0.8)
    assert normalised((0.0, 0.0, 0.0, 0.0)) == (0.0, 0.0, 0.0, 0.0)


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
