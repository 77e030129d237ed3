"""Reading a recording into typed messages per topic: :func:`read_recording`."""

import os
from typing import Any, Dict, Iterable, List, NamedTuple, Optional, Tuple, Union

from r2d2_sim.recording.message_definitions import UnknownMessageType
from r2d2_sim.recording.reader import (
    message_class, RecordedChannel, RecordingError, RecordingFile)

__all__ = ['RecordedMessage', 'RecordingError', 'read_recording', 'MAX_MESSAGES']

# The most messages read_recording keeps by default: a typed message costs
# several times its bytes in Python objects.
MAX_MESSAGES = 1_000_000


class RecordedMessage(NamedTuple):
    """One message of a recording: ``log_time_ns`` (the sink's simulated time) and ``message``."""

    log_time_ns: int
    message: Any


def read_recording(path: Union[str, os.PathLike[str]],
                   topics: Optional[Iterable[str]] = None, *,
                   max_messages: int = MAX_MESSAGES,
                   max_bytes: Optional[int] = None) -> Dict[str, List[RecordedMessage]]:
    """
    Return the messages of an MCAP recording, typed, by topic, in the order they were written.

    ``read_recording('run.mcap')['/odom'][-1].message`` is the last recorded
    ``Odometry``. ``topics``: only these, or this one (each must be in the file with a
    type this machine has); default every topic whose type an installed ROS
    interface package defines (others are left out). Read as ``replay``
    reads (:class:`~r2d2_sim.recording.reader.RecordingFile`): types only
    from installed interface packages, decompression bounded by ``max_bytes``
    (default: the larger of 1 GiB and 100 times the file's size), and a file
    whose recorder was killed gives the messages of its complete records.
    Raises :class:`RecordingError` (one line) for a file that cannot be read,
    a requested topic that is missing or of an unknown type, bytes that are
    not their topic's type, or more than ``max_messages`` messages.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise RecordingError(f'read_recording takes the path of an MCAP file, got '
                             f'{type(path).__name__}')
    recording = RecordingFile(path, max_bytes)
    # One topic as a string: itself, not its letters (it was read as '/', 'o', 'd'...).
    wanted = None if topics is None else [topics] if isinstance(topics, str) else list(topics)
    by_topic: Dict[str, List[RecordedChannel]] = {}
    for channel in recording.channels.values():
        if channel.message_encoding == 'cdr' and (wanted is None or channel.topic in wanted):
            by_topic.setdefault(channel.topic, []).append(channel)
    classes: Dict[int, Tuple[str, type]] = {}
    refused: Dict[str, str] = {}
    for topic, channels in by_topic.items():
        for channel in channels:
            try:
                classes[channel.id] = (topic, message_class(channel.type_name))
            except UnknownMessageType as exc:
                refused[topic] = str(exc)
    if wanted is not None:
        for topic in wanted:
            if topic in refused:
                raise RecordingError(f'{recording.path}: {topic!r} cannot be read: '
                                     f'{refused[topic]}')
            if topic not in by_topic:
                raise RecordingError(f'{recording.path} has no cdr topic {topic!r}; it has '
                                     f'{sorted(c.topic for c in recording.channels.values())}')
    count = sum(recording.message_counts.get(channel_id, 0) for channel_id in classes)
    if count > max_messages:
        raise RecordingError(f'{recording.path} holds {count} messages, more than '
                             f'max_messages={max_messages}')
    from rclpy.serialization import deserialize_message
    result: Dict[str, List[RecordedMessage]] = {topic: [] for topic, _ in classes.values()}
    for channel_id, log_time_ns, data in recording.messages(classes):
        topic, cls = classes[channel_id]
        try:
            message = deserialize_message(data, cls)
        except Exception as exc:  # rclpy raises assorted types for bytes of another type
            raise RecordingError(
                f'{recording.path}: a message on {topic!r} at {log_time_ns} ns is not a '
                f'{cls.__module__.split(".")[0]}/msg/{cls.__name__}: '
                f'{" ".join(str(exc).split())[:200]}') from None
        result[topic].append(RecordedMessage(log_time_ns, message))
    return result
