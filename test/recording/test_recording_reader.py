"""
Reading recordings from anywhere (r2d2_sim.recording.reader): types, bounds, cut-off files.

The files are written here with the ``mcap`` package (its writer, or its
record classes in ``recording_files.py``); what a cut-off file still holds
is what ``mcap``'s own sequential reader gets from it before it fails.
"""

import importlib
import os
import random
import sys

from mcap.records import Message
from mcap.writer import CompressionType, Writer
import pytest
from std_msgs.msg import String

from r2d2_sim.recording.message_definitions import offered_qos_profiles, UnknownMessageType
from r2d2_sim.recording.reader import (MAX_CHANNELS, MAX_CHUNK_BYTES, message_class,
                                       MIN_PASS_BYTES, RecordingError, RecordingFile)
from r2d2_sim.recording.sink import FoxgloveSink
from recording_files import (bomb_chunk, complete_messages, MIB, plain_messages, Topic,
                             write_mcap, zstd_chunk)
from sample_messages import samples, TOPICS


def write_drive(path, drive, compression=CompressionType.ZSTD, chunk_size=4096):
    """Write samples with mcap's writer in small chunks; return {channel id: topic}."""
    topics = {}
    with open(path, 'wb') as stream:
        writer = Writer(stream, chunk_size=chunk_size, compression=compression)
        writer.start('ros2', 'test_recording_reader')
        for sample in drive:
            if sample.topic not in topics.values():
                schema = writer.register_schema(sample.type_name, 'ros2msg', b'')
                channel = writer.register_channel(
                    sample.topic, 'cdr', schema,
                    {'offered_qos_profiles': offered_qos_profiles(TOPICS[sample.topic][1])})
                topics[channel] = sample.topic
            channel = next(c for c, t in topics.items() if t == sample.topic)
            writer.add_message(channel, sample.time_ns, sample.data, sample.time_ns)
        writer.finish()
    return topics


@pytest.fixture(scope='module')
def drive(tmp_path_factory):
    """Return (path, {channel id: topic}, samples) of a 2 s drive in 4 KiB zstd chunks."""
    path = tmp_path_factory.mktemp('reader') / 'drive.mcap'
    # Serialized once: CDR padding bytes are whatever memory held, so two
    # serializations of one message may differ.
    drive = samples(2.0)
    return path, write_drive(path, drive), drive


def as_tuples(messages, topics):
    return [(topics[m.channel_id], m.log_time_ns, m.data) for m in messages]


def expected(messages, topics):
    return [(topics[m.channel_id], m.log_time, m.data) for m in messages]


@pytest.mark.parametrize('compression', [CompressionType.ZSTD, CompressionType.LZ4,
                                         CompressionType.NONE])
def test_a_finished_file_gives_every_message_in_order(tmp_path, compression):
    """Every message, in the order written, with its log time and bytes; not cut short."""
    path = tmp_path / 'drive.mcap'
    drive = samples(2.0)
    topics = write_drive(path, drive, compression)
    recording = RecordingFile(path)
    assert not recording.cut_short
    assert recording.message_count == len(drive)
    assert as_tuples(recording.messages(), topics) == [(s.topic, s.time_ns, s.data)
                                                       for s in drive]
    assert {c.topic: c.type_name for c in recording.channels.values()} == \
        {s.topic: s.type_name for s in drive}


def test_a_sink_recording_reads_back(tmp_path):
    """What FoxgloveSink writes (zstd chunks, channels inside them) reads back whole."""
    path = tmp_path / 'sink.mcap'
    drive = samples(2.0)
    with FoxgloveSink(record_path=path) as sink:
        channels = {t: sink.channel(t, *TOPICS[t]) for t in TOPICS}
        for sample in drive:
            channels[sample.topic].log(sample.data, sample.time_ns)
    recording = RecordingFile(path)
    topics = {c.id: c.topic for c in recording.channels.values()}
    assert not recording.cut_short
    assert as_tuples(recording.messages(), topics) == [(s.topic, s.time_ns, s.data)
                                                       for s in drive]
    assert recording.channels[next(iter(topics))].metadata['offered_qos_profiles']


@pytest.mark.parametrize('fraction', [0.02, 0.1, 0.25, 0.4, 0.5, 0.63, 0.77, 0.9, 0.97, 0.999])
def test_a_file_cut_anywhere_gives_the_messages_of_its_complete_records(drive, tmp_path,
                                                                        fraction):
    """A recorder killed at any byte: every message before the first incomplete record."""
    path, topics, drive = drive
    whole = path.read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(whole[:int(len(whole) * fraction)])
    reference = complete_messages(cut)
    recording = RecordingFile(cut)
    assert as_tuples(recording.messages(), topics) == expected(reference, topics)
    assert recording.message_count == len(reference)
    assert recording.cut_short or len(reference) == len(drive)
    if recording.cut_short:
        line = recording.describe_cut()
        assert f'recovered {len(reference)} messages' in line and '\n' not in line
        assert recording.readable_bytes <= len(whole) * fraction


def test_zeros_after_a_crash_end_the_readable_part(drive, tmp_path):
    """A power loss can leave zeros where the end was: the records before them are read."""
    path, topics, _ = drive
    whole = path.read_bytes()
    cut = tmp_path / 'zeros.mcap'
    cut.write_bytes(whole[:len(whole) // 2] + bytes(64 * 1024))
    half = tmp_path / 'half.mcap'
    half.write_bytes(whole[:len(whole) // 2])
    reference = complete_messages(half)
    recording = RecordingFile(cut)
    assert recording.cut_short and reference
    assert as_tuples(recording.messages(), topics) == expected(reference, topics)


def test_a_damaged_chunk_ends_the_readable_part(tmp_path):
    """A chunk whose compressed bytes are garbage: the chunks before it, and one line on why."""
    topic = Topic(1, '/chatter')
    chunks = [zstd_chunk(plain_messages(1, [f'{i}-{j}' for j in range(5)])) for i in range(3)]
    chunks[1].data = chunks[1].data[:8] + bytes(len(chunks[1].data) - 8)
    path = write_mcap(tmp_path / 'damaged.mcap', [topic], chunks)
    recording = RecordingFile(path)
    assert recording.cut_short and recording.damage
    assert [m.data for m in recording.messages()] == [m.data for m in plain_messages(
        1, [f'0-{j}' for j in range(5)])]
    assert 'damaged at byte' in recording.describe_cut()


@pytest.mark.parametrize('content', [b'\x89MCAP0\r\n', b'\x89MCAP0\r\n' + bytes(9)])
def test_a_file_cut_to_nothing_holds_nothing(tmp_path, content):
    """The magic alone, or followed by zeros: no channel, no message, cut short."""
    path = tmp_path / 'nothing.mcap'
    path.write_bytes(content)
    recording = RecordingFile(path)
    assert recording.cut_short and recording.message_count == 0 and not recording.channels


def test_garbage_after_the_magic_holds_nothing(tmp_path):
    """Random bytes after a valid start: nothing read, no exception, whatever they say."""
    rng = random.Random(30)
    for attempt in range(50):
        path = tmp_path / f'garbage{attempt}.mcap'
        path.write_bytes(b'\x89MCAP0\r\n' + bytes(rng.randrange(256) for _ in range(2000)))
        try:
            recording = RecordingFile(path)
        except RecordingError as exc:  # a "record" that declares more than a chunk may hold
            assert 'refused' in str(exc)
            continue
        assert recording.message_count == 0


@pytest.mark.parametrize('content, words', [
    (b'', 'not a readable MCAP file'),
    (b'this is text, not MCAP\n' * 10, 'not a readable MCAP file'),
    ('directory', 'not a regular file'),
    ('fifo', 'not a regular file'),
    (None, 'cannot open'),
])
def test_what_is_not_an_mcap_file_is_one_line(tmp_path, content, words):
    """Empty, foreign, a directory, a FIFO (which open() would block on), missing."""
    path = tmp_path / 'bad.mcap'
    if content == 'directory':
        path.mkdir()
    elif content == 'fifo':
        os.mkfifo(path)
    elif content is not None:
        path.write_bytes(content)
    with pytest.raises(RecordingError, match=words) as raised:
        RecordingFile(path)
    assert '\n' not in str(raised.value)


@pytest.mark.parametrize('type_name', [
    'this/Foo', 'this/msg/Foo', 'antigravity/msg/Fly', 'os/path', 'subprocess/msg/Popen',
    'std_msgs/srv/String', 'std_msgs/msg/NoSuchType', 'std_msgs/msg/String\n',
    'std_msgs.msg/String', '../std_msgs/String', 'std_msgs/msg/String/x', '',
])
def test_a_type_no_installed_interface_package_defines_imports_nothing(monkeypatch, type_name):
    """S1: a schema name from a file never reaches the import machinery unless it is known."""
    imported = []
    real = importlib.import_module
    monkeypatch.setattr(importlib, 'import_module',
                        lambda name, *a: imported.append(name) or real(name, *a))
    sys.modules.pop('this', None)
    with pytest.raises(UnknownMessageType) as raised:
        message_class(type_name)
    assert imported == [] and 'this' not in sys.modules
    assert '\n' not in str(raised.value)


@pytest.mark.parametrize('type_name', ['std_msgs/msg/String', 'std_msgs/String'])
def test_an_installed_type_resolves_to_its_class(type_name):
    """rosbag2's pkg/msg/Type and the short pkg/Type both name the class."""
    assert message_class(type_name) is String


def test_a_pass_decompresses_no_more_than_its_bound(tmp_path):
    """S2: chunks each within bounds, but more in total than one pass may decompress."""
    chunk = bomb_chunk(1, MIB)
    path = write_mcap(tmp_path / 'many.mcap', [Topic(1, '/bomb')], [chunk] * 8)
    assert RecordingFile(path).message_count == 8
    with pytest.raises(RecordingError, match='more than 5242880 bytes in one pass'):
        RecordingFile(path, max_bytes=5 * MIB)
    assert RecordingFile(path).max_bytes == MIN_PASS_BYTES


def test_a_chunk_that_declares_too_much_is_refused_before_decompressing(tmp_path):
    """S2: a chunk may declare at most MAX_CHUNK_BYTES (it is not decompressed to find out)."""
    chunk = bomb_chunk(1, 1024, declared_size=MAX_CHUNK_BYTES + 1)
    path = write_mcap(tmp_path / 'big.mcap', [Topic(1, '/bomb')], [chunk])
    with pytest.raises(RecordingError, match=f'would decompress to {MAX_CHUNK_BYTES + 1}'):
        RecordingFile(path)


def test_a_chunk_that_holds_more_than_it_declares_is_refused(tmp_path):
    """S2: decompression stops one byte past the declared size."""
    chunk = bomb_chunk(1, MIB, declared_size=1024)
    path = write_mcap(tmp_path / 'liar.mcap', [Topic(1, '/bomb')], [chunk])
    with pytest.raises(RecordingError, match='more than the 1024 bytes it declares'):
        RecordingFile(path)


def test_more_channels_than_a_replay_would_publish_are_refused(tmp_path):
    """Each playable channel becomes a publisher: a file may not ask for thousands more."""
    topics = [Topic(i, f'/t{i}') for i in range(1, MAX_CHANNELS + 2)]
    path = write_mcap(tmp_path / 'channels.mcap', topics, [], summary=False)
    with pytest.raises(RecordingError, match=f'more than {MAX_CHANNELS} channels'):
        RecordingFile(path)


def test_messages_on_undefined_channels_are_not_counted(tmp_path):
    """A message whose channel the file never defines is not a message of any topic."""
    stray = Message(channel_id=9, sequence=0, log_time=0, publish_time=0, data=b'x')
    path = write_mcap(tmp_path / 'stray.mcap', [Topic(1, '/chatter')],
                      plain_messages(1, ['a']) + [stray])
    recording = RecordingFile(path)
    assert recording.message_count == 1 and recording.message_counts == {1: 1}
    assert [m.channel_id for m in recording.messages()] == [1]
