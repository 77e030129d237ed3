"""
replay's schedule with a stand-in clock: each message at its log time over the rate, exactly.

The wall clock of a test machine says little about pacing (a loaded machine
delays what a listener hears); a clock the test moves says all of it.
"""

import threading
from types import SimpleNamespace

import pytest

from r2d2_sim.apps import replay


class Clock:
    """Wall time that moves only when replay waits."""

    def __init__(self):
        self.now = 100.0

    def monotonic(self):
        return self.now


class Stop:
    """replay's stop event: waiting moves the clock on; never set."""

    def __init__(self, clock):
        self.clock = clock

    def wait(self, seconds):
        self.clock.now += seconds

    def is_set(self):
        return False


class Publisher:
    """Records the clock's time of every publish."""

    def __init__(self, clock, sent):
        self.clock, self.sent = clock, sent

    def publish(self, data):
        self.sent.append((self.clock.now, data))


@pytest.mark.parametrize('rate', [1.0, 2.0, 0.25])
def test_each_message_goes_at_its_log_time_over_the_rate(monkeypatch, rate):
    """Log times 0, 0.1, 0.5 and 2 s after the first: sent at those over the rate, no drift."""
    clock = Clock()
    monkeypatch.setattr(replay, 'time', SimpleNamespace(monotonic=clock.monotonic))
    log_s = [0.0, 0.1, 0.5, 2.0]
    messages = [(1, 5 * 10**9 + round(t * 1e9), f'm{i}'.encode()) for i, t in enumerate(log_s)]
    recording = SimpleNamespace(file=SimpleNamespace(messages=lambda publishers: iter(messages)))
    sent = []
    count = replay.play(recording, {1: Publisher(clock, sent)}, rate, Stop(clock))
    assert count == 4 and [data for _, data in sent] == [b'm0', b'm1', b'm2', b'm3']
    assert [when - 100.0 for when, _ in sent] == pytest.approx([t / rate for t in log_s],
                                                               abs=1e-9)


def test_a_message_logged_before_the_one_ahead_goes_at_once(monkeypatch):
    """Out of order in the file: no waiting backwards, the next deadline still holds."""
    clock = Clock()
    monkeypatch.setattr(replay, 'time', SimpleNamespace(monotonic=clock.monotonic))
    messages = [(1, 0, b'a'), (1, 10**9, b'b'), (1, 5 * 10**8, b'c'), (1, 2 * 10**9, b'd')]
    recording = SimpleNamespace(file=SimpleNamespace(messages=lambda publishers: iter(messages)))
    sent = []
    replay.play(recording, {1: Publisher(clock, sent)}, 1.0, Stop(clock))
    assert [when - 100.0 for when, _ in sent] == pytest.approx([0.0, 1.0, 1.0, 2.0], abs=1e-9)


class SleepsAsThreading(Stop):
    """A stop event that refuses waits as threading.Event does, and is set by the first one."""

    def __init__(self, clock):
        super().__init__(clock)
        self.waits = []

    def wait(self, seconds):
        if seconds > threading.TIMEOUT_MAX:
            raise OverflowError('timestamp out of range for platform time_t')
        self.waits.append(seconds)
        super().wait(seconds)

    def is_set(self):
        return bool(self.waits)


def test_log_times_further_apart_than_the_platform_sleeps_are_waited_for_in_parts(monkeypatch):
    """A file's log times may lie 2**64 ns apart: replay waits, in parts, instead of crashing."""
    clock = Clock()
    monkeypatch.setattr(replay, 'time', SimpleNamespace(monotonic=clock.monotonic))
    messages = [(1, 0, b'first'), (1, 2**64 - 1, b'centuries later')]
    recording = SimpleNamespace(file=SimpleNamespace(messages=lambda publishers: iter(messages)))
    sent = []
    stop = SleepsAsThreading(clock)
    with pytest.raises(KeyboardInterrupt):  # stopped during the wait, as by Ctrl-C
        replay.play(recording, {1: Publisher(clock, sent)}, 1.0, stop)
    assert [data for _, data in sent] == [b'first']
    assert stop.waits == [replay.MAX_WAIT_S]
