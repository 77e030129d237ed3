"""
SDF's poses: numbers to transforms, rotations back to rpy, frames resolved through relative_to.

Hand-computable geometry: a frame 1 m up, turned 90 degrees about z, puts
a point 1 m along its x at (0, 1, 1). Pure math, no PyBullet.
"""

import math

import pytest

from common import approx
from r2d2_sim.model.sdf_poses import (
    FrameError, PoseGraph, pose_from_values, rpy_from_quaternion)
from r2d2_sim.model.transforms import (
    apply, IDENTITY, quaternion_from_rpy, Transform)

QUARTER = math.pi / 2.0


def turned(x, y, z, yaw=0.0):
    return Transform((x, y, z), quaternion_from_rpy(0.0, 0.0, yaw))


def test_six_numbers_are_a_translation_and_urdf_rpy():
    pose = pose_from_values([1.0, 2.0, 3.0, 0.0, 0.0, QUARTER])
    assert pose.translation == (1.0, 2.0, 3.0)
    assert apply(pose, (1.0, 0.0, 0.0)) == approx((1.0, 3.0, 3.0))


def test_degrees_and_quaternions_are_read_as_sdf_1_9_writes_them():
    in_degrees = pose_from_values([0, 0, 0, 0, 0, 90], degrees=True)
    in_radians = pose_from_values([0, 0, 0, 0, 0, QUARTER])
    assert in_degrees.rotation == approx(in_radians.rotation)
    s = math.sqrt(0.5)
    quaternion = pose_from_values([0, 0, 0, 0, 0, s, s], quaternion=True)
    assert quaternion.rotation == approx(in_radians.rotation, 1e-9)
    rounded = pose_from_values([0, 0, 0, 0, 0, 0.7072, 0.7072], quaternion=True)  # as printed
    assert math.fsum(c * c for c in rounded.rotation) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize('values, quaternion, problem', [
    ([1, 2, 3], False, 'a pose is 6 finite numbers'),
    ([0, 0, 0, 0, 0, float('nan')], False, 'a pose is 6 finite numbers'),
    ([0, 0, 0, 0, 0, 0], True, 'a pose is 7 finite numbers'),
    ([0, 0, 0, 0, 0, 0, 2], True, 'not a unit one'),
])
def test_a_bad_pose_is_refused(values, quaternion, problem):
    with pytest.raises(FrameError, match=problem):
        pose_from_values(values, quaternion=quaternion)


@pytest.mark.parametrize('rpy', [
    (0.1, -0.2, 0.3), (3.0, 1.2, -2.5), (0.0, QUARTER, 0.7), (0.4, -QUARTER, -1.1),
    (-3.1, 0.0, 3.1), (0.0, 0.0, 0.0)])
def test_rpy_from_a_quaternion_gives_the_same_rotation_back(rpy):
    q = quaternion_from_rpy(*rpy)
    back = quaternion_from_rpy(*rpy_from_quaternion(q))
    sign = 1.0 if sum(a * b for a, b in zip(q, back)) >= 0 else -1.0
    assert [sign * c for c in back] == approx(q, 1e-9)


def test_frames_resolve_through_chains_to_the_scope_frame():
    graph = PoseGraph('__model__')
    graph.add('base', '', turned(1.0, 0.0, 0.0, QUARTER))
    graph.add('arm', 'base', turned(1.0, 0.0, 0.0))          # 1 m along base's x: world +y
    graph.add('tip', 'arm', turned(0.0, 0.0, 1.0))
    assert graph.pose('arm').translation == approx((1.0, 1.0, 0.0))
    assert graph.pose('tip').translation == approx((1.0, 1.0, 1.0))
    assert graph.pose('__model__') == IDENTITY


def test_the_order_frames_are_added_in_does_not_matter():
    graph = PoseGraph('__model__')
    graph.add('tip', 'arm', turned(0.0, 0.0, 1.0))
    graph.add('arm', '', turned(2.0, 0.0, 0.0))
    assert graph.pose('tip').translation == approx((2.0, 0.0, 1.0))


def test_scoped_names_go_through_nested_scopes():
    inner = PoseGraph('__model__')
    inner.add('link', '', turned(0.0, 1.0, 0.0))
    outer = PoseGraph('__model__')
    outer.add('nested', '', turned(5.0, 0.0, 0.0, QUARTER), scope=inner)
    outer.add('marker', 'nested::link', turned(1.0, 0.0, 0.0))
    # nested::link: (5, 0, 0) + rotate90((0, 1, 0)) = (4, 0, 0); marker 1 m along its x: (4, 1, 0)
    assert outer.pose('nested::link').translation == approx((4.0, 0.0, 0.0))
    assert outer.pose('marker').translation == approx((4.0, 1.0, 0.0))
    assert outer.pose('nested::__model__') == outer.pose('nested')
    assert 'nested::link' in outer and 'nested::nothing' not in outer


def test_a_circle_of_relative_to_is_refused_naming_the_frames():
    graph = PoseGraph('__model__')
    graph.add('a', 'b', IDENTITY)
    graph.add('b', 'c', IDENTITY)
    graph.add('c', 'a', IDENTITY)
    with pytest.raises(FrameError, match=r'the poses of .*a.*b.*c.* in a circle'):
        graph.pose('a')


def test_a_circle_through_a_nested_scope_is_refused_not_a_recursion_error():
    inner = PoseGraph('__model__')
    inner.add('link', '', IDENTITY)
    outer = PoseGraph('__model__')
    outer.add('nested', 'frame', IDENTITY, scope=inner)
    outer.add('frame', 'nested::link', IDENTITY)
    with pytest.raises(FrameError, match='circle'):
        outer.pose('frame')


def test_a_frame_relative_to_nothing_and_a_repeated_name_are_refused():
    graph = PoseGraph('__model__')
    graph.add('a', 'ghost', IDENTITY)
    with pytest.raises(FrameError, match="relative to 'ghost', which names no frame"):
        graph.pose('a')
    with pytest.raises(FrameError, match="two frames are named 'a'"):
        graph.add('a', '', IDENTITY)
    with pytest.raises(FrameError, match="no frame named 'nowhere'"):
        graph.pose('nowhere')
