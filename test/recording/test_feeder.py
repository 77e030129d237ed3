"""
SinkFeeder: a sink's work done on a thread of its own, in order, the caller waiting only when full.

A stand-in sink whose channels can be made to stall (a disk that does not
answer) shows that logging returns at once, that everything is done in the
order given once the stall ends (the viewers' time among the messages, as
given), that a full queue makes the caller wait, that dropping the queue
leaves the sink to close after the message being written, and that a
channel the sink refuses is one error line.
"""

import threading

from r2d2_sim.recording.feeder import SinkFeeder
from r2d2_sim.recording.sink import SinkError

WAIT_S = 5.0


class StallingChannel:
    """Records what it is given; waits for ``gate`` first (a stalled disk)."""

    def __init__(self, topic, done, gate, writing):
        self.topic, self._done, self._gate, self._writing = topic, done, gate, writing

    def log(self, data, time_ns):
        self._writing.set()
        assert self._gate.wait(WAIT_S)
        self._done.append(('log', self.topic, data, time_ns))

    def taken(self):
        return True

    def release(self):
        self._done.append(('release', self.topic))


class StandInSink:
    def __init__(self):
        self.done = []
        self.gate = threading.Event()
        self.writing = threading.Event()  # a message is being written

    def set_time(self, time_ns):
        self.done.append(('time', time_ns))

    def channel(self, topic, type_name, qos):
        if type_name == 'unknown/msg/Type':
            raise SinkError(f'no definition of {type_name}')
        self.done.append(('open', topic))
        return StallingChannel(topic, self.done, self.gate, self.writing)


def test_logging_returns_at_once_and_everything_is_done_in_order():
    sink, errors, opened = StandInSink(), [], []
    feeder = SinkFeeder(sink, errors.append, lambda index, channel: opened.append(index))
    feeder.open(0, '/odom', 'nav_msgs/msg/Odometry', None)
    feeder.open(1, '/scan', 'sensor_msgs/msg/LaserScan', None)
    for step in range(5):  # the disk stalls: every log is queued, none waits
        feeder.set_time(step)
        feeder.log(0, b'odom%d' % step, step)
        feeder.log(1, b'scan%d' % step, step)
    feeder.release(1)
    feeder.log(1, b'after its release', 9)  # nothing: no channel any more
    assert feeder.queued_bytes > 0 and len(sink.done) <= 2
    sink.gate.set()
    feeder.close()
    expected = [('open', '/odom'), ('open', '/scan')]
    for step in range(5):
        expected += [('time', step), ('log', '/odom', b'odom%d' % step, step),
                     ('log', '/scan', b'scan%d' % step, step)]
    assert sink.done == expected + [('release', '/scan')]
    assert opened == [0, 1] and errors == [] and feeder.queued_bytes == 0


def test_a_full_queue_makes_the_caller_wait_until_the_thread_catches_up():
    sink = StandInSink()
    feeder = SinkFeeder(sink, print, max_bytes=10)
    feeder.open(0, '/odom', 'nav_msgs/msg/Odometry', None)
    feeder.log(0, b'12345678', 1)  # taken by the thread, which stalls on it
    feeder.log(0, b'12345678', 2)  # queued: 16 bytes, over the bound
    returned = threading.Event()

    def third():
        feeder.log(0, b'12345678', 3)
        returned.set()
    threading.Thread(target=third, daemon=True).start()
    assert not returned.wait(0.3)  # held back while the disk stalls
    sink.gate.set()
    assert returned.wait(WAIT_S)
    feeder.close()
    assert [entry[3] for entry in sink.done if entry[0] == 'log'] == [1, 2, 3]


def test_a_channel_the_sink_refuses_is_one_line_and_the_rest_goes_on():
    sink, errors = StandInSink(), []
    sink.gate.set()
    feeder = SinkFeeder(sink, errors.append)
    feeder.open(0, '/odd', 'unknown/msg/Type', None)
    feeder.open(1, '/odom', 'nav_msgs/msg/Odometry', None)
    feeder.log(0, b'dropped', 1)
    feeder.log(1, b'kept', 1)
    feeder.close()
    feeder.close()  # twice: nothing more
    assert errors == ['/odd is not recorded or shown: no definition of unknown/msg/Type']
    assert sink.done == [('open', '/odom'), ('log', '/odom', b'kept', 1)]


def test_dropping_the_queue_ends_the_thread_after_the_message_being_written():
    sink = StandInSink()
    feeder = SinkFeeder(sink, print)
    feeder.open(0, '/odom', 'nav_msgs/msg/Odometry', None)
    for step in range(5):  # the first is being written (stalled), four wait behind it
        feeder.log(0, b'odom%d' % step, step)
    assert sink.writing.wait(WAIT_S)
    feeder.drop()
    assert feeder.queued_bytes == 0
    sink.gate.set()
    feeder.close()  # returns: the thread ended after the first
    feeder.drop()  # twice: nothing more
    assert sink.done == [('open', '/odom'), ('log', '/odom', b'odom0', 0)]
