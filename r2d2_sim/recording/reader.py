"""
Reading an MCAP recording that may come from anywhere: record by record, within bounds.

A recording is data, often from another machine, so nothing in it chooses
what runs or how much memory is used:

- **Types.** :func:`message_class` imports a message class only for a
  ``pkg/msg/Type`` (or ``pkg/Type``) whose ``share/<pkg>/msg/<Type>.msg`` an
  installed ROS interface package provides (see
  :func:`~r2d2_sim.recording.message_definitions.known_message_type`), so a
  schema named ``this/Foo`` imports nothing.
- **Bounds.** A chunk may declare at most :data:`MAX_CHUNK_BYTES` and
  decompress to no more than it declares (decompression is streamed, so a
  lie is caught after that many bytes); one pass over the file may
  decompress at most ``max_bytes`` (by default the larger of
  :data:`MIN_PASS_BYTES` and :data:`PASS_BYTES_PER_FILE_BYTE` times the
  file's size); a record read whole may be at most :data:`MAX_CHUNK_BYTES`
  (attachments and indexes are skipped unread). A 65 KB file whose one chunk
  decompresses to 2 GiB is refused before any of it is decompressed.
- **Cut-off files.** The file is read from its start, never from its summary,
  so a file whose recorder was killed or ran out of disk space (no summary,
  no footer, a last record half written) gives every message of its complete
  records; :attr:`RecordingFile.cut_short` says it happened. A damaged record
  ends the readable part the same way.

Every problem is a :class:`RecordingError` with a one-line message. Needs
``zstandard`` for zstd chunks and ``lz4`` for lz4 ones (the ``mcap``
package's own dependencies); rclpy is not needed.
"""

import importlib
import os
import stat
import struct
from typing import Dict, Iterable, Iterator, List, NamedTuple, Optional, Tuple, Union

from r2d2_sim.recording.message_definitions import known_message_type, UnknownMessageType

__all__ = ['MAX_CHANNELS', 'MAX_CHUNK_BYTES', 'MIN_PASS_BYTES', 'PASS_BYTES_PER_FILE_BYTE',
           'RawMessage', 'RecordedChannel', 'RecordingError', 'RecordingFile', 'message_class']

# The most one chunk may declare (and so decompress to), and the most one
# record may hold when read whole: far above the 1 MiB chunks foxglove-sdk
# and rosbag2 write, and above one 4K camera image (25 MB) in a chunk of its own.
MAX_CHUNK_BYTES = 256 * 2**20
# One pass over a file may decompress the larger of these: 1 GiB, or 100 times
# the file's size (our own recordings compress about 7 to 1).
MIN_PASS_BYTES = 2**30
PASS_BYTES_PER_FILE_BYTE = 100
# Channels a file may define: each playable one becomes a publisher. A
# recording of 440 spawned namespaces had 2,214.
MAX_CHANNELS = 10_000

MAGIC = b'\x89MCAP0\r\n'
# Opcodes of the MCAP specification that are read here; others are skipped.
_HEADER, _FOOTER, _SCHEMA, _CHANNEL, _MESSAGE, _CHUNK, _DATA_END = 1, 2, 3, 4, 5, 6, 0x0F
_RECORD = struct.Struct('<BQ')            # opcode, length
_MESSAGE_HEAD = struct.Struct('<HIQQ')    # channel id, sequence, log time, publish time
_CHUNK_HEAD = struct.Struct('<QQQI')      # start time, end time, uncompressed size, crc
_U16, _U32, _U64 = struct.Struct('<H'), struct.Struct('<I'), struct.Struct('<Q')


class RecordingError(Exception):
    """A recording that cannot be read, or is refused (the message is one line)."""


class _Damaged(Exception):
    """A record that is not what the specification says (ends the readable part)."""


class RecordedChannel(NamedTuple):
    """A channel of the file: its topic, its schema's type name ('' without one), metadata."""

    id: int
    topic: str
    type_name: str
    message_encoding: str
    metadata: Dict[str, str]


class RawMessage(NamedTuple):
    """One recorded message: its channel id, log time (ns) and serialized bytes."""

    channel_id: int
    log_time_ns: int
    data: bytes


def message_class(type_name: str) -> type:
    """
    Return the rclpy message class of ``pkg/msg/Type`` (or ``pkg/Type``) from a recording.

    Imports ``pkg.msg`` only when an installed ROS interface package defines
    the type (its ``.msg`` file is there); raises UnknownMessageType, with
    why, for anything else, having imported nothing.
    """
    full_name = known_message_type(type_name)
    package, _, name = full_name.split('/')
    try:
        module = importlib.import_module(f'{package}.msg')
    except ImportError as exc:
        raise UnknownMessageType(f'{full_name}: {package}.msg cannot be imported ({exc})') \
            from None
    cls = getattr(module, name, None)
    if not isinstance(cls, type) or not callable(getattr(cls, '__import_type_support__', None)):
        raise UnknownMessageType(f'{full_name}: {package}.msg has no message class {name}')
    return cls


def _string(body: memoryview, offset: int) -> Tuple[str, int]:
    """Return a length-prefixed UTF-8 string at ``offset`` and the offset after it."""
    if offset + 4 > len(body):
        raise _Damaged('a string runs past its record')
    (length,) = _U32.unpack_from(body, offset)
    end = offset + 4 + length
    if end > len(body):
        raise _Damaged('a string runs past its record')
    try:
        return str(body[offset + 4:end], 'utf-8'), end
    except UnicodeDecodeError:
        raise _Damaged('a string is not UTF-8') from None


def _schema(body: memoryview) -> Tuple[int, str]:
    if len(body) < 2:
        raise _Damaged('a schema record is too short')
    (schema_id,) = _U16.unpack_from(body, 0)
    name, _ = _string(body, 2)
    return schema_id, name


def _channel(body: memoryview) -> Tuple[int, int, str, str, Dict[str, str]]:
    if len(body) < 4:
        raise _Damaged('a channel record is too short')
    channel_id, schema_id = struct.unpack_from('<HH', body, 0)
    topic, offset = _string(body, 4)
    encoding, offset = _string(body, offset)
    if offset + 4 > len(body):
        raise _Damaged('a channel record is too short')
    (map_length,) = _U32.unpack_from(body, offset)
    offset += 4
    end = offset + map_length
    if end > len(body):
        raise _Damaged("a channel's metadata runs past its record")
    metadata = {}
    while offset < end:
        key, offset = _string(body, offset)
        metadata[key], offset = _string(body, offset)
    return channel_id, schema_id, topic, encoding, metadata


def _decompress(compression: str, data: memoryview,
                size: int) -> Union[bytes, bytearray, memoryview]:
    """Return a chunk's records (bytes-like), never producing more than ``size`` + 1 bytes."""
    if compression == '':
        return data
    if compression == 'zstd':
        try:
            import zstandard
        except ImportError:
            raise RecordingError('its chunks are zstd-compressed: reading them needs the '
                                 'zstandard package (pip install zstandard)') from None
        # Streamed into one buffer of the declared size and a byte: a chunk
        # that holds more than it declares is caught at that byte.
        output = bytearray(size + 1)
        view = memoryview(output)
        produced = 0
        try:
            with zstandard.ZstdDecompressor().stream_reader(
                    data, read_across_frames=True) as reader:
                while produced <= size:
                    count = reader.readinto(view[produced:])
                    if count == 0:
                        break
                    produced += count
        except zstandard.ZstdError as exc:
            raise _Damaged(f'zstd: {exc}') from None
        view.release()
        del output[produced:]
        return output
    if compression == 'lz4':
        try:
            import lz4.frame
        except ImportError:
            raise RecordingError('its chunks are lz4-compressed: reading them needs the '
                                 'lz4 package (pip install lz4)') from None
        try:
            return lz4.frame.LZ4FrameDecompressor().decompress(bytes(data), max_length=size + 1)
        except RuntimeError as exc:
            raise _Damaged(f'lz4: {exc}') from None
    raise RecordingError(f'a chunk is compressed with {compression[:40]!r}, which this reader '
                         'does not know (only zstd and lz4)')


class RecordingFile:
    """
    An MCAP file, read once from its start to learn its channels and to check every bound.

    ``channels`` (by id), ``message_counts`` (by channel id), ``message_count``,
    ``first_time_ns`` and ``last_time_ns`` describe the readable part;
    ``cut_short`` is True when the file ends without its data section's end
    (a recorder killed or out of disk space, or a damaged record), with
    ``readable_bytes`` of ``size`` bytes read. :meth:`messages` reads the
    same part again. ``max_bytes``: what one pass may decompress (None: the
    default bound). Raises :class:`RecordingError`.
    """

    def __init__(self, path: Union[str, os.PathLike[str]],
                 max_bytes: Optional[int] = None) -> None:
        self.path = os.fspath(path)
        try:
            if not stat.S_ISREG(os.stat(self.path).st_mode):  # a FIFO would block open()
                raise RecordingError(f'{self.path} is not a regular file')
            with open(self.path, 'rb') as stream:
                self.size = os.fstat(stream.fileno()).st_size
                head = stream.read(len(MAGIC))
        except OSError as exc:
            raise RecordingError(f'cannot open {self.path}: {exc.strerror or exc}') from None
        if head != MAGIC:
            raise RecordingError(f'{self.path} is not a readable MCAP file '
                                 f'(it does not start as one)')
        self.max_bytes = max_bytes if max_bytes is not None else max(
            MIN_PASS_BYTES, PASS_BYTES_PER_FILE_BYTE * self.size)
        self.channels: Dict[int, RecordedChannel] = {}
        self.message_counts: Dict[int, int] = {}
        self.message_count = 0
        self.first_time_ns: Optional[int] = None
        self.last_time_ns: Optional[int] = None
        self.cut_short = False
        self.damage: Optional[str] = None
        self.readable_bytes = len(MAGIC)
        self._end = self.size
        self._scan()

    def _scan(self) -> None:
        schemas: Dict[int, str] = {}
        channels: Dict[int, Tuple[int, str, str, Dict[str, str]]] = {}
        counts: Dict[int, int] = {}
        first = last = None
        for kind, item in self._walk(scanning=True):
            if kind == _MESSAGE:
                channel_id, log_time = item[0], item[1]
                counts[channel_id] = counts.get(channel_id, 0) + 1
                first = log_time if first is None else min(first, log_time)
                last = log_time if last is None else max(last, log_time)
            elif kind == _SCHEMA:
                schemas.setdefault(item[0], item[1])
            elif kind == _CHANNEL and item[0] not in channels:
                if len(channels) >= MAX_CHANNELS:
                    raise RecordingError(f'{self.path} defines more than {MAX_CHANNELS} '
                                         'channels: refused')
                channels[item[0]] = item[1:]
            del item  # a message's bytes keep its chunk alive while the next one is read
        for channel_id, (schema_id, topic, encoding, metadata) in channels.items():
            self.channels[channel_id] = RecordedChannel(
                channel_id, topic, schemas.get(schema_id, ''), encoding, metadata)
        self.message_counts = {c: n for c, n in counts.items() if c in self.channels}
        self.message_count = sum(self.message_counts.values())
        self.first_time_ns, self.last_time_ns = first, last

    def messages(self, channel_ids: Optional[Iterable[int]] = None) -> Iterator[RawMessage]:
        """
        Yield the messages of the readable part in file order, of ``channel_ids`` (default all).

        Recorders write in log-time order; within a chunk the order is the
        writer's. Raises :class:`RecordingError` if the file changed since it
        was opened.
        """
        wanted = frozenset(self.channels if channel_ids is None else channel_ids)
        for kind, item in self._walk(scanning=False):
            if kind == _MESSAGE and item[0] in wanted:
                message = RawMessage(item[0], item[1], bytes(item[2]))
                del item  # not to keep this chunk alive while the next one is read
                yield message

    def describe_cut(self) -> str:
        """Return one line on what a cut-short file still held (for the user)."""
        first, last = self.first_time_ns, self.last_time_ns  # both None without messages
        seconds = 0.0 if first is None or last is None else (last - first) * 1e-9
        why = f'damaged at byte {self.readable_bytes} ({self.damage})' if self.damage else \
            'its recorder did not close it (killed, or out of disk space?)'
        return (f'{self.path} was cut short: {why}; recovered {self.message_count} messages '
                f'on {len(self.message_counts)} topics, {seconds:.2f} s of log time, from the '
                f'first {self.readable_bytes} of its {self.size} bytes')

    def _walk(self, scanning: bool) -> Iterator[Tuple[int, tuple]]:
        """
        Yield (opcode, fields) of the schemas, channels and messages, chunks opened, in order.

        While ``scanning``, note where the readable part ends (the data
        section's end, the first incomplete or damaged record); afterwards,
        read up to there.
        """
        budget = [self.max_bytes]
        try:
            with open(self.path, 'rb') as stream:
                position = len(MAGIC)
                stream.seek(position)
                while position < self._end:
                    head = stream.read(_RECORD.size)
                    if len(head) < _RECORD.size:
                        self._stop(scanning, position, cut=True)
                        break
                    opcode, length = _RECORD.unpack(head)
                    # Opcode 0 is reserved: zeros where a crash left the end unwritten.
                    if opcode == 0 or length > self.size - position - _RECORD.size:
                        self._stop(scanning, position, cut=True)
                        break
                    if opcode in (_DATA_END, _FOOTER):
                        self._stop(scanning, position, cut=False)
                        break
                    if opcode in (_SCHEMA, _CHANNEL, _MESSAGE, _CHUNK):
                        if length > MAX_CHUNK_BYTES:
                            raise RecordingError(
                                f'{self.path}: the record at byte {position} holds {length} '
                                f'bytes, more than the {MAX_CHUNK_BYTES} one record may hold '
                                'here: refused')
                        body = memoryview(stream.read(length))
                        if len(body) < length:
                            self._stop(scanning, position, cut=True)
                            break
                        try:
                            if opcode == _CHUNK:
                                yield from self._chunk(body, budget, position)
                            else:
                                yield from _parse(opcode, body)
                        except _Damaged as exc:
                            if not scanning:
                                raise RecordingError(
                                    f'{self.path} changed while it was read: {exc}') from None
                            self._stop(scanning, position, cut=True, damage=str(exc))
                            break
                    else:  # attachments, indexes, metadata: not needed here
                        stream.seek(length, os.SEEK_CUR)
                    position += _RECORD.size + length
                    if scanning:
                        self.readable_bytes = position
                else:  # the file ends at a record's end, before its data section's
                    self._stop(scanning, position, cut=True)
        except OSError as exc:
            raise RecordingError(f'cannot read {self.path}: {exc.strerror or exc}') from None

    def _stop(self, scanning: bool, position: int, cut: bool,
              damage: Optional[str] = None) -> None:
        """Note, while scanning, that the readable part ends at ``position``."""
        if scanning:
            self._end = position
            self.cut_short = cut
            self.damage = damage

    def _chunk(self, body: memoryview, budget: List[int],
               position: int) -> Iterator[Tuple[int, tuple]]:
        """Yield the records of a chunk, decompressed within the bounds."""
        if len(body) < _CHUNK_HEAD.size:
            raise _Damaged('a chunk record is too short')
        _, _, size, _ = _CHUNK_HEAD.unpack_from(body, 0)
        compression, offset = _string(body, _CHUNK_HEAD.size)
        if offset + 8 > len(body):
            raise _Damaged('a chunk record is too short')
        (records_length,) = _U64.unpack_from(body, offset)
        offset += 8
        if records_length > len(body) - offset:
            raise _Damaged("a chunk's records run past it")
        if size > MAX_CHUNK_BYTES:
            raise RecordingError(
                f'{self.path}: the chunk at byte {position} would decompress to {size} '
                f'bytes, more than the {MAX_CHUNK_BYTES} a chunk may hold here: refused '
                '(a compression bomb?)')
        if size > budget[0]:
            raise RecordingError(
                f'{self.path} would decompress to more than {self.max_bytes} bytes in one '
                'pass: refused (a compression bomb?)')
        budget[0] -= size
        records = _decompress(compression, body[offset:offset + records_length], size)
        if len(records) > size:
            raise RecordingError(
                f'{self.path}: the chunk at byte {position} decompresses to more than the '
                f'{size} bytes it declares: refused (a compression bomb?)')
        if len(records) < size:
            raise _Damaged(f'a chunk holds {len(records)} of the {size} bytes it declares')
        view = memoryview(records)
        offset = 0
        while offset < len(view):
            if len(view) - offset < _RECORD.size:
                raise _Damaged('a record in a chunk is cut off')
            opcode, length = _RECORD.unpack_from(view, offset)
            start = offset + _RECORD.size
            if opcode == 0 or length > len(view) - start:
                raise _Damaged('a record in a chunk is cut off or invalid')
            yield from _parse(opcode, view[start:start + length])
            offset = start + length


def _parse(opcode: int, body: memoryview) -> Iterator[Tuple[int, tuple]]:
    if opcode == _MESSAGE:
        if len(body) < _MESSAGE_HEAD.size:
            raise _Damaged('a message record is too short')
        channel_id, _, log_time, _ = _MESSAGE_HEAD.unpack_from(body, 0)
        yield _MESSAGE, (channel_id, log_time, body[_MESSAGE_HEAD.size:])
    elif opcode == _SCHEMA:
        yield _SCHEMA, _schema(body)
    elif opcode == _CHANNEL:
        yield _CHANNEL, _channel(body)
