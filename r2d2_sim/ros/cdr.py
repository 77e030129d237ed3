"""
Canonical CDR: a message serialized as rclpy does, with zeros in every padding byte.

rclpy's serializer leaves CDR's alignment padding (and a few bytes past the
end) as whatever was in memory, so one message gave different bytes in two
runs, and two recordings of one run different hashes. :func:`serialize`
writes zeros there: the same message gives the same bytes, always. Where the
padding lies follows from CDR's alignment rules over the message's fields
(:func:`layout`), and is checked: the bytes laid out must fit the bytes
serialized. The node's templates (:mod:`r2d2_sim.ros.serialization`), its
recordings and its live view all start from these bytes.
"""

from typing import Any, List, Tuple

from rclpy.serialization import serialize_message
from rosidl_parser.definition import (
    AbstractGenericString, AbstractNestedType, AbstractSequence, AbstractWString, BasicType)

__all__ = ['serialize', 'message_bytes', 'ros_type_name', 'layout', 'fields']

# Bytes of each basic type in CDR, which is also its alignment.
_CDR_SIZES = {'boolean': 1, 'octet': 1, 'char': 1, 'uint8': 1, 'int8': 1, 'int16': 2,
              'uint16': 2, 'wchar': 2, 'int32': 4, 'uint32': 4, 'float': 4, 'int64': 8,
              'uint64': 8, 'double': 8}


def fields(message: Any) -> List[Tuple[str, Any]]:
    """Return (name, rosidl type) of each field of a message, in serialization order."""
    message_class = type(message)
    return list(zip(message_class.get_fields_and_field_types(), message_class.SLOT_TYPES))


def serialize(msg: Any) -> bytes:
    """
    Serialize a message as rclpy does, with zeros in every padding byte: the same bytes always.

    ValueError (one line) for a message whose layout this does not follow
    (wide strings) or whose bytes do not match it.
    """
    serialized = bytearray(serialize_message(msg))
    pads: List[Tuple[int, int]] = []
    end = layout(msg, None, 0, pads)
    data = len(serialized) - 4  # after the encapsulation header
    if end > data:
        raise ValueError(f'{type(msg).__name__}: {data} bytes serialized, {end} laid out')
    for offset, size in pads:
        serialized[4 + offset:4 + offset + size] = bytes(size)
    serialized[4 + end:] = bytes(data - end)  # what the serializer leaves past the end
    return bytes(serialized)


def message_bytes(msg: Any, msg_type: type) -> bytes:
    """
    Return what a publisher of ``msg_type`` sends for ``msg``: its bytes, or serialized.

    A message already serialized goes as it is; a typed one is serialized
    once (:func:`serialize`); anything else is rclpy's TypeError, before any
    byte goes out.
    """
    if type(msg) is bytes:
        return msg
    if isinstance(msg, msg_type):
        return serialize(msg)
    raise TypeError(f'Expected {msg_type}, got {type(msg)}')


def ros_type_name(msg_type: type) -> str:
    """Return the ROS name of an rclpy message class: ``sensor_msgs/msg/LaserScan``."""
    package = msg_type.__module__.split('.', 1)[0]
    return f'{package}/msg/{msg_type.__name__}'


def _align(offset: int, size: int, pads: List[Tuple[int, int]]) -> int:
    """Return ``offset`` aligned to ``size``, noting the padding in between."""
    pad = -offset % size
    if pad:
        pads.append((offset, pad))
    return offset + pad


def layout(value: Any, type_def: Any, offset: int, pads: List[Tuple[int, int]]) -> int:
    """
    Lay out ``value`` (of rosidl type ``type_def``; None: a message) in CDR from ``offset``.

    Returns the offset after it and notes each run of padding in ``pads``:
    plain CDR aligns every value to its own size from the data's start; a
    string is a uint32 length (its NUL included) and its bytes; a sequence a
    uint32 count and its elements; an array its elements. rclpy holds arrays
    of numbers in numpy arrays and sequences of them in array.array.
    """
    if isinstance(type_def, BasicType):
        size = _CDR_SIZES[type_def.typename]
        return _align(offset, size, pads) + size
    if isinstance(type_def, AbstractWString):
        raise ValueError('wide strings are not laid out here')
    if isinstance(type_def, AbstractGenericString):
        return _align(offset, 4, pads) + 4 + len(value.encode('utf-8')) + 1
    if isinstance(type_def, AbstractNestedType):
        if isinstance(type_def, AbstractSequence):
            offset = _align(offset, 4, pads) + 4
        element = type_def.value_type
        if isinstance(element, BasicType):
            # A run of numbers is aligned once, and not at all when empty.
            size = _CDR_SIZES[element.typename]
            return _align(offset, size, pads) + size * len(value) if len(value) else offset
        for item in value:
            offset = layout(item, element, offset, pads)
        return offset
    for name, field_type in fields(value):
        offset = layout(getattr(value, name), field_type, offset, pads)
    return offset
