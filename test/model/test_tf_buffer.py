"""
The tf2-style transform buffer, checked with frames and numbers one can follow by hand.

The robot of these tests: odom -> base_footprint moves; base_footprint ->
base_link is static, 0.47 m up; base_link -> base_scan is static, 0.1 m ahead
and 0.25 m up. Right angles and halves keep every expected number exact or a
simple sum.
"""

import math
from types import SimpleNamespace

import pytest

from common import approx, yaw
from r2d2_sim.model.tf_buffer import (
    ConnectivityException, DEFAULT_CACHE_TIME_NS, ExtrapolationException, from_tf_message,
    interpolate, InvalidArgumentException, LookupException, slerp, StampedTransform,
    TransformBuffer, TransformException)
from r2d2_sim.model.transforms import Transform, yaw_of

S = 10**9  # ns per second
NO_TURN = (0.0, 0.0, 0.0, 1.0)


def robot(buffer=None):
    """Return a buffer holding the static part of the robot: footprint -> base -> laser."""
    buffer = buffer or TransformBuffer()
    buffer.add('base_footprint', 'base_link', 0, (0.0, 0.0, 0.47), NO_TURN, static=True)
    buffer.add('base_link', 'base_scan', 0, (0.1, 0.0, 0.25), NO_TURN, static=True)
    return buffer


# -- the chain, at one time ----------------------------------------------------

def test_laser_point_into_odom_through_the_chain():
    """A point 1 m ahead of the laser, robot at (1, 2) facing +y: (1, 3.1, 0.72) in odom."""
    buffer = robot()
    buffer.add('odom', 'base_footprint', 1 * S, (1.0, 2.0, 0.0), yaw(math.pi / 2))
    # base_scan (1, 0, 0) -> base_link (1.1, 0, 0.25) -> base_footprint (1.1, 0, 0.72)
    # -> turned 90 degrees: (0, 1.1, 0.72) -> moved by (1, 2): (1, 3.1, 0.72).
    assert buffer.transform_point('odom', 'base_scan', (1.0, 0.0, 0.0)) == \
        approx((1.0, 3.1, 0.72))
    found = buffer.lookup_transform('odom', 'base_scan')
    assert (found.frame_id, found.child_frame_id, found.stamp_ns) == \
        ('odom', 'base_scan', 1 * S)
    assert found.translation == approx((1.0, 2.1, 0.72))
    assert found.rotation == approx(yaw(math.pi / 2))


def test_the_other_way_round_is_the_inverse():
    """Odom's (1, 3.1, 0.72) is 1 m ahead of the laser; odom's origin in base_scan by hand."""
    buffer = robot()
    buffer.add('odom', 'base_footprint', 1 * S, (1.0, 2.0, 0.0), yaw(math.pi / 2))
    assert buffer.transform_point('base_scan', 'odom', (1.0, 3.1, 0.72)) == \
        approx((1.0, 0.0, 0.0))
    # Odom's origin is 1 m behind-left and 2 m behind the robot: in the footprint frame
    # (x = odom +y, y = odom -x) it is (-2, 1, 0); in base_scan (-2.1, 1, -0.72).
    assert buffer.transform_point('base_scan', 'odom', (0.0, 0.0, 0.0)) == \
        approx((-2.1, 1.0, -0.72))


def test_a_frame_in_itself_is_the_identity():
    """Same frame both ways: no motion, and the known frame is enough."""
    buffer = robot()
    found = buffer.lookup_transform('base_link', 'base_link', 5 * S)
    assert found.transform == Transform((0.0, 0.0, 0.0), NO_TURN) and found.stamp_ns == 5 * S


def test_lookup_walks_only_up_to_the_common_ancestor():
    """Laser in base_link needs no odom data, even at a time odom has none for."""
    buffer = robot()
    buffer.add('odom', 'base_footprint', 1 * S, (1.0, 2.0, 0.0), yaw(math.pi / 2))
    assert buffer.transform_point('base_link', 'base_scan', (1.0, 0.0, 0.0), 99 * S) == \
        approx((1.1, 0.0, 0.25))
    buffer.add('base_link', 'head', 0, (0.0, 0.0, 0.3), yaw(math.pi), static=True)
    # Siblings under base_link: the laser's point 1 m ahead is 1.1 m behind the turned head.
    assert buffer.transform_point('head', 'base_scan', (1.0, 0.0, 0.0)) == \
        approx((-1.1, 0.0, -0.05))


# -- time ------------------------------------------------------------------------

def test_halfway_between_two_stamps_interpolates_position_and_yaw():
    """At 1.5 s, between x 0 yaw 0 (1 s) and x 2 yaw 90 (2 s): x 1, yaw 45 degrees."""
    buffer = robot()
    buffer.add('odom', 'base_footprint', 1 * S, (0.0, 0.0, 0.0), yaw(0.0))
    buffer.add('odom', 'base_footprint', 2 * S, (2.0, 0.0, 0.0), yaw(math.pi / 2))
    found = buffer.lookup_transform('odom', 'base_footprint', 3 * S // 2)
    assert found.translation == approx((1.0, 0.0, 0.0))
    assert found.rotation == approx(yaw(math.pi / 4))
    # A point 1 m ahead of the footprint then lies at (1 + cos 45, sin 45).
    half = math.sqrt(0.5)
    assert buffer.transform_point('odom', 'base_footprint', (1.0, 0.0, 0.0), 3 * S // 2) == \
        approx((1.0 + half, half, 0.0))
    # A quarter of the way: x 0.5, yaw 22.5 degrees (slerp is uniform in angle).
    quarter = buffer.lookup_transform('odom', 'base_footprint', 5 * S // 4)
    assert quarter.translation == approx((0.5, 0.0, 0.0))
    assert yaw_of(quarter.rotation) == pytest.approx(math.pi / 8, abs=1e-12)


def test_samples_added_out_of_order_are_sorted():
    """Stamps may arrive late: the samples around the requested time are used."""
    buffer = TransformBuffer()
    for t, x in ((3, 3.0), (1, 1.0), (2, 2.0)):
        buffer.add('odom', 'base_footprint', t * S, (x, 0.0, 0.0), NO_TURN)
    assert buffer.lookup_transform('odom', 'base_footprint', 5 * S // 2).translation == \
        approx((2.5, 0.0, 0.0))


def test_interpolated_yaw_takes_the_short_way_across_180_degrees():
    """From yaw 170 to -170 degrees, halfway is 180 (not 0)."""
    buffer = TransformBuffer()
    buffer.add('odom', 'base_footprint', 0, (0.0, 0.0, 0.0), yaw(math.radians(170)))
    buffer.add('odom', 'base_footprint', 2 * S, (0.0, 0.0, 0.0), yaw(math.radians(-170)))
    middle = buffer.lookup_transform('odom', 'base_footprint', 1 * S).rotation
    assert abs(yaw_of(middle)) == pytest.approx(math.pi, abs=1e-12)


def test_static_edges_hold_at_any_time_and_stamp_0_when_all_static():
    """A static transform answers at every time; time 0 over static edges only is time 0."""
    buffer = robot()
    for t in (1, 10**12, 0):
        found = buffer.lookup_transform('base_footprint', 'base_scan', t)
        assert found.translation == approx((0.1, 0.0, 0.72)) and found.stamp_ns == t


def test_time_0_is_the_latest_time_every_moving_edge_has():
    """With odom data to 3 s and head data to 2 s, odom -> head resolves at 2 s."""
    buffer = robot()
    for t in (1, 2, 3):
        buffer.add('odom', 'base_footprint', t * S, (float(t), 0.0, 0.0), NO_TURN)
    for t in (1, 2):
        buffer.add('base_link', 'head', t * S, (0.0, 0.0, 0.3), yaw(t * math.pi / 2))
    found = buffer.lookup_transform('odom', 'head')
    assert found.stamp_ns == 2 * S
    assert found.translation == approx((2.0, 0.0, 0.77))
    assert found.rotation == approx(yaw(math.pi))
    # Without the head, the footprint's own latest sample counts.
    assert buffer.lookup_transform('odom', 'base_scan').stamp_ns == 3 * S


def test_extrapolation_into_the_past_and_the_future_names_the_times_and_frames():
    """Outside a moving edge's samples: tf2's messages, with both times in seconds."""
    buffer = robot()
    buffer.add('odom', 'base_footprint', 1 * S, (0.0, 0.0, 0.0), NO_TURN)
    buffer.add('odom', 'base_footprint', 2 * S, (1.0, 0.0, 0.0), NO_TURN)
    with pytest.raises(ExtrapolationException) as past:
        buffer.lookup_transform('odom', 'base_scan', S // 2)
    assert 'extrapolation into the past' in str(past.value)
    assert 'Requested time 0.500000000' in str(past.value)
    assert 'earliest data is at time 1.000000000' in str(past.value)
    assert 'from frame [base_footprint] to frame [odom]' in str(past.value)
    with pytest.raises(ExtrapolationException) as future:
        buffer.lookup_transform('base_scan', 'odom', 2 * S + 1)
    assert 'extrapolation into the future' in str(future.value)
    assert 'Requested time 2.000000001 but the latest data is at time 2.000000000' in \
        str(future.value)
    assert not buffer.can_transform('odom', 'base_scan', 3 * S)
    assert buffer.can_transform('odom', 'base_scan', 2 * S)


def test_a_single_sample_answers_only_at_its_own_time():
    """One sample of a moving edge: its time works, any other is extrapolation."""
    buffer = TransformBuffer()
    buffer.add('odom', 'base_footprint', 7 * S, (1.0, 0.0, 0.0), NO_TURN)
    assert buffer.lookup_transform('odom', 'base_footprint', 7 * S).translation == \
        approx((1.0, 0.0, 0.0))
    with pytest.raises(ExtrapolationException, match='only time 7.000000000 is in the buffer'):
        buffer.lookup_transform('odom', 'base_footprint', 8 * S)


def test_history_is_bounded_like_tf2s_cache():
    """10 s behind the newest sample are kept; older samples go, and late old data is ignored."""
    assert DEFAULT_CACHE_TIME_NS == 10 * S
    buffer = TransformBuffer()
    for t in range(21):
        assert buffer.add('odom', 'base_footprint', t * S, (float(t), 0.0, 0.0), NO_TURN)
    assert buffer.lookup_transform('odom', 'base_footprint', 10 * S).translation == \
        approx((10.0, 0.0, 0.0))
    with pytest.raises(ExtrapolationException, match='earliest data is at time 10.0'):
        buffer.lookup_transform('odom', 'base_footprint', 19 * S // 2)
    assert not buffer.add('odom', 'base_footprint', 5 * S, (0.0, 0.0, 0.0), NO_TURN)
    short = TransformBuffer(cache_time_ns=1 * S)
    for t in range(5):
        short.add('odom', 'base_footprint', t * S, (float(t), 0.0, 0.0), NO_TURN)
    assert not short.can_transform('odom', 'base_footprint', 2 * S)
    assert short.can_transform('odom', 'base_footprint', 3 * S)


def test_a_repeated_stamp_keeps_the_first_sample():
    """As tf2 (TF_REPEATED_DATA): the second sample at one time is ignored."""
    buffer = TransformBuffer()
    assert buffer.add('odom', 'base_footprint', 1 * S, (1.0, 0.0, 0.0), NO_TURN)
    assert not buffer.add('odom', 'base_footprint', 1 * S, (5.0, 0.0, 0.0), NO_TURN)
    assert buffer.lookup_transform('odom', 'base_footprint').translation == \
        approx((1.0, 0.0, 0.0))


def test_static_value_is_replaced_by_a_newer_static_value():
    """/tf_static sent again (a latched publisher restarting) replaces the value."""
    buffer = robot()
    buffer.add('base_link', 'base_scan', 5 * S, (0.2, 0.0, 0.25), NO_TURN, static=True)
    assert buffer.lookup_transform('base_link', 'base_scan', 1).translation == \
        approx((0.2, 0.0, 0.25))


# -- errors ----------------------------------------------------------------------

def test_unknown_frames_are_lookup_errors_naming_the_argument():
    """tf2's 'does not exist', also a Python LookupError, listing the frames it knows."""
    buffer = robot()
    with pytest.raises(LookupException) as info:
        buffer.lookup_transform('map', 'base_link')
    message = str(info.value)
    assert '"map" passed to lookup_transform argument target_frame does not exist' in message
    assert 'base_footprint, base_link, base_scan' in message
    assert isinstance(info.value, LookupError) and isinstance(info.value, TransformException)
    with pytest.raises(LookupException, match='argument source_frame'):
        buffer.transform_point('base_link', 'laser', (0.0, 0.0, 0.0))
    with pytest.raises(LookupException, match='none yet'):
        TransformBuffer().lookup_transform('odom', 'odom')


def test_two_unconnected_trees_are_a_connectivity_error():
    """A map -> beacon tree and the robot's share no frame: tf2's 'not part of the same tree'."""
    buffer = robot()
    buffer.add('odom', 'base_footprint', 1 * S, (0.0, 0.0, 0.0), NO_TURN)
    buffer.add('map', 'beacon', 0, (5.0, 0.0, 0.0), NO_TURN, static=True)
    with pytest.raises(ConnectivityException) as info:
        buffer.lookup_transform('beacon', 'base_scan')
    assert "between 'beacon' and 'base_scan'" in str(info.value)
    assert "roots 'map' and 'odom'" in str(info.value)
    buffer.add('map', 'odom', 0, (1.0, 0.0, 0.0), NO_TURN, static=True)  # now one tree
    assert buffer.transform_point('beacon', 'base_footprint', (0.0, 0.0, 0.0), 1 * S) == \
        approx((-4.0, 0.0, 0.0))


@pytest.mark.parametrize('parent, child, translation, rotation, fragment', [
    ('base_link', 'base_link', (0, 0, 0), NO_TURN, 'its own parent'),
    ('/odom', 'base_link', (0, 0, 0), NO_TURN, "cannot start with a '/'"),
    ('odom', '', (0, 0, 0), NO_TURN, 'non-empty frame id'),
    ('odom', 'base_link', (math.nan, 0, 0), NO_TURN, 'NaN'),
    ('odom', 'base_link', (0, 0, 0), (0.0, 0.0, 0.0, 2.0), 'not a unit quaternion'),
    ('odom', 'base_link', (0, 0), NO_TURN, '3 numbers'),
    ('base_scan', 'base_footprint', (0, 0, 0), NO_TURN, 'would make a loop'),
])
def test_transforms_tf2_would_refuse_are_refused(
        parent, child, translation, rotation, fragment):
    """Self transforms, '/' frames, NaN, non-unit rotations and loops: InvalidArgument."""
    buffer = robot()
    with pytest.raises(InvalidArgumentException, match=fragment):
        buffer.add(parent, child, 1 * S, translation, rotation)
    assert buffer.parent_of('base_footprint') is None  # nothing half-added


def test_lookup_arguments_tf2_would_refuse():
    """A '/' frame id or a negative time is refused before any search."""
    buffer = robot()
    with pytest.raises(InvalidArgumentException, match="cannot start with a '/'"):
        buffer.lookup_transform('/base_link', 'base_scan')
    with pytest.raises(InvalidArgumentException, match='>= 0'):
        buffer.lookup_transform('base_link', 'base_scan', -1)


def test_a_new_parent_starts_the_frame_history_anew():
    """A frame moved under another parent: the tree follows, old samples are gone."""
    buffer = TransformBuffer()
    buffer.add('odom', 'cup', 1 * S, (1.0, 0.0, 0.0), NO_TURN)
    buffer.add('gripper', 'cup', 2 * S, (0.0, 0.0, -0.1), NO_TURN)
    assert buffer.parent_of('cup') == 'gripper'
    assert buffer.frames == {'odom', 'gripper', 'cup'}
    with pytest.raises(ConnectivityException):
        buffer.lookup_transform('odom', 'cup')
    buffer.clear()
    assert buffer.frames == set()


# -- the math and the message reader ---------------------------------------------

def test_slerp_and_interpolate_by_hand():
    """Ends, the middle, and q against -q (the same rotation)."""
    a, b = yaw(0.0), yaw(math.pi / 2)
    assert slerp(a, b, 0.0) == approx(a) and slerp(a, b, 1.0) == approx(b)
    assert slerp(a, b, 0.5) == approx(yaw(math.pi / 4))
    minus_b = tuple(-c for c in b)
    assert slerp(a, minus_b, 0.5) == approx(yaw(math.pi / 4))
    assert slerp(a, a, 0.3) == approx(a)
    middle = interpolate(Transform((0.0, 0.0, 0.0), a), Transform((2.0, 4.0, -2.0), b), 0.5)
    assert middle.translation == approx((1.0, 2.0, -1.0))


def _tf_message(*transforms):
    """Build a duck-typed TFMessage from (parent, child, sec, nanosec, xyz, xyzw) tuples."""
    items = []
    for parent, child, sec, nanosec, (x, y, z), (qx, qy, qz, qw) in transforms:
        items.append(SimpleNamespace(
            header=SimpleNamespace(frame_id=parent,
                                   stamp=SimpleNamespace(sec=sec, nanosec=nanosec)),
            child_frame_id=child,
            transform=SimpleNamespace(translation=SimpleNamespace(x=x, y=y, z=z),
                                      rotation=SimpleNamespace(x=qx, y=qy, z=qz, w=qw))))
    return SimpleNamespace(transforms=items)


def test_tf_messages_feed_the_buffer():
    """What /tf_static and /tf carry, read field by field, gives the laser point in odom."""
    static = _tf_message(('base_footprint', 'base_link', 0, 0, (0.0, 0.0, 0.47), NO_TURN),
                         ('base_link', 'base_scan', 0, 0, (0.1, 0.0, 0.25), NO_TURN))
    moving = _tf_message(('odom', 'base_footprint', 1, 500_000_000, (1.0, 2.0, 0.0),
                          yaw(math.pi / 2)))
    assert from_tf_message(moving) == [StampedTransform(
        'odom', 'base_footprint', 1_500_000_000,
        Transform((1.0, 2.0, 0.0), yaw(math.pi / 2)))]
    buffer = TransformBuffer()
    assert buffer.add_tf_message(static, static=True) == 2
    assert buffer.add_tf_message(moving) == 1
    assert buffer.add_tf_message(moving) == 0  # the same stamp again
    found = buffer.lookup_transform('odom', 'base_scan')
    assert found.stamp_ns == 1_500_000_000
    assert buffer.transform_point('odom', 'base_scan', (1.0, 0.0, 0.0)) == \
        approx((1.0, 3.1, 0.72))
