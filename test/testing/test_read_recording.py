"""
``r2d2_sim.testing.read_recording``: a recording read into typed messages per topic.

The recordings are written here by FoxgloveSink (as ``sim_node`` writes
them) from the sample drive, or by hand with the ``mcap`` package.
"""

import sys

from nav_msgs.msg import Odometry
import pytest
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock

from r2d2_sim.recording.sink import FoxgloveSink
from r2d2_sim.testing import read_recording, RecordedMessage, RecordingError
from recording_files import complete_messages, plain_messages, Topic, write_mcap
from sample_messages import message_class, samples, TOPICS


@pytest.fixture(scope='module')
def recording(tmp_path_factory):
    """Record a 2 s drive with the sink; return (path, the samples logged)."""
    path = tmp_path_factory.mktemp('read_recording') / 'run.mcap'
    drive = samples(2.0)
    with FoxgloveSink(record_path=path) as sink:
        channels = {t: sink.channel(t, *TOPICS[t]) for t in TOPICS}
        for sample in drive:
            channels[sample.topic].log(sample.data, sample.time_ns)
    return path, drive


def test_every_topic_comes_back_typed_in_order(recording):
    """Each topic: its messages as rclpy objects, with their log times, in the order logged."""
    path, drive = recording
    read = read_recording(path)
    assert sorted(read) == sorted(TOPICS)
    for topic in TOPICS:
        logged = [s for s in drive if s.topic == topic]
        cls = message_class(TOPICS[topic][0])
        assert [m.log_time_ns for m in read[topic]] == [s.time_ns for s in logged]
        assert [m.message for m in read[topic]] == \
            [deserialize_message(s.data, cls) for s in logged]
    odometry = read['/odom'][-1]
    assert isinstance(odometry, RecordedMessage) and isinstance(odometry.message, Odometry)
    log_time_ns, clock = read['/clock'][-1]
    assert isinstance(clock, Clock) and clock.clock.sec * 10**9 == log_time_ns == 2 * 10**9


def test_only_the_topics_asked_for(recording):
    """``topics`` picks topics; one the file lacks is an error naming the ones it has."""
    path, _ = recording
    assert sorted(read_recording(path, ['/clock', '/odom'])) == ['/clock', '/odom']
    with pytest.raises(RecordingError, match=r"no cdr topic '/cmd_vel'; it has \[.*'/odom'"):
        read_recording(path, ['/cmd_vel'])
    assert list(read_recording(path, '/odom')) == ['/odom']  # one topic as a string
    with pytest.raises(RecordingError, match='^read_recording takes the path of an MCAP file, '
                       'got NoneType$'):
        read_recording(None)


def test_a_cut_off_recording_gives_what_it_holds(recording, tmp_path):
    """A recorder killed mid-file: the messages of its complete records, no error."""
    path, _ = recording
    sink_cut = tmp_path / 'sink_cut.mcap'  # 2 s of the sink are one chunk: cut inside it
    sink_cut.write_bytes(path.read_bytes()[:path.stat().st_size // 2])
    assert read_recording(sink_cut) == {}
    records = write_mcap(tmp_path / 'records.mcap', [Topic(1, '/chatter')],
                         plain_messages(1, [str(i) for i in range(40)]))
    cut = tmp_path / 'records_cut.mcap'
    cut.write_bytes(records.read_bytes()[:records.stat().st_size // 2])
    count = len(complete_messages(cut))
    assert 0 < count < 40
    assert [m.message.data for m in read_recording(cut)['/chatter']] == \
        [str(i) for i in range(count)]


def test_a_topic_of_an_unknown_type_is_left_out_or_refused_never_imported(tmp_path):
    """S1 in the testing API: 'this/Foo' is not imported; asked for, it is one error line."""
    path = write_mcap(tmp_path / 'this.mcap', [Topic(1, '/chatter'), Topic(2, '/zen', 'this/Foo')],
                      plain_messages(1, ['a', 'b']) + plain_messages(2, ['c']))
    sys.modules.pop('this', None)
    assert sorted(read_recording(path)) == ['/chatter']
    with pytest.raises(RecordingError, match="'/zen' cannot be read: no definition of this/Foo"):
        read_recording(path, ['/zen'])
    assert 'this' not in sys.modules


def test_bytes_that_are_not_their_type_are_one_error_line(tmp_path):
    """A message whose bytes do not deserialize as its channel's type."""
    path = write_mcap(tmp_path / 'odd.mcap', [Topic(1, '/odom', 'nav_msgs/msg/Odometry')],
                      plain_messages(1, ['not an odometry']))
    with pytest.raises(RecordingError, match="on '/odom' at 0 ns is not a nav_msgs/msg/Odometry"):
        read_recording(path)


def test_more_messages_than_allowed_are_refused(recording):
    """``max_messages`` bounds what is turned into Python objects (default 1,000,000)."""
    path, drive = recording
    assert sum(len(m) for m in read_recording(path, max_messages=len(drive)).values()) == \
        len(drive)
    with pytest.raises(RecordingError, match=f'holds {len(drive)} messages, more than'):
        read_recording(path, max_messages=len(drive) - 1)
