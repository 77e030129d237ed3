"""
Messages serialized once, whose numeric fields are patched in place before each publish.

In rclpy 7.1.6 ``publish(msg)`` of an Odometry costs 10-12 us with no
subscriber (conversion to C and serialization), ``publish(b)`` of the same
message as ``bytes`` 1.7 us; patching the template's stamp, pose and twist
costs 1 us more. A :class:`MessageTemplate` keeps one serialization of a
filled-in message; its strings and sequence lengths are frozen, and only
fixed-size numeric fields (stamps, poses, joint positions, ranges) are
rewritten each step.

Where a field lies in the CDR bytes is never computed by hand (a prototype got
a sequence's alignment padding wrong and every message was rejected). It is
found by serializing the message with two random sentinel values written into
the field and locating them, and then proved: the template patched with the
sentinels must deserialize to exactly the message holding them.

Templates start from :func:`r2d2_sim.ros.cdr.serialize`'s bytes (padding
zeroed), so a patched message is the same bytes every run.
"""

import array
import importlib
import random
import struct
from typing import Any, Dict, List, NamedTuple, Optional, Sequence, Tuple, Union

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message
from rosidl_parser.definition import (
    AbstractGenericString, AbstractNestedType, BasicType, NamespacedType)

from r2d2_sim.ros.cdr import fields as _fields, serialize

__all__ = ['FieldError', 'FieldSlot', 'BytesSlot', 'MessageTemplate', 'StampSlot',
           'serialize']

# Numeric leaf types that can be patched, as little-endian struct codes. Types
# narrower than 4 bytes are left out: a 1- or 2-byte sentinel cannot be located
# unambiguously among the other bytes of a message.
_STRUCT_CODES = {
    'double': 'd', 'float': 'f', 'int32': 'i', 'uint32': 'I', 'int64': 'q', 'uint64': 'Q',
}
_DTYPE_NAMES = {'d': 'float64', 'f': 'float32', 'i': 'int32', 'I': 'uint32',
                'q': 'int64', 'Q': 'uint64'}

# The first two bytes of a serialized message: the RTPS encapsulation kind.
_CDR_LE = b'\x00\x01'
_CDR_BE = b'\x00\x00'

_NANOSECONDS_PER_SECOND = 1_000_000_000
_LOCATE_ATTEMPTS = 4


class FieldError(ValueError):
    """A path that names no patchable numeric field of the message, or one not found."""


class _Leaf(NamedTuple):
    """One numeric value inside a message: where it is held, and its struct code."""

    holder: Any            # a message (key: attribute name) or a numeric array (key: index)
    key: Union[str, int]
    code: str


def _parse_path(path: str) -> List[Tuple[str, Optional[int]]]:
    """Split ``'transforms[1].transform'`` into ``[('transforms', 1), ('transform', None)]``."""
    steps = []
    for part in path.split('.'):
        name, bracket, rest = part.partition('[')
        index = None
        if bracket:
            if not rest.endswith(']') or not rest[:-1].isdigit():
                raise FieldError(f'{path!r}: bad index in {part!r} (expected name[N])')
            index = int(rest[:-1])
        if not name.isidentifier():
            raise FieldError(f'{path!r}: {part!r} is not a field name')
        steps.append((name, index))
    return steps


def _get(holder: Any, key: Union[str, int]) -> Any:
    return getattr(holder, key) if isinstance(key, str) else holder[key]


def _resolve(message: Any, path: str) -> Tuple[Any, Union[str, int], Any]:
    """Walk ``path`` from ``message``; return (holder, key, rosidl type) of its target."""
    holder: Any = message
    key: Union[str, int] = ''
    type_def: Any = None
    walked = ''
    for name, index in _parse_path(path):
        if type_def is not None:
            if isinstance(type_def, AbstractNestedType):
                raise FieldError(f'{path!r}: {walked!r} is an array; pick an element, '
                                 f'as in {walked}[0].{name}')
            if not isinstance(type_def, NamespacedType):
                raise FieldError(
                    f'{path!r}: {walked!r} is not a message, it has no field {name!r}')
            holder = _get(holder, key)
        fields = dict(_fields(holder))
        if name not in fields:
            raise FieldError(f'{path!r}: {type(holder).__name__} has no field {name!r} '
                             f'(it has: {", ".join(fields)})')
        key, type_def = name, fields[name]
        walked = f'{walked}.{name}' if walked else name
        if index is not None:
            if not isinstance(type_def, AbstractNestedType):
                raise FieldError(f'{path!r}: {walked!r} is not an array, it cannot be indexed')
            sequence = _get(holder, key)
            if index >= len(sequence):
                raise FieldError(f'{path!r}: {walked!r} has {len(sequence)} elements, '
                                 f'no index {index}')
            holder, key, type_def = sequence, index, type_def.value_type
            walked = f'{walked}[{index}]'
    return holder, key, type_def


def _message_class(type_def: NamespacedType) -> Any:
    """Return the Python class of a nested message type (e.g. geometry_msgs.msg.Pose)."""
    return getattr(importlib.import_module('.'.join(type_def.namespaces)), type_def.name)


def _codes(type_def: Any, path: str) -> str:
    """
    Return the struct codes of one element of a field's type, or raise if not patchable.

    Decided from the type alone, so that an empty sequence of strings is refused
    as surely as a full one; a sequence contributes its element type once.
    """
    if isinstance(type_def, BasicType):
        code = _STRUCT_CODES.get(type_def.typename)
        if code is None:
            raise FieldError(f'{path!r} is {type_def.typename}; only '
                             f'{", ".join(_STRUCT_CODES)} fields can be patched')
        return code
    if isinstance(type_def, AbstractGenericString):
        raise FieldError(f'{path!r} is a string; strings are frozen in the template')
    if isinstance(type_def, AbstractNestedType):
        return _codes(type_def.value_type, f'{path}[]')
    message_class = _message_class(type_def)
    return ''.join(_codes(field_type, f'{path}.{name}') for name, field_type in zip(
        message_class.get_fields_and_field_types(), message_class.SLOT_TYPES))


def _leaves(holder: Any, key: Union[str, int], type_def: Any) -> List[_Leaf]:
    """List the numeric values a field consists of now, in serialization order."""
    if isinstance(type_def, BasicType):
        return [_Leaf(holder, key, _STRUCT_CODES[type_def.typename])]
    value = _get(holder, key)
    leaves = []
    if isinstance(type_def, AbstractNestedType):
        # A sequence's length is frozen; its elements are patched one by one.
        for index in range(len(value)):
            leaves += _leaves(value, index, type_def.value_type)
    else:
        for name, field_type in _fields(value):
            leaves += _leaves(value, name, field_type)
    return leaves


def _sentinels(codes: str, rng: random.Random) -> Tuple[bytes, List[Union[int, float]]]:
    """Return random finite values for ``codes``, packed and as numbers (unique in practice)."""
    packed = b''
    for code in codes:
        size = struct.calcsize('<' + code)
        while True:
            raw = rng.getrandbits(8 * size).to_bytes(size, 'little')
            if code in 'df':
                # NaN payloads need not survive conversion; infinities are too common.
                value = struct.unpack('<' + code, raw)[0]
                if value != value or value in (float('inf'), float('-inf')):
                    continue
            break
        packed += raw
    return packed, list(struct.unpack('<' + codes, packed))


def _write(leaves: Sequence[_Leaf], values: Sequence[Union[int, float]]) -> None:
    for leaf, value in zip(leaves, values):
        if isinstance(leaf.key, str):
            setattr(leaf.holder, leaf.key, value)
        else:
            leaf.holder[leaf.key] = value


def _canonical(value: Any) -> Any:
    """Return a comparable form of a message value; floats by their bits (NaN, -0.0)."""
    if isinstance(value, float):
        return struct.pack('<d', value)
    if isinstance(value, (str, bool, int, bytes)):
        return value
    if isinstance(value, np.ndarray):
        return value.dtype.str, value.tobytes()
    if isinstance(value, array.array):  # a uint8[] field: a point cloud's data
        return value.typecode, value.tobytes()
    if hasattr(type(value), 'get_fields_and_field_types'):
        return tuple((name, _canonical(getattr(value, name)))
                     for name in type(value).get_fields_and_field_types())
    return tuple(_canonical(item) for item in value)


class _Span(NamedTuple):
    """Where a located field lies in the template's bytes, and how it is packed."""

    path: str
    offset: int
    length: int             # how many values (bytes for a BytesSlot); 'count' is tuple's
    codes: str              # struct codes of the run, one per value
    dtype: Optional[str]    # 'float64', 'float32', ... when all values share one type


class FieldSlot:
    """
    A run of numeric values of a template, contiguous in its bytes: one value or many.

    Obtained from :meth:`MessageTemplate.field`; :meth:`set` rewrites them in the
    template's buffer. Not thread-safe (neither is the template).
    """

    __slots__ = ('path', 'offset', 'count', 'dtype', '_buffer', '_pack_into', '_view')

    def __init__(self, buffer: bytearray, span: _Span) -> None:
        self.path = span.path
        self.offset = span.offset
        self.count = span.length
        self.dtype = span.dtype
        self._buffer = buffer
        self._pack_into = struct.Struct('<' + span.codes).pack_into
        self._view: Optional[np.ndarray] = None
        if span.length and span.dtype in ('float64', 'float32'):
            # A numpy array handed to set() is copied in through this view: much
            # faster than unpacking it into struct.pack_into (360 ranges: see bench).
            self._view = np.frombuffer(buffer, np.dtype(span.dtype).newbyteorder('<'),
                                       span.length, span.offset)

    def set(self, values: Union[Sequence[float], np.ndarray]) -> None:
        """
        Write exactly ``count`` values: a sequence, or a 1-D numpy array.

        A wrong count raises ValueError and writes nothing; a value struct cannot
        pack (a string, an int out of range) raises ValueError after the slot was
        zeroed, since packing into a temporary first would cost ~120 ns per call.
        Arrays are cast as numpy casts (a float64 too large for float32 becomes
        inf), where a sequence's value would raise.
        """
        if len(values) != self.count:
            raise ValueError(f'{self.path}: expected {self.count} values, got {len(values)}')
        if self._view is not None and type(values) is np.ndarray:
            if values.ndim != 1:
                raise ValueError(f'{self.path}: expected a 1-D array, got shape {values.shape}')
            self._view[:] = values
            return
        try:
            self._pack_into(self._buffer, self.offset, *values)
        except struct.error as error:
            raise ValueError(f'{self.path}: {error}') from None

    def __repr__(self) -> str:
        return (f'FieldSlot({self.path!r}, offset={self.offset}, count={self.count}, '
                f'dtype={self.dtype!r})')


class StampSlot:
    """A builtin_interfaces/Time of a template, from :meth:`MessageTemplate.stamp`."""

    __slots__ = ('path', 'offset', '_buffer', '_pack_into')

    def __init__(self, buffer: bytearray, span: _Span) -> None:
        self.path = span.path
        self.offset = span.offset
        self._buffer = buffer
        self._pack_into = struct.Struct('<' + span.codes).pack_into

    def set(self, sec: int, nanosec: int) -> None:
        """Write a stamp; ``sec`` must fit int32, ``nanosec`` uint32 (else ValueError, zeroed)."""
        try:
            self._pack_into(self._buffer, self.offset, sec, nanosec)
        except struct.error as error:
            raise ValueError(f'{self.path}: sec={sec!r}, nanosec={nanosec!r}: {error}') from None

    def set_nanoseconds(self, nanoseconds: int) -> None:
        """Write a stamp given in integer nanoseconds, split as rclpy's Time.to_msg does."""
        sec, nanosec = divmod(nanoseconds, _NANOSECONDS_PER_SECOND)
        self.set(sec, nanosec)

    def __repr__(self) -> str:
        return f'StampSlot({self.path!r}, offset={self.offset})'


class BytesSlot:
    """
    A byte array of a template (a point cloud's ``data``): :meth:`MessageTemplate.bytes_field`.

    Its length is frozen with the template; :meth:`set` copies exactly
    ``count`` bytes in. Not thread-safe (neither is the template).
    """

    __slots__ = ('path', 'offset', 'count', '_view')

    def __init__(self, buffer: bytearray, path: str, offset: int, count: int) -> None:
        self.path = path
        self.offset = offset
        self.count = count
        self._view = np.frombuffer(buffer, np.uint8, count, offset)

    def set(self, data: Union[bytes, bytearray, memoryview, np.ndarray]) -> None:
        """Write exactly ``count`` bytes: bytes, or a contiguous numpy array of that many bytes."""
        if isinstance(data, np.ndarray):
            if not data.flags.c_contiguous:
                raise ValueError(f'{self.path}: expected a contiguous array')
            data = data.reshape(-1).view(np.uint8)
        else:
            data = np.frombuffer(data, np.uint8)
        if len(data) != self.count:
            raise ValueError(f'{self.path}: expected {self.count} bytes, got {len(data)}')
        self._view[:] = data

    def __repr__(self) -> str:
        return f'BytesSlot({self.path!r}, offset={self.offset}, count={self.count})'


class MessageTemplate:
    """
    A message serialized once, whose fixed-size numeric fields are patched in place.

    ``msg`` is a filled-in message; its strings and sequence lengths are frozen
    from here on (later changes to ``msg`` itself are not seen). Typical use::

        template = MessageTemplate(odometry)
        stamp, pose = template.stamp('header.stamp'), template.field('pose.pose')
        ...  # each step:
        stamp.set(sec, nanosec)
        pose.set(position + orientation)
        publisher.publish(template.to_bytes())
    """

    def __init__(self, msg: Any) -> None:
        if not hasattr(type(msg), 'SLOT_TYPES'):
            raise TypeError(f'expected a ROS message instance, got {type(msg).__name__}')
        self.message_type = type(msg)
        serialized = serialize(msg)
        kind = serialized[:2]
        if kind == _CDR_BE:
            raise ValueError('the serializer writes big-endian CDR; templates patch '
                             'little-endian values only')
        if kind != _CDR_LE:
            raise ValueError(f'unsupported serialization: encapsulation {kind.hex()}, '
                             f'expected {_CDR_LE.hex()} (plain little-endian CDR)')
        self._buffer = bytearray(serialized)
        self._serialized = bytes(serialized)
        # A private copy, normalized the way a subscriber sees it (float32 rounded).
        self._message = deserialize_message(serialized, self.message_type)

    def field(self, path: str, count: Optional[int] = None,
              dtype: Optional[str] = None) -> FieldSlot:
        """
        Locate a numeric field, or a contiguous run of them, by its path.

        ``path`` names a float64/float32/(u)int32/(u)int64 field, a fixed-size
        array or a sequence of them (at its current length), or a nested message
        whose numeric fields are contiguous: ``'pose.pose'`` (7 float64),
        ``'twist.twist'`` (6), ``'position'``, ``'ranges'``,
        ``'transforms[1].transform.translation'``. ``count`` and ``dtype``
        ('float64', np.float32, ...), when given, are checked against the field.
        """
        holder, key, type_def = _resolve(self._message, path)
        kinds = sorted({_DTYPE_NAMES[code] for code in _codes(type_def, path)})
        found_dtype = kinds[0] if len(kinds) == 1 else None
        if dtype is not None and np.dtype(dtype).name != found_dtype:
            raise FieldError(f'{path!r} holds {", ".join(kinds)}, not {dtype}')
        leaves = _leaves(holder, key, type_def)
        if count is not None and count != len(leaves):
            raise FieldError(f'{path!r} has {len(leaves)} values, not {count}')
        return FieldSlot(self._buffer, self._locate(path, leaves, found_dtype))

    def stamp(self, path: str = 'header.stamp') -> StampSlot:
        """Locate a builtin_interfaces/Time field: 'header.stamp', 'clock', ..."""
        holder, key, type_def = _resolve(self._message, path)
        if not (isinstance(type_def, NamespacedType)
                and type_def.namespaced_name() == ('builtin_interfaces', 'msg', 'Time')):
            raise FieldError(f'{path!r} is not a builtin_interfaces/Time')
        return StampSlot(self._buffer, self._locate(path, _leaves(holder, key, type_def), None))

    def bytes_field(self, path: str) -> BytesSlot:
        """
        Locate a ``uint8[]`` (or ``byte[]``) field by its path: ``'data'``; any length.

        Random bytes are put there, then the same bytes each flipped: the
        array lies where the first serialization holds the first and the
        second the second. A few bytes (a 1x1 camera's 12-byte cloud) may
        also occur elsewhere by chance, but seldom flipped in both; only
        alignment padding, which rmw leaves unwritten, changes besides.
        Found and proved as :meth:`field` finds numbers.
        """
        holder, key, type_def = _resolve(self._message, path)
        value_type = getattr(type_def, 'value_type', None)
        if not (isinstance(type_def, AbstractNestedType) and isinstance(value_type, BasicType)
                and value_type.typename in ('uint8', 'octet', 'int8', 'char')):
            raise FieldError(f'{path!r} is not a byte array')
        if not isinstance(key, str):
            raise FieldError(f'{path!r}: name the byte array itself, not an element of a list')
        original = _get(holder, key)
        count = len(original)
        if count == 0:
            return BytesSlot(self._buffer, path, 0, 0)  # nothing to patch, nothing to find
        try:
            for attempt in range(_LOCATE_ATTEMPTS):
                rng = np.random.default_rng(attempt)  # seeded: the same layout every run
                packed_a = rng.bytes(count)
                packed_b = bytes(np.frombuffer(packed_a, np.uint8) ^ 0xFF)
                setattr(holder, key, packed_b)
                serialized_b = serialize_message(self._message)
                setattr(holder, key, packed_a)
                serialized_a = serialize_message(self._message)
                offsets = [offset for offset in _occurrences(serialized_a, packed_a)
                           if serialized_b[offset:offset + count] == packed_b]
                if len(offsets) == 1:
                    break
            else:
                raise FieldError(f'{path!r}: its {count} bytes were not found in one place')
            self._prove(_Span(path, offsets[0], count, '', None), packed_a)
        finally:
            setattr(holder, key, original)
        return BytesSlot(self._buffer, path, offsets[0], count)

    def to_bytes(self) -> bytes:
        """Return the message as it stands, for ``publisher.publish`` (which wants bytes)."""
        return bytes(self._buffer)

    def to_message(self) -> Any:
        """Return the message as it stands, deserialized (for inspection and tests)."""
        return deserialize_message(bytes(self._buffer), self.message_type)

    def _locate(self, path: str, leaves: List[_Leaf], dtype: Optional[str]) -> _Span:
        """Find where ``leaves`` lie in the bytes by sentinels, and prove it (once per layout)."""
        codes = ''.join(leaf.code for leaf in leaves)
        # The bytes of the message as given fix its layout (every sequence's length), and
        # the search is seeded: the same message and path are found at the same place.
        # A farm builds the same templates for every run: found once per process.
        key = (self.message_type, self._serialized, path, codes, dtype)
        span = _LOCATED.get(key)
        if span is None:
            span = self._search(path, leaves, codes, dtype)
            if len(_LOCATED) >= _LOCATED_MAX:
                _LOCATED.clear()
            _LOCATED[key] = span
        return span

    def _search(self, path: str, leaves: List[_Leaf], codes: str, dtype: Optional[str]) -> _Span:
        """Find where ``leaves`` lie in the bytes by sentinels, and prove it."""
        if not leaves:
            # An empty sequence: nothing to patch, and nothing to find.
            return _Span(path, 0, 0, codes, dtype)
        size = struct.calcsize('<' + codes)
        originals = [_get(leaf.holder, leaf.key) for leaf in leaves]
        try:
            for attempt in range(_LOCATE_ATTEMPTS):
                # Seeded: a template is laid out the same way on every run.
                rng = random.Random(attempt)
                packed_a, values_a = _sentinels(codes, rng)
                packed_b, values_b = _sentinels(codes, rng)
                _write(leaves, values_b)
                serialized_b = serialize_message(self._message)
                _write(leaves, values_a)
                serialized_a = serialize_message(self._message)
                # Padding bytes hold whatever was in memory, so two serializations
                # may differ outside the field: look for both sentinels, not a diff.
                offsets = [offset for offset in _occurrences(serialized_a, packed_a)
                           if serialized_b[offset:offset + size] == packed_b]
                if len(offsets) == 1:
                    break
            else:
                raise FieldError(
                    f'{path!r}: its {len(leaves)} values are not one contiguous run of '
                    f'{size} bytes in the serialized message (alignment padding between '
                    'them?); locate its parts separately')
            span = _Span(path, offsets[0], len(leaves), codes, dtype)
            self._prove(span, packed_a)
        finally:
            _write(leaves, originals)
        return span

    def _prove(self, span: _Span, packed: bytes) -> None:
        """Check that the template with ``packed`` at ``span`` reads back as the message."""
        end = span.offset + len(packed)
        patched = bytes(self._buffer[:span.offset]) + packed + bytes(self._buffer[end:])
        problem = 'do not read back as the expected message'
        try:
            if _canonical(deserialize_message(patched, self.message_type)) == _canonical(
                    self._message):
                return
        except Exception as error:  # rclpy's RMWError is not public; any failure is ours
            problem = f'do not deserialize ({error})'
        raise FieldError(f'{span.path!r}: found at byte {span.offset}, but the bytes '
                         f'patched there {problem}')


# Spans found, by message type, bytes, path, codes and dtype (see MessageTemplate._locate).
_LOCATED: Dict[Tuple[Any, bytes, str, str, Optional[str]], _Span] = {}
_LOCATED_MAX = 1024


def _occurrences(haystack: bytes, needle: bytes) -> List[int]:
    """Return every offset at which ``needle`` starts in ``haystack``."""
    offsets = []
    start = haystack.find(needle)
    while start >= 0:
        offsets.append(start)
        start = haystack.find(needle, start + 1)
    return offsets
