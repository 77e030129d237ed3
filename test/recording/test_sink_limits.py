"""
FoxgloveSink when things go wrong: a full disk, hostile viewers, robots that come and go.

A real WebSocket viewer (the public :class:`~r2d2_sim.testing.LiveViewClient`,
or the ``websockets`` package for what no honest client sends) against the
SDK's server on loopback. The full disk is made where the recording's
writes go (``os.write`` on that one file fails with ENOSPC once a budget is
spent); ``test/system/test_live_view_faults.py`` fills a real filesystem
under ``sim_node``.
"""

import errno
import gc
import json
import logging
import os
import time

import foxglove
from mcap.reader import make_reader
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from r2d2_sim.recording.sink import FoxgloveSink, SinkError, SUBPROTOCOL
from r2d2_sim.testing import LiveViewClient
from sample_messages import samples, TOPICS

# A robot's own topics, as a spawned robot's namespace has them.
ROBOT_TOPICS = ('/odom', '/joint_states', '/scan', '/robot_description', '/ground_truth')


def log_round(channels, batch, offset_ns):
    """Log a batch of samples, shifted in time; return the last time logged."""
    for sample in batch:
        channels[sample.topic].log(sample.data, sample.time_ns + offset_ns)
    return batch[-1].time_ns + offset_ns


def fill_disk_at(path, monkeypatch, room):
    """Make writes to ``path`` fail with ENOSPC once ``room`` bytes are in (the last partly)."""
    space = [room]
    real_write = os.write

    def write(fd, data):
        try:
            target = os.readlink(f'/proc/self/fd/{fd}')
        except OSError:
            target = None
        if target == str(path):
            if space[0] <= 0:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            data = bytes(data)[:space[0]]  # a partial write, as a disk that fills gives
            space[0] -= len(data)
        return real_write(fd, data)
    monkeypatch.setattr(os, 'write', write)


def test_a_write_error_stops_the_recording_once_and_the_live_view_goes_on(tmp_path, monkeypatch):
    """One error line, no more writes, the file closed, close() quiet, the viewer still fed."""
    path = tmp_path / 'run.mcap'
    fill_disk_at(path, monkeypatch, 30_000)
    errors, warnings = [], []
    batch = samples(0.5)
    with FoxgloveSink(port=0, record_path=path, error=errors.append,
                      warn=warnings.append) as sink:
        channels = {t: sink.channel(t, *TOPICS[t]) for t in TOPICS}
        with LiveViewClient(sink.port) as viewer:
            viewer.subscribe(['/clock'])
            rounds = 0
            while not errors and rounds < 1000:
                rounds += 1
                log_round(channels, batch, rounds * 10**9)
            assert errors, 'the recording never filled its disk'
            for _ in range(20):  # on, after the failure
                rounds += 1
                last_ns = log_round(channels, batch, rounds * 10**9)
            assert viewer.pump(lambda: any(t == last_ns for t, _ in viewer.messages['/clock']))
    assert len(errors) == 1, errors
    assert errors[0].startswith(f'recording stopped: cannot write {path}: No space left on device')
    assert sink.record_error.errno == errno.ENOSPC
    assert not warnings, warnings  # the SDK never saw an error: nothing of its own to say
    assert 0 < path.stat().st_size <= 30_000
    assert not any(link == str(path) for link in open_files()), 'the file is still open'


def test_a_disk_full_from_the_start_is_a_startup_error_leaving_no_file(tmp_path, monkeypatch):
    """Not even the header fits: SinkError in one line, and nothing left behind."""
    path = tmp_path / 'run.mcap'
    fill_disk_at(path, monkeypatch, 0)
    with pytest.raises(SinkError, match=f'^cannot record to {path}: No space left on device$'):
        FoxgloveSink(port=0, record_path=path)
    assert not path.exists()


def open_files():
    """Return what this process's descriptors point at."""
    links = []
    for name in os.listdir('/proc/self/fd'):
        try:
            links.append(os.readlink(f'/proc/self/fd/{name}'))
        except OSError:
            pass
    return links


def raw_viewer(port):
    """Connect a bare WebSocket (no client library's manners) speaking the live view's protocol."""
    return connect(f'ws://127.0.0.1:{port}', subprotocols=[SUBPROTOCOL], open_timeout=10)


def recv_until(ws, condition, timeout_s=10.0):
    """Read frames until ``condition(frame)`` holds for one; return it (None at the deadline)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            frame = ws.recv(timeout=0.1)
        except TimeoutError:
            continue
        if condition(frame):
            return frame
    return None


class Kept(logging.Handler):
    """A logging handler that keeps the records it is given."""

    def __init__(self):
        super().__init__()
        self.records = []

    def emit(self, record):
        self.records.append(record)


@pytest.fixture
def root_records():
    """Return the records that reach the root logger's handlers (stderr, when unconfigured)."""
    kept = Kept()
    logging.getLogger().addHandler(kept)
    try:
        yield kept.records
    finally:
        logging.getLogger().removeHandler(kept)


def test_bad_client_messages_reach_warn_throttled_and_nothing_else(root_records):
    """300 invalid messages and 10 refused handshakes: a few throttled lines, none per message."""
    warnings = []
    with FoxgloveSink(port=0, warn=warnings.append, error=warnings.append) as sink:
        clock = sink.channel('/clock', *TOPICS['/clock'])
        for _ in range(10):  # an older client's subprotocol: refused with HTTP 400
            try:
                connect(f'ws://127.0.0.1:{sink.port}', subprotocols=['foxglove.websocket.v1'],
                        open_timeout=10).close()
            except InvalidStatus:
                pass
        with raw_viewer(sink.port) as ws:
            advertise = recv_until(ws, lambda f: isinstance(f, str) and '"advertise"' in f)
            channel_id = json.loads(advertise)['channels'][0]['id']
            for _ in range(100):
                ws.send('not json')
                ws.send(json.dumps({'op': 'noSuchOp'}))
                ws.send(b'\x99garbage')
            # Messages on one connection are handled in order: once this subscription
            # delivers, every bad message before it was handled.
            ws.send(json.dumps({'op': 'subscribe',
                                'subscriptions': [{'id': 1, 'channelId': channel_id}]}))
            deadline = time.monotonic() + 10.0
            delivered = None
            while delivered is None and time.monotonic() < deadline:
                clock.log(b'\x00\x01\x00\x00' + bytes(8), 5)
                delivered = recv_until(ws, lambda f: isinstance(f, bytes) and f[0] == 1, 0.2)
            assert delivered is not None
    sdk_records = [r for r in root_records if r.name.startswith('foxglove')]
    assert not sdk_records, [r.getMessage() for r in sdk_records[:3]]
    assert 1 <= len(warnings) <= 4, warnings  # one per kind of complaint at most
    assert all(line.startswith('foxglove-sdk: ') for line in warnings), warnings


def test_latched_topics_go_again_at_a_bounded_rate_however_often_viewers_subscribe():
    """One viewer subscribing 300 times sends another a few copies, and still gets its own."""
    period_s = 0.5
    with FoxgloveSink(port=0, latched_resend_period_s=period_s) as sink:
        description = sink.channel('/robot_description', *TOPICS['/robot_description'])
        description.log(b'<robot name="r2d2"/>', 7)
        with LiveViewClient(sink.port) as watcher, LiveViewClient(sink.port) as flicker:
            watcher.wait_for_messages('/robot_description')
            start = time.monotonic()
            for _ in range(300):
                flicker.subscribe(['/robot_description'])
                flicker.unsubscribe(['/robot_description'])
            # Handled in order: its last subscription served means all before it were.
            received = flicker.wait_for_messages('/robot_description')
            assert received[-1] == (7, b'<robot name="r2d2"/>')
            watcher.pump(timeout_s=period_s)  # a re-send in flight
            elapsed_s = time.monotonic() - start
        copies = len(watcher.messages['/robot_description'])
    # Its own first copy, then at most one per period (and one more at its end).
    assert copies <= 3 + elapsed_s / period_s, (copies, elapsed_s)


def sdk_channels():
    """Return how many foxglove.Channel objects this process holds."""
    gc.collect()
    return sum(isinstance(o, foxglove.Channel) for o in gc.get_objects())


def test_released_robots_leave_no_channels_behind_but_the_file_lists_them(tmp_path):
    """50 robots' topics registered, logged, released: the sink holds what it held before."""
    path = tmp_path / 'run.mcap'
    with FoxgloveSink(port=0, record_path=path) as sink:
        sink.channel('/clock', *TOPICS['/clock']).log(b'\x00\x01\x00\x00' + bytes(8), 1)
        before = sdk_channels()
        for robot in range(50):
            handles = [sink.channel(f'/robot_{robot}{t}', *TOPICS[t]) for t in ROBOT_TOPICS]
            for handle in handles:
                handle.log(b'\x00\x01\x00\x00', robot)
            for handle in handles:
                handle.release()
        assert sink.topics == ['/clock']
        assert sdk_channels() == before
    with open(path, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    # An MCAP file lists every channel it wrote a message on: those stay.
    assert len(summary.channels) == 1 + 50 * len(ROBOT_TOPICS)


def test_a_live_view_on_an_ipv6_host_gives_an_address_a_client_takes():
    """An IPv6 host: the address puts it in brackets (RFC 3986), and a viewer connects to it."""
    with FoxgloveSink(port=0, host='::1') as sink:
        assert sink.url == f'ws://[::1]:{sink.port}'
        with connect(sink.url, subprotocols=[SUBPROTOCOL], open_timeout=10):
            pass
