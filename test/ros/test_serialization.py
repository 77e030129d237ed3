"""
MessageTemplate: patched bytes equal the serializer's, byte for byte, and cross processes.

``serialize_message`` (rmw_fastrtps_cpp) leaves alignment padding and a few bytes
at the end unwritten: they hold whatever was in memory, so two serializations
of one message may differ there. The reference here is therefore the serializer
itself run twice into buffers prefilled with 0x00 and 0xFF: bytes equal in both
are the ones it writes, and every one of those must match the template's. The
patched bytes received by a typed subscriber in another process are
system/test_serialization_system.py's; the random values both draw are in
helpers.py.
"""

import ctypes
import math
import os
import random
import struct
from typing import Any, Callable, List, Sequence, Tuple

from builtin_interfaces.msg import Time
from helpers import floats64, header, stamp, text
from geometry_msgs.msg import PoseStamped, TransformStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.type_support import check_for_type_support
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, LaserScan, Range

from r2d2_sim.ros import cdr
from r2d2_sim.ros.serialization import FieldError, MessageTemplate

STATES = 200
FRAME_ID_LENGTHS = range(10)    # every remainder of string padding, twice over
SPECIAL_FLOAT32 = [0.0, -0.0, 0.1, 1e-40, 1.4e-45, 3.4e38, -3.4e38, math.inf, -math.inf,
                   math.nan]


class _Allocator(ctypes.Structure):
    _fields_ = [(name, ctypes.c_void_p) for name in
                ('allocate', 'deallocate', 'reallocate', 'zero_allocate', 'state')]


class _SerializedMessage(ctypes.Structure):
    """rmw_serialized_message_t (rcutils_uint8_array_t)."""

    _fields_ = [('buffer', ctypes.c_void_p), ('buffer_length', ctypes.c_size_t),
                ('buffer_capacity', ctypes.c_size_t), ('allocator', _Allocator)]


def _capsule_pointer(capsule: Any) -> int:
    get_pointer = ctypes.pythonapi.PyCapsule_GetPointer
    get_pointer.restype = ctypes.c_void_p
    get_pointer.argtypes = [ctypes.py_object, ctypes.c_char_p]
    return get_pointer(capsule, None)


def _rmw_serialize() -> Callable:
    """Return rmw_fastrtps_cpp's rmw_serialize, as loaded by rclpy in this process."""
    serialize_message(Time())  # makes sure rclpy has loaded the rmw implementation
    with open('/proc/self/maps') as maps:
        paths = {line.split()[-1] for line in maps if line.rstrip().endswith('.so')}
    libraries = [p for p in paths if os.path.basename(p) == 'librmw_fastrtps_cpp.so']
    if os.environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp') != 'rmw_fastrtps_cpp' or \
            not libraries:
        pytest.skip('the reference serializer calls rmw_fastrtps_cpp directly')
    function = ctypes.CDLL(libraries[0]).rmw_serialize
    function.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.POINTER(_SerializedMessage)]
    function.restype = ctypes.c_int
    return function


@pytest.fixture(scope='module')
def reference() -> Callable[[Any], Tuple[bytes, List[int]]]:
    """Return ``serialize(msg) -> (bytes, offsets the serializer writes)``."""
    rmw_serialize = _rmw_serialize()

    def serialize_into(msg: Any, fill: int) -> bytes:
        # What rclpy's serialize_message does, but into a buffer of our own
        # (big enough, so rmw does not reallocate it) with known contents.
        message_type = type(msg)
        check_for_type_support(message_type)
        meta = type(message_type)
        create = ctypes.CFUNCTYPE(ctypes.c_void_p)(_capsule_pointer(meta._CREATE_ROS_MESSAGE))
        destroy = ctypes.CFUNCTYPE(None, ctypes.c_void_p)(
            _capsule_pointer(meta._DESTROY_ROS_MESSAGE))
        # PYFUNCTYPE: the conversion calls the Python C API, so it must hold the GIL.
        convert = ctypes.PYFUNCTYPE(ctypes.c_bool, ctypes.py_object, ctypes.c_void_p)(
            _capsule_pointer(meta._CONVERT_FROM_PY))
        capacity = len(serialize_message(msg))
        buffer = (ctypes.c_uint8 * capacity)(*([fill] * capacity))
        raw = _SerializedMessage(ctypes.cast(buffer, ctypes.c_void_p), 0, capacity)
        c_message = create()
        try:
            assert convert(msg, c_message)
            assert rmw_serialize(c_message, _capsule_pointer(meta._TYPE_SUPPORT),
                                 ctypes.byref(raw)) == 0
            assert raw.buffer_length == capacity
            return bytes(buffer)
        finally:
            destroy(c_message)

    def serialize(msg: Any) -> Tuple[bytes, List[int]]:
        zeros, ones = serialize_into(msg, 0x00), serialize_into(msg, 0xFF)
        return zeros, [i for i in range(len(zeros)) if zeros[i] == ones[i]]
    return serialize


def assert_same_bytes(reference, patched: bytes, expected_msg: Any) -> None:
    """Assert that every byte the serializer writes for ``expected_msg`` is in ``patched``."""
    expected, written = reference(expected_msg)
    assert len(patched) == len(expected)
    wrong = [i for i in written if patched[i] != expected[i]]
    assert not wrong, (f'{type(expected_msg).__name__}: {len(wrong)} bytes differ, first at '
                       f'{wrong[0]}: {patched[wrong[0]:wrong[0] + 8].hex()} != '
                       f'{expected[wrong[0]:wrong[0] + 8].hex()}')


def canonical(value: Any) -> Any:
    """Return a comparable form of a message; floats by their bits, so NaN == NaN."""
    if isinstance(value, float):
        return struct.pack('<d', value)
    if isinstance(value, (str, int, bytes)):
        return value
    if isinstance(value, np.ndarray):
        return value.dtype.str, value.tobytes()
    if hasattr(type(value), 'get_fields_and_field_types'):
        return tuple((name, canonical(getattr(value, name)))
                     for name in type(value).get_fields_and_field_types())
    return tuple(canonical(item) for item in value)


def floats32(rng: random.Random, count: int) -> List[float]:
    """Return ``count`` values for float32 fields, some special, most needing rounding."""
    return [rng.choice(SPECIAL_FLOAT32) if rng.random() < 0.2 else rng.uniform(0.0, 30.0)
            for _ in range(count)]


def as_given(rng: random.Random, values: List[float], dtype: str = 'float64') -> Sequence[float]:
    """Return the values as a list, tuple or numpy array: each path of FieldSlot.set."""
    kind = rng.randrange(3)
    if kind == 0:
        return values
    if kind == 1:
        return tuple(values)
    return np.array(values, dtype=dtype)


def check_states(reference, build: Callable, draw: Callable, patches: Callable,
                 seed: int) -> None:
    """
    Patch templates with STATES random states, and prove each one byte for byte.

    ``build(rng, frame_id_length, state)`` makes the typed message for a state
    (None: zeros, for the template), its frozen parts (names, frame ids,
    covariances) drawn from ``rng``; ``draw(rng)`` makes a random state;
    ``patches(template)`` returns ``apply(state, rng)``, which writes a state
    through the template's slots.
    """
    per_template = STATES // len(FRAME_ID_LENGTHS)
    for frame_id_length in FRAME_ID_LENGTHS:
        # The frozen parts come from their own seed, so the template and every
        # expected message get the same ones.
        frozen_seed = seed * 100 + frame_id_length
        template = MessageTemplate(build(random.Random(frozen_seed), frame_id_length, None))
        apply = patches(template)
        rng = random.Random(frozen_seed + 10_000)
        for _ in range(per_template):
            state = draw(rng)
            apply(state, rng)
            expected = build(random.Random(frozen_seed), frame_id_length, state)
            assert_same_bytes(reference, template.to_bytes(), expected)
            # And as a subscriber reads it (float32 fields rounded on both sides).
            assert canonical(template.to_message()) == canonical(
                deserialize_message(serialize_message(expected), type(expected)))


def test_the_reference_agrees_with_serialize_message(reference):
    """The 0x00/0xFF reference is what serialize_message writes, apart from unwritten bytes."""
    msg = JointState(header=header('a', 3, 4), name=['ab', 'c'], position=[1.0, 2.0])
    expected, written = reference(msg)
    actual = serialize_message(msg)
    assert [actual[i] for i in written] == [expected[i] for i in written]
    assert len(written) < len(expected), 'expected some padding in this layout'


def test_clock(reference):
    """Clock: one stamp at the start of the message."""
    template = MessageTemplate(Clock())
    clock = template.stamp('clock')
    rng = random.Random(1)
    for _ in range(STATES):
        sec, nanosec = stamp(rng)
        clock.set(sec, nanosec)
        expected = Clock(clock=Time(sec=sec, nanosec=nanosec))
        assert_same_bytes(reference, template.to_bytes(), expected)


def test_stamp_from_nanoseconds_matches_rclpy_time():
    """set_nanoseconds splits as rclpy.time.Time.to_msg does (and floors negative times)."""
    from rclpy.time import Time as RclpyTime
    template = MessageTemplate(Clock())
    clock = template.stamp('clock')
    for nanoseconds in (0, 1, 999_999_999, 10**9, 1_234_567_890_123):
        clock.set_nanoseconds(nanoseconds)
        assert template.to_message().clock == RclpyTime(nanoseconds=nanoseconds).to_msg()
    clock.set_nanoseconds(-10**9 - 5)
    assert template.to_message().clock == Time(sec=-2, nanosec=999_999_995)


@pytest.mark.parametrize('joints', [15, 5, 0])
def test_joint_state(reference, joints):
    """JointState: stamp and three float64[] after names of varied lengths (string padding)."""
    def build(rng, frame_id_length, state):
        names = [text(rng, rng.randrange(13)) for _ in range(joints)]
        if state is None:
            state = (0, 0), [0.0] * joints, [0.0] * joints, [0.0] * joints
        (sec, nanosec), position, velocity, effort = state
        return JointState(header=header(text(rng, frame_id_length), sec, nanosec), name=names,
                          position=position, velocity=velocity, effort=effort)

    def draw(rng):
        return stamp(rng), floats64(rng, joints), floats64(rng, joints), floats64(rng, joints)

    def patches(template):
        slots = (template.stamp(), template.field('position', joints),
                 template.field('velocity', joints), template.field('effort', joints))

        def apply(state, rng):
            slots[0].set(*state[0])
            for slot, values in zip(slots[1:], state[1:]):
                slot.set(as_given(rng, values))
        return apply
    check_states(reference, build, draw, patches, seed=joints)


def test_odometry(reference):
    """Odometry: stamp, pose (7 float64), twist (6) among odd-length frame ids, covariances."""
    def build(rng, frame_id_length, state):
        msg = Odometry(header=header(text(rng, frame_id_length), 0, 0),
                       child_frame_id=text(rng, 2 * frame_id_length + 1))
        msg.pose.covariance = floats64(rng, 36)
        msg.twist.covariance = floats64(rng, 36)
        if state is not None:
            (sec, nanosec), pose, twist = state
            msg.header.stamp = Time(sec=sec, nanosec=nanosec)
            p, q = msg.pose.pose.position, msg.pose.pose.orientation
            p.x, p.y, p.z, q.x, q.y, q.z, q.w = pose
            v, w = msg.twist.twist.linear, msg.twist.twist.angular
            v.x, v.y, v.z, w.x, w.y, w.z = twist
        return msg

    def draw(rng):
        return stamp(rng), floats64(rng, 7), floats64(rng, 6)

    def patches(template):
        slots = (template.stamp(), template.field('pose.pose', 7, 'float64'),
                 template.field('twist.twist', 6, 'float64'))

        def apply(state, rng):
            slots[0].set(*state[0])
            slots[1].set(as_given(rng, state[1]))
            slots[2].set(as_given(rng, state[2]))
        return apply
    check_states(reference, build, draw, patches, seed=20)


def test_imu(reference):
    """Imu: orientation (4), angular velocity (3), linear acceleration (3) between covariances."""
    def build(rng, frame_id_length, state):
        msg = Imu(header=header(text(rng, frame_id_length), 0, 0))
        msg.orientation_covariance = floats64(rng, 9)
        msg.angular_velocity_covariance = floats64(rng, 9)
        msg.linear_acceleration_covariance = floats64(rng, 9)
        if state is not None:
            (sec, nanosec), orientation, angular, linear = state
            msg.header.stamp = Time(sec=sec, nanosec=nanosec)
            q, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
            q.x, q.y, q.z, q.w = orientation
            w.x, w.y, w.z = angular
            a.x, a.y, a.z = linear
        return msg

    def draw(rng):
        return stamp(rng), floats64(rng, 4), floats64(rng, 3), floats64(rng, 3)

    def patches(template):
        slots = (template.stamp(), template.field('orientation', 4),
                 template.field('angular_velocity', 3), template.field('linear_acceleration', 3))

        def apply(state, rng):
            slots[0].set(*state[0])
            for slot, values in zip(slots[1:], state[1:]):
                slot.set(as_given(rng, values))
        return apply
    check_states(reference, build, draw, patches, seed=30)


def test_laser_scan(reference):
    """LaserScan: 360 float32 ranges, no intensities; float32 rounding as the serializer does."""
    def build(rng, frame_id_length, state):
        msg = LaserScan(header=header(text(rng, frame_id_length), 0, 0),
                        angle_min=-math.pi, angle_max=math.pi, angle_increment=2 * math.pi / 360,
                        time_increment=0.0, scan_time=0.1, range_min=0.05, range_max=30.0)
        (sec, nanosec), ranges = state if state is not None else ((0, 0), [0.0] * 360)
        msg.header.stamp = Time(sec=sec, nanosec=nanosec)
        msg.ranges = ranges
        return msg

    def draw(rng):
        return stamp(rng), floats32(rng, 360)

    def patches(template):
        stamp_slot, ranges = template.stamp(), template.field('ranges', 360, 'float32')

        def apply(state, rng):
            stamp_slot.set(*state[0])
            ranges.set(as_given(rng, state[1], rng.choice(['float32', 'float64'])))
        return apply
    check_states(reference, build, draw, patches, seed=40)


def test_indexed_messages_in_a_sequence(reference):
    """
    ``poses[i].pose``: nav_msgs/Path, the layout of TFMessage's transforms[i] without tf2_msgs.

    Both are a sequence of stamped messages, each with its own frame id string,
    so each element's numbers sit behind differently padded strings.
    """
    count = 4

    def build(rng, frame_id_length, state):
        msg = Path(header=header(text(rng, frame_id_length), 0, 0))
        msg.poses = [PoseStamped(header=header(text(rng, (frame_id_length + i) % 10), 0, 0))
                     for i in range(count)]
        if state is not None:
            for element, ((sec, nanosec), pose) in zip(msg.poses, state):
                element.header.stamp = Time(sec=sec, nanosec=nanosec)
                p, q = element.pose.position, element.pose.orientation
                p.x, p.y, p.z, q.x, q.y, q.z, q.w = pose
        return msg

    def draw(rng):
        return [(stamp(rng), floats64(rng, 7)) for _ in range(count)]

    def patches(template):
        slots = [(template.stamp(f'poses[{i}].header.stamp'), template.field(f'poses[{i}].pose'))
                 for i in range(count)]

        def apply(state, rng):
            for (stamp_slot, pose), ((sec, nanosec), values) in zip(slots, state):
                stamp_slot.set(sec, nanosec)
                pose.set(as_given(rng, values))
        return apply
    check_states(reference, build, draw, patches, seed=50)


def test_transform_stamped(reference):
    """TransformStamped: translation + rotation (7 float64) behind two strings of any length."""
    def build(rng, frame_id_length, state):
        msg = TransformStamped(header=header(text(rng, frame_id_length), 0, 0),
                               child_frame_id=text(rng, rng.randrange(10)))
        if state is not None:
            (sec, nanosec), transform = state
            msg.header.stamp = Time(sec=sec, nanosec=nanosec)
            t, q = msg.transform.translation, msg.transform.rotation
            t.x, t.y, t.z, q.x, q.y, q.z, q.w = transform
        return msg

    def draw(rng):
        return stamp(rng), floats64(rng, 7)

    def patches(template):
        stamp_slot, transform = template.stamp(), template.field('transform', 7)

        def apply(state, rng):
            stamp_slot.set(*state[0])
            transform.set(as_given(rng, state[1]))
        return apply
    check_states(reference, build, draw, patches, seed=60)


def test_tf_message(reference):
    """tf2_msgs/TFMessage transforms[i], where tf2_msgs is installed (it is not on PyPI)."""
    tf2_msgs = pytest.importorskip('tf2_msgs.msg')
    count = 3

    def build(rng, frame_id_length, state):
        msg = tf2_msgs.TFMessage(transforms=[
            TransformStamped(header=header(text(rng, (frame_id_length + i) % 10), 0, 0),
                             child_frame_id=text(rng, rng.randrange(10)))
            for i in range(count)])
        if state is not None:
            for element, ((sec, nanosec), transform) in zip(msg.transforms, state):
                element.header.stamp = Time(sec=sec, nanosec=nanosec)
                t, q = element.transform.translation, element.transform.rotation
                t.x, t.y, t.z, q.x, q.y, q.z, q.w = transform
        return msg

    def draw(rng):
        return [(stamp(rng), floats64(rng, 7)) for _ in range(count)]

    def patches(template):
        slots = [(template.stamp(f'transforms[{i}].header.stamp'),
                  template.field(f'transforms[{i}].transform', 7)) for i in range(count)]

        def apply(state, rng):
            for (stamp_slot, transform), ((sec, nanosec), values) in zip(slots, state):
                stamp_slot.set(sec, nanosec)
                transform.set(as_given(rng, values))
        return apply
    check_states(reference, build, draw, patches, seed=70)


def test_contiguity_depends_on_string_lengths(reference):
    """
    Whether MapMetaData (stamp, float32, 2 uint32, float64s) is one run depends on frame ids.

    After a 1-byte frame id the doubles need 4 bytes of padding; after a 4-byte
    one they do not: the very mistake hand-computed offsets make.
    """
    with pytest.raises(FieldError, match='not one contiguous run'):
        MessageTemplate(OccupancyGrid()).field('info')
    grid = OccupancyGrid(header=header('abcd', 0, 0))
    template = MessageTemplate(grid)
    info = template.field('info', 12)
    assert info.dtype is None
    info.set([7, 8, 0.25, 100, 200, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0])
    grid.info.map_load_time = Time(sec=7, nanosec=8)
    grid.info.resolution, grid.info.width, grid.info.height = 0.25, 100, 200
    grid.info.origin.position.x, grid.info.origin.position.y = 1.0, 2.0
    grid.info.origin.position.z, grid.info.origin.orientation.w = 3.0, 1.0
    assert_same_bytes(reference, template.to_bytes(), grid)


def test_template_is_frozen_from_its_message():
    """Changing the message after building the template changes nothing in it."""
    msg = JointState(name=['a'], position=[1.0])
    template = MessageTemplate(msg)
    before = template.to_bytes()
    msg.name = ['abcdef']
    msg.position = [2.0]
    assert template.to_bytes() == before


def test_paths_that_name_no_patchable_field():
    """Unknown names, strings, wrong indices and wrong expectations are clear FieldErrors."""
    odometry = MessageTemplate(Odometry())
    with pytest.raises(FieldError, match="Odometry has no field 'pos'.*it has: header"):
        odometry.field('pos.pose')
    with pytest.raises(FieldError, match="'pose.pose.position.w'.*Point has no field 'w'"):
        odometry.field('pose.pose.position.w')
    with pytest.raises(FieldError, match='is a string'):
        odometry.field('child_frame_id')
    with pytest.raises(FieldError, match='is a string'):
        odometry.field('header')
    with pytest.raises(FieldError, match='has 7 values, not 6'):
        odometry.field('pose.pose', count=6)
    with pytest.raises(FieldError, match='holds float64, not float32'):
        odometry.field('twist.twist', dtype='float32')
    with pytest.raises(FieldError, match='not a builtin_interfaces/Time'):
        odometry.stamp('pose.pose')
    with pytest.raises(FieldError, match="'pose.pose.position.x' is not a message"):
        odometry.field('pose.pose.position.x.y')
    with pytest.raises(FieldError, match='not an array'):
        odometry.field('pose[0]')
    with pytest.raises(FieldError, match='bad index'):
        odometry.field('pose.covariance[-1]')
    with pytest.raises(FieldError, match='has 36 elements, no index 36'):
        odometry.field('pose.covariance[36]')
    assert odometry.field('pose.covariance[35]').count == 1
    path = MessageTemplate(Path(poses=[PoseStamped()]))
    with pytest.raises(FieldError, match=r'is an array; pick an element, as in poses\[0\]'):
        path.field('poses.pose')
    with pytest.raises(FieldError, match='is a string'):
        MessageTemplate(JointState()).field('name')  # even when empty
    with pytest.raises(FieldError, match='is uint8; only double, float'):
        MessageTemplate(Range()).field('radiation_type')
    with pytest.raises(TypeError, match='expected a ROS message instance'):
        MessageTemplate({'a': 1.0})


def test_values_of_the_wrong_length_or_range():
    """set() refuses a wrong count (list or array, even one numpy would broadcast) or type."""
    template = MessageTemplate(Odometry())
    pose, stamp_slot = template.field('pose.pose'), template.stamp()
    before = template.to_bytes()
    for values in ([1.0] * 6, [1.0] * 8, np.zeros(6), np.zeros(1), []):
        with pytest.raises(ValueError, match=f"pose.pose: expected 7 values, got {len(values)}"):
            pose.set(values)
    with pytest.raises(ValueError, match='1-D array'):
        pose.set(np.zeros((7, 1)))
    assert template.to_bytes() == before, 'a wrong count or shape must write nothing'
    with pytest.raises(ValueError, match='pose.pose: '):  # struct's own words follow
        pose.set(['a'] * 7)
    with pytest.raises(ValueError, match=r'header.stamp: sec=2147483648'):
        stamp_slot.set(2**31, 0)
    with pytest.raises(ValueError, match='nanosec=-1'):
        stamp_slot.set(0, -1)
    empty = MessageTemplate(JointState()).field('position')
    empty.set([])
    with pytest.raises(ValueError, match='expected 0 values, got 1'):
        empty.set([1.0])


@pytest.mark.parametrize('encapsulation, error', [
    (b'\x00\x00', 'big-endian'), (b'\x00\x07', 'unsupported serialization: encapsulation 0007')])
def test_other_encodings_are_refused(monkeypatch, encapsulation, error):
    """Big-endian CDR (0x0000) or XCDR2 (0x0007) from the serializer get a clear error."""
    def other_encoding(msg):
        return encapsulation + serialize_message(msg)[2:]
    monkeypatch.setattr(cdr, 'serialize_message', other_encoding)  # the template's first
    with pytest.raises(ValueError, match=error):
        MessageTemplate(Clock())


def test_a_layout_is_searched_once_per_process_and_found_where_a_search_finds_it(monkeypatch):
    """A farm builds the same templates every run: a second one reuses the first one's spans."""
    from r2d2_sim.ros import serialization
    searched = []
    search = MessageTemplate._search

    def counted(self, path, *args):
        searched.append(path)
        return search(self, path, *args)
    monkeypatch.setattr(serialization, '_LOCATED', {})
    monkeypatch.setattr(MessageTemplate, '_search', counted)
    first = MessageTemplate(LaserScan(ranges=[0.0] * 181)).field('ranges')
    again = MessageTemplate(LaserScan(ranges=[0.0] * 181)).field('ranges')
    assert searched == ['ranges'] and (again.offset, again.count) == (first.offset, 181)
    other = MessageTemplate(LaserScan(ranges=[0.0] * 90)).field('ranges')  # another layout
    assert searched == ['ranges', 'ranges'] and other.count == 90
    framed = MessageTemplate(LaserScan(header=header('x' * 7, 0, 0), ranges=[0.0] * 181))
    assert framed.field('ranges').offset != first.offset and len(searched) == 3
