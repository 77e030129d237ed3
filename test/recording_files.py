"""
MCAP files made by hand for the tests of reading recordings: hostile, cut off, or plain.

Written with the ``mcap`` package's own record classes (not with the reader
under test), so a file here is what the MCAP specification says it is:
magic, header, data records, data end, a summary with chunk indexes (what
``mcap``'s indexed reader follows), footer, magic.
"""

import zlib
from pathlib import Path
from typing import Dict, Iterable, List, NamedTuple, Sequence

from mcap.data_stream import RecordBuilder
from mcap.records import (Channel, Chunk, ChunkIndex, DataEnd, Footer, Header, Message, Schema,
                          Statistics)
from mcap.writer import MCAP0_MAGIC
from rclpy.qos import QoSProfile
from rclpy.serialization import serialize_message
from std_msgs.msg import String
import zstandard

from r2d2_sim.recording.message_definitions import offered_qos_profiles

MESSAGE_HEADER_BYTES = 31  # opcode, length, channel id, sequence, log and publish time
GIB = 2**30
MIB = 2**20


class Topic(NamedTuple):
    """A channel to write: its id, topic, schema name and offered_qos_profiles text."""

    channel_id: int
    topic: str
    type_name: str = 'std_msgs/msg/String'
    qos_text: str = offered_qos_profiles(QoSProfile(depth=10))


def string_bytes(text: str) -> bytes:
    """Return a std_msgs/String serialized as the node serializes it."""
    return serialize_message(String(data=text))


def _records(records: Iterable) -> bytes:
    builder = RecordBuilder()
    for record in records:
        record.write(builder)
    return builder.end()


def _schemas_and_channels(topics: Sequence[Topic]) -> List:
    records, schema_ids = [], {}
    for topic in topics:
        if topic.type_name not in schema_ids:
            schema_ids[topic.type_name] = len(schema_ids) + 1
            records.append(Schema(id=schema_ids[topic.type_name], name=topic.type_name,
                                  encoding='ros2msg', data=b'string data\n'))
        records.append(Channel(id=topic.channel_id, topic=topic.topic, message_encoding='cdr',
                               metadata={'offered_qos_profiles': topic.qos_text},
                               schema_id=schema_ids[topic.type_name]))
    return records


def zstd_chunk(messages: Sequence[Message]) -> Chunk:
    """Return an honest zstd chunk of ``messages``."""
    data = _records(messages)
    return Chunk(compression='zstd', data=zstandard.ZstdCompressor().compress(data),
                 message_start_time=min(m.log_time for m in messages),
                 message_end_time=max(m.log_time for m in messages),
                 uncompressed_crc=zlib.crc32(data), uncompressed_size=len(data))


def bomb_chunk(channel_id: int, message_bytes: int, declared_size: int = 0) -> Chunk:
    """
    Return a zstd chunk holding one message of ``message_bytes`` zeros, compressed as a stream.

    A 2 GiB message costs about 64 KB and 0.3 s to make, and no memory.
    ``declared_size``: the uncompressed size the chunk claims (0: the truth).
    """
    head = bytes([5]) + (message_bytes + 22).to_bytes(8, 'little')
    head += channel_id.to_bytes(2, 'little') + bytes(4 + 8 + 8)
    compressor = zstandard.ZstdCompressor(level=1).compressobj()
    parts = [compressor.compress(bytes(head))]
    zeros = bytes(16 * MIB)
    left = message_bytes
    while left > 0:
        parts.append(compressor.compress(zeros[:min(left, len(zeros))]))
        left -= len(zeros)
    parts.append(compressor.flush())
    size = MESSAGE_HEADER_BYTES + message_bytes
    return Chunk(compression='zstd', data=b''.join(parts), message_start_time=0,
                 message_end_time=0, uncompressed_crc=0,
                 uncompressed_size=declared_size or size)


def write_mcap(path: Path, topics: Sequence[Topic], data: Sequence, summary: bool = True,
               message_counts: Dict[int, int] = None) -> Path:
    """
    Write an MCAP file: ``topics``' schemas and channels, then ``data`` (messages or chunks).

    With ``summary``, the summary section repeats them and indexes every
    chunk, as ``mcap``'s and rosbag2's writers do. Returns ``path``.
    """
    builder = RecordBuilder()
    builder.write(MCAP0_MAGIC)
    Header(profile='ros2', library='recording_files').write(builder)
    for record in _schemas_and_channels(topics):
        record.write(builder)
    chunk_indexes = []
    for record in data:
        start = builder.count
        record.write(builder)
        if isinstance(record, Chunk):
            chunk_indexes.append(ChunkIndex(
                message_start_time=record.message_start_time,
                message_end_time=record.message_end_time, chunk_start_offset=start,
                chunk_length=builder.count - start, message_index_offsets={},
                message_index_length=0, compression=record.compression,
                compressed_size=len(record.data), uncompressed_size=record.uncompressed_size))
    DataEnd(data_section_crc=0).write(builder)
    summary_start = builder.count if summary else 0
    if summary:
        for record in _schemas_and_channels(topics):
            record.write(builder)
        counts = message_counts or {}
        Statistics(message_count=sum(counts.values()), schema_count=len(topics),
                   channel_count=len(topics), attachment_count=0, metadata_count=0,
                   chunk_count=len(chunk_indexes), message_start_time=0, message_end_time=0,
                   channel_message_counts=counts).write(builder)
        for index in chunk_indexes:
            index.write(builder)
    Footer(summary_start=summary_start, summary_offset_start=0, summary_crc=0).write(builder)
    builder.write(MCAP0_MAGIC)
    path.write_bytes(builder.end())
    return path


def plain_messages(channel_id: int, texts: Sequence[str], period_ns: int = 10**8) -> List:
    """Return Message records of std_msgs/String ``texts``, ``period_ns`` apart in log time."""
    return [Message(channel_id=channel_id, sequence=i, log_time=i * period_ns,
                    publish_time=i * period_ns, data=string_bytes(text))
            for i, text in enumerate(texts)]


def complete_messages(path: Path) -> List[Message]:
    """
    Return the messages ``mcap``'s own sequential reader gets from a file before it fails.

    The reference for a cut-off file: every message of the records before
    the first incomplete one, in file order.
    """
    from mcap.stream_reader import StreamReader
    messages = []
    try:
        for record in StreamReader(str(path)).records:
            if isinstance(record, Message):
                messages.append(record)
    except Exception:  # mcap fails at the cut with assorted types
        pass
    return messages
