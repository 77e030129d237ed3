"""
A sink fed from a thread of its own: whoever logs to it never waits for the disk.

No ROS here. :class:`SinkFeeder` takes a
:class:`~r2d2_sim.recording.sink.FoxgloveSink`'s work (open a publisher's
channel, log a message, tell the viewers the time, release a channel),
queues it, and one thread does it in the order given: the same calls in
the same order as made directly, so the same MCAP file. The caller waits
only once ``max_bytes`` of messages are queued (a disk stalled that long),
and then only until the thread catches up. The outputs process
(:mod:`r2d2_sim.ros.relay_child`) feeds its sink so: its reading of frames
and its publishing do not wait for the recording, and a disk that stalls
for a few seconds delays the file, not the topics.
"""

from collections import deque
import threading
from typing import Any, Callable, Deque, Dict, Optional, Tuple

from r2d2_sim.recording.channels import SinkChannel
from r2d2_sim.recording.sink import FoxgloveSink, SinkError

__all__ = ['SinkFeeder', 'MAX_QUEUED_BYTES']

# What a stalled disk may hold back before a log waits: about 30 s of 16 robots'
# every output (8-9 MB/s), several minutes of one robot's.
MAX_QUEUED_BYTES = 256 << 20


def _ignore(index: int, channel: SinkChannel) -> None:
    pass


class SinkFeeder:
    """
    One thread doing ``sink``'s work in the order it was asked; see the module.

    Channels are known by the caller's index (a publisher's). ``error`` takes
    one line for what goes wrong in the thread (a channel the sink refuses);
    ``opened(index, channel)`` is called in the thread once a channel exists.
    :meth:`close` does what is queued, then stops the thread (the sink stays
    open: its owner closes it).
    """

    def __init__(self, sink: FoxgloveSink, error: Callable[[str], None],
                 opened: Callable[[int, SinkChannel], None] = _ignore,
                 max_bytes: int = MAX_QUEUED_BYTES) -> None:
        self.sink = sink
        self.channels: Dict[int, SinkChannel] = {}
        self._error = error
        self._opened = opened
        self._max_bytes = max_bytes
        self._queue: Deque[Tuple[Optional[tuple], int]] = deque()
        self._queued_bytes = 0
        self._changed = threading.Condition()
        self._thread = threading.Thread(target=self._run, name='sink feeder', daemon=True)
        self._thread.start()

    def open(self, index: int, topic: str, type_name: str, qos: Any) -> None:
        """Open the channel of publisher ``index`` (``sink.channel``'s arguments)."""
        self._put(('open', index, topic, type_name, qos), 0)

    def log(self, index: int, data: bytes, time_ns: int) -> None:
        """Log ``data`` on publisher ``index``'s channel at ``time_ns`` (none open: nothing)."""
        self._put(('log', index, data, time_ns), len(data))

    def release(self, index: int) -> None:
        """Release publisher ``index``'s channel (its publisher is gone)."""
        self._put(('release', index), 0)

    def set_time(self, time_ns: int) -> None:
        """Tell the sink's viewers the time, in order with the messages (``sink.set_time``)."""
        self._put(('time', time_ns), 0)

    def drop(self) -> None:
        """
        Drop everything queued and stop the thread after what it is doing now.

        For an owner that cannot wait for the disk any longer: the sink stays
        open, so its owner can still close it (an MCAP file then ends after the
        last message written). Safe from a signal handler and to call twice.
        """
        with self._changed:
            self._queue.clear()
            self._queued_bytes = 0
            self._queue.append((None, 0))
            self._changed.notify_all()

    @property
    def queued_bytes(self) -> int:
        """Return the bytes of messages queued and not yet logged."""
        return self._queued_bytes

    def _put(self, item: Optional[tuple], size: int) -> None:
        with self._changed:
            while self._queued_bytes > self._max_bytes and self._thread.is_alive():
                self._changed.wait()
            self._queue.append((item, size))
            self._queued_bytes += size
            self._changed.notify_all()

    def _run(self) -> None:
        while True:
            with self._changed:
                while not self._queue:
                    self._changed.wait()
                item, size = self._queue.popleft()
            if item is None:
                return
            try:
                self._do(item)
            except Exception as exc:  # the thread must go on: the queue would never drain
                self._error(f'the live view or recording failed on {item[0]}: {exc}')
            with self._changed:
                self._queued_bytes -= size
                self._changed.notify_all()

    def _do(self, item: tuple) -> None:
        kind, index = item[0], item[1]  # 'time': the time, not an index
        if kind == 'log':
            channel = self.channels.get(index)
            if channel is not None:
                channel.log(item[2], item[3])
        elif kind == 'time':
            self.sink.set_time(item[1])
        elif kind == 'open':
            topic, type_name, qos = item[2:]
            try:
                channel = self.sink.channel(topic, type_name, qos)
            except SinkError as exc:  # in one process, that publisher's refusal
                self._error(f'{topic} is not recorded or shown: {exc}')
                return
            self.channels[index] = channel
            self._opened(index, channel)
        else:
            gone = self.channels.pop(index, None)
            if gone is not None:
                gone.release()

    def close(self) -> None:
        """Do what is queued, then stop the thread; safe to call twice."""
        if self._thread.is_alive():
            self._put(None, 0)
            self._thread.join()
