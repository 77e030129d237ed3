"""
FoxgloveSink with real serialized messages: a real WebSocket viewer, and MCAP files read back.

The viewer is the ``websockets`` package speaking the Foxglove protocol
(subprotocol ``foxglove.sdk.v1``) to the SDK's server on loopback. The
recordings are read with two independent readers: ``mcap``'s and rosbags'
``AnyReader`` (which also decodes every message from the definitions the
file carries). A recorder in a process of its own, stopped by a signal, is
system/test_foxglove_sink_system.py's.
"""

from collections import defaultdict
import time

from mcap.reader import make_reader
import pytest
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability
from std_msgs.msg import String

from common import read_with_mcap
from r2d2_sim.recording.sink import FoxgloveSink, SinkError
from r2d2_sim.recording.message_definitions import message_definition, type_hash
from foxglove_viewer import Viewer
from sample_messages import LATCHED, message_class, samples, TOPICS


def open_channels(sink):
    """Register every sample topic with the QoS the node publishes it with."""
    return {topic: sink.channel(topic, type_name, qos)
            for topic, (type_name, qos) in TOPICS.items()}


def log_all(channels, batch):
    """Log samples in order."""
    for sample in batch:
        channels[sample.topic].log(sample.data, sample.time_ns)


def by_topic(batch):
    """Group samples as topic -> [(time, bytes)]."""
    grouped = defaultdict(list)
    for sample in batch:
        grouped[sample.topic].append((sample.time_ns, sample.data))
    return grouped


PROBE_NS = 1


def received(viewer, topic):
    """Return what a viewer got on ``topic``, without the probes."""
    return [m for m in viewer.messages[topic] if m[0] != PROBE_NS]


def connected_viewer(sink, topics):
    """Connect a viewer, wait for the channels' advertisements, subscribe to ``topics``."""
    viewer = Viewer(sink.port)
    assert viewer.pump(lambda: set(TOPICS) <= set(viewer.channels)), viewer.channels.keys()
    viewer.subscribe(topics)
    return viewer


def test_viewer_gets_ros_channels_and_the_logged_bytes():
    """Every channel is cdr/ros2msg with its ROS type; each payload is the logged message."""
    batch = samples(1.0)
    with FoxgloveSink(port=0) as sink:
        channels = open_channels(sink)
        with connected_viewer(sink, TOPICS) as viewer:
            assert viewer.server_info['name'] == 'r2d2_sim'
            assert 'time' in viewer.server_info['capabilities']
            for topic, (type_name, _) in TOPICS.items():
                advertised = viewer.channels[topic]
                assert advertised['encoding'] == 'cdr'
                assert advertised['schemaEncoding'] == 'ros2msg'
                assert advertised['schemaName'] == type_name
                assert advertised['schema'] == message_definition(type_name)
            # The server takes the subscription asynchronously: log a probe
            # clock (at a time of its own) until one arrives, then the drive.
            probe = batch[2]
            assert probe.topic == '/clock'
            assert viewer.pump(lambda: channels['/clock'].log(probe.data, PROBE_NS) or
                               viewer.messages['/clock'], timeout_s=10.0)
            log_all(channels, batch)
            expected = by_topic(batch)
            assert viewer.pump(lambda: all(len(received(viewer, t)) >= len(expected[t])
                                           for t in expected)), \
                {t: len(m) for t, m in viewer.messages.items()}
    for topic, sent in expected.items():
        viewer.messages[topic] = received(viewer, topic)
        assert viewer.messages[topic] == sent, topic
        try:
            cls = message_class(TOPICS[topic][0])
        except ImportError:
            continue
        for _, payload in viewer.messages[topic]:
            assert isinstance(deserialize_message(payload, cls), cls)
    clock = deserialize_message(viewer.messages['/clock'][-1][1], message_class(
        'rosgraph_msgs/msg/Clock'))
    assert clock.clock.sec * 10**9 + clock.clock.nanosec == viewer.messages['/clock'][-1][0]


def test_late_viewer_gets_latched_topics_which_the_file_has_once(tmp_path):
    """/robot_description and /tf_static reach viewers that subscribe after they were logged."""
    path = tmp_path / 'run.mcap'
    batch = samples(0.5)
    with FoxgloveSink(port=0, record_path=path) as sink:
        channels = open_channels(sink)
        log_all(channels, batch)
        latched = ['/robot_description', '/tf_static']
        expected = by_topic(batch)
        for _ in range(2):  # each new viewer, not only the first
            with connected_viewer(sink, TOPICS) as viewer:
                assert viewer.pump(lambda: all(viewer.messages[t] for t in latched))
                for topic in latched:
                    assert viewer.messages[topic] == expected[topic]
                assert not viewer.messages['/odom'], 'a volatile topic was re-sent'
        newer = serialize_message(String(data='<robot name="newer"/>'))
        channels['/robot_description'].log(newer, 10**9)
        with connected_viewer(sink, ['/robot_description']) as viewer:
            assert viewer.pump(lambda: viewer.messages['/robot_description'])
            assert viewer.messages['/robot_description'] == [(10**9, newer)]
    with open(path, 'rb') as stream:
        counts = defaultdict(int)
        for _, channel, _ in make_reader(stream).iter_messages():
            counts[channel.topic] += 1
    assert counts['/robot_description'] == 2  # the first and the newer, no repeats
    assert counts['/tf_static'] == 1


def test_time_messages_carry_the_simulated_time():
    """set_time reaches viewers as Time; a time going back is sent at once; the rate is capped."""
    with FoxgloveSink(port=0, time_rate_hz=10.0) as sink:
        open_channels(sink)
        with connected_viewer(sink, []) as viewer:
            sink.set_time(123_456_789_012)
            assert viewer.pump(lambda: viewer.times)
            assert viewer.times == [123_456_789_012]
            sink.set_time(5_000)  # a reset: back in time
            assert viewer.pump(lambda: len(viewer.times) == 2)
            assert viewer.times[-1] == 5_000
            started = time.monotonic()
            for step in range(1, 1001):
                sink.set_time(5_000 + step)
            elapsed = time.monotonic() - started
            viewer.pump(lambda: False, timeout_s=0.3)
            # 1000 calls in `elapsed` seconds at 10 Hz: at most one per 0.1 s.
            assert len(viewer.times) - 2 <= 1 + elapsed * 10.0, viewer.times


def decode_with_rosbags(reader, raw, msgtype):
    """
    Decode with the deserializer rosbags generated from the file's own definitions.

    Not ``reader.deserialize``: rclpy's ``serialize_message`` returns
    rmw_fastrtps' estimated size, which for some types (JointState: 8 bytes)
    runs past the last field, and rosbags refuses more than 3 bytes after
    it. Those trailing bytes are allowed here, and no more.
    """
    msgdef = reader.typestore.get_msgdef(msgtype)
    assert raw[:4] == b'\x00\x01\x00\x00', 'not little-endian CDR'
    message, end = msgdef.deserialize_cdr_le(raw[4:], 0, msgdef.cls, reader.typestore)
    assert 0 <= len(raw) - 4 - end <= 8, f'{msgtype}: {len(raw) - 4 - end} bytes left over'
    return message


def test_recording_reads_back_with_two_readers(tmp_path):
    """The closed file: ros2 profile, zstd chunks, rosbag2 metadata; rosbags decodes it all."""
    path = tmp_path / 'run.mcap'
    batch = samples(2.0)
    with FoxgloveSink(record_path=path) as sink:
        log_all(open_channels(sink), batch)
    expected = by_topic(batch)

    header, summary, messages = read_with_mcap(path)
    assert header.profile == 'ros2'
    assert summary is not None and summary.statistics.message_count == len(batch)
    assert {index.compression for index in summary.chunk_indexes} == {'zstd'}
    got = defaultdict(list)
    for channel, schema, message in messages:
        type_name, qos = TOPICS[channel.topic]
        assert channel.message_encoding == 'cdr'
        assert (schema.name, schema.encoding) == (type_name, 'ros2msg')
        assert schema.data.decode() == message_definition(type_name)
        assert channel.metadata['topic_type_hash'] == type_hash(type_name)
        assert 'durability: transient_local' in channel.metadata['offered_qos_profiles'] \
            or qos is not LATCHED
        got[channel.topic].append((message.log_time, message.data))
    assert got == expected

    with AnyReader([path]) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == \
            {t: type_name for t, (type_name, _) in TOPICS.items()}
        counts = {t: info.msgcount for t, info in reader.topics.items()}
        assert counts == {t: len(m) for t, m in expected.items()}
        for connection in reader.connections:
            qos = connection.ext.offered_qos_profiles[0]
            latched = TOPICS[connection.topic][1] is LATCHED
            assert (qos.durability == QosDurability.TRANSIENT_LOCAL) == latched
            assert qos.depth == TOPICS[connection.topic][1].depth
        decoded = 0
        for connection, time_ns, raw in reader.messages():
            message = decode_with_rosbags(reader, raw, connection.msgtype)
            decoded += 1
            if connection.topic == '/clock':
                assert message.clock.sec * 10**9 + message.clock.nanosec == time_ns
            if connection.topic == '/scan':
                scan = deserialize_message(raw, message_class('sensor_msgs/msg/LaserScan'))
                assert list(message.ranges) == pytest.approx(list(scan.ranges))
        assert decoded == len(batch)


def test_publishers_sharing_a_latched_topic_each_reach_a_late_viewer(tmp_path):
    """Two robots' /tf_static: one channel, each publisher's last message re-sent, logged once."""
    path = tmp_path / 'run.mcap'
    type_name, qos = TOPICS['/tf_static']
    with FoxgloveSink(port=0, record_path=path) as sink:
        first = sink.channel('/tf_static', type_name, qos)
        second = sink.channel('/tf_static', type_name, qos)
        assert sink.topics == ['/tf_static']
        first.log(b'robot_a', 5)
        second.log(b'robot_b', 6)
        with Viewer(sink.port) as viewer:
            assert viewer.pump(lambda: '/tf_static' in viewer.channels)
            viewer.subscribe(['/tf_static'])
            assert viewer.pump(lambda: len(viewer.messages['/tf_static']) >= 2)
            assert sorted(viewer.messages['/tf_static']) == [(5, b'robot_a'), (6, b'robot_b')]
    with open(path, 'rb') as stream:
        logged = [message.data for _, _, message in make_reader(stream).iter_messages()]
    assert logged == [b'robot_a', b'robot_b']


def test_bad_channels_and_sinks_are_one_line_errors(tmp_path):
    """Relative topics, a topic with two types, unknown types, an existing file, a taken port."""
    path = tmp_path / 'run.mcap'
    path.write_bytes(b'')
    with FoxgloveSink(port=0) as sink:
        sink.channel('/scan', 'sensor_msgs/msg/LaserScan', QoSProfile(depth=5))
        cases = [
            lambda: sink.channel('scan', 'sensor_msgs/msg/LaserScan', QoSProfile(depth=5)),
            lambda: sink.channel('/scan', 'sensor_msgs/msg/Imu', QoSProfile(depth=5)),
            lambda: sink.channel('/x', 'foo_msgs/msg/Bar', QoSProfile(depth=5)),
            lambda: FoxgloveSink(record_path=path),
            lambda: FoxgloveSink(record_path=tmp_path / 'missing' / 'run.mcap'),
            lambda: FoxgloveSink(port=sink.port),
            lambda: FoxgloveSink(port=sink.port, record_path=tmp_path / 'never.mcap'),
        ]
        for case in cases:
            with pytest.raises(SinkError) as raised:
                case()
            assert '\n' not in str(raised.value) and str(raised.value)
    assert not (tmp_path / 'never.mcap').exists(), 'a sink that failed left a file'
    assert sink.port is None
    sink.close()  # again: nothing happens


def test_a_channel_is_taken_by_the_file_always_and_by_the_live_view_while_watched(tmp_path):
    """taken(): the node builds a message only when someone takes it (the live view's part)."""
    volatile = next(t for t, (_, qos) in TOPICS.items() if qos != LATCHED)
    latched = next(t for t, (_, qos) in TOPICS.items() if qos == LATCHED)
    with FoxgloveSink(port=0) as live_only:
        channels = open_channels(live_only)
        assert not channels[volatile].taken() and channels[latched].taken()
        sibling = live_only.channel(volatile, *TOPICS[volatile])  # a second publisher
        viewer = connected_viewer(live_only, [volatile])
        with viewer:
            assert viewer.pump(channels[volatile].taken) and sibling.taken()
            viewer.unsubscribe([volatile])
            assert viewer.pump(lambda: not channels[volatile].taken())
            assert not sibling.taken()
    with FoxgloveSink(port=0, record_path=str(tmp_path / 'run.mcap')) as both:
        channel = open_channels(both)[volatile]
        assert channel.taken()
        channel.stop_file()  # as when the disk fills: the live view alone is left
        assert not channel.taken()
        channel.stop()
        assert not channel.taken()


def test_a_publisher_made_after_the_first_of_its_topic_went_still_records(tmp_path):
    """Robot a's /tf publisher released (a deleted), then c spawned: c's /tf is recorded."""
    path = tmp_path / 'run.mcap'
    volatile = next(t for t, (_, qos) in TOPICS.items() if qos != LATCHED)
    type_name, qos = TOPICS[volatile]
    data = next(s.data for s in samples() if s.topic == volatile)
    with FoxgloveSink(record_path=str(path)) as sink:
        first = sink.channel(volatile, type_name, qos)
        second = sink.channel(volatile, type_name, qos)
        first.release()
        third = sink.channel(volatile, type_name, qos)
        assert second.taken() and third.taken()
        second.log(data, 1)
        third.log(data, 2)
    _, _, messages = read_with_mcap(path)
    assert [m.log_time for c, _, m in messages if c.topic == volatile] == [1, 2]
