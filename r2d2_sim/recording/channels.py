"""
One topic's channel of the sink: the same bytes to the MCAP file and to the live view.

:class:`SinkChannel` is what a publisher holds: ``log(data, time_ns)`` bound to
the cheapest call that reaches the sinks there are, rebound when one of them
stops. A latched topic's handle keeps its last messages and sends them to the
live view again when a viewer subscribes, at most once per period (the SDK
can only send to every subscribed viewer at once). The sink
(:mod:`.sink`) makes the handles and tracks them.
"""

from collections import deque
import threading
import time
from types import ModuleType
from typing import Callable, Deque, Optional, Tuple, TYPE_CHECKING

if TYPE_CHECKING:  # an optional dependency: imported for the checker only
    from foxglove import Channel

__all__ = ['SinkChannel', 'LATCHED_RESEND_PERIOD_S', 'forget_channel', 'locked', 'nothing']

# A latched topic's messages go to the live view again at most this often (wall
# seconds): one viewer subscribing and unsubscribing 2,000 times pushed 1,387
# copies of robot_description (21 MB) to another viewer without a bound.
LATCHED_RESEND_PERIOD_S = 1.0


def _ignore(data: bytes, time_ns: int) -> None:
    """Stand in for a sink that is not there."""


def nothing() -> None:
    """Release a handle no sink tracks."""


def _yes() -> bool:
    return True


def _no() -> bool:
    return False


def locked(log: Callable, lock: threading.Lock) -> Callable:
    """Return ``log`` holding ``lock`` (the recording file's: see :mod:`.mcap_file`)."""
    def locked_log(data: bytes, time_ns: int) -> None:
        with lock:
            log(data, time_ns)
    return locked_log


class SinkChannel:
    """
    One publisher of a topic of the sink: ``log(data, time_ns)`` sends the bytes on.

    ``data`` is one serialized message as ``bytes`` (the SDK refuses a
    ``bytearray`` or ``memoryview`` with TypeError: pass the object given to
    ``publish``), ``time_ns`` the simulated time in nanoseconds (>= 0), which
    becomes the MCAP log time and the WebSocket message time. ``log`` is
    bound to the cheapest call for the sinks that exist (the SDK's own
    method when there is one), and bound again when one of them stops.

    ``taken()`` says whether a message logged now goes anywhere: always with
    the file, and for a latched topic (kept for viewers to come); else while
    a viewer subscribes to the topic (``live_taken``, the live channel's
    ``has_sinks``, 0.06 us). The node builds a message nobody takes, over DDS
    or here, not at all.
    """

    def __init__(self, topic: str, type_name: str, live_log: Optional[Callable],
                 file_log: Optional[Callable], latched_depth: int = 0,
                 resend_period_s: float = LATCHED_RESEND_PERIOD_S,
                 live_taken: Optional[Callable[[], bool]] = None) -> None:
        self.topic = topic
        self.type_name = type_name
        self._live_log = live_log or _ignore
        self._file_log = file_log or _ignore
        # A live channel with no way to ask says it is always taken.
        self._live_taken = live_taken or _yes
        # The messages kept for viewers that subscribe later (none: not latched).
        self._latched: Deque[Tuple[bytes, int]] = deque(maxlen=max(latched_depth, 0))
        self._latched_version = 0
        self._resend_period_s = resend_period_s
        self._next_resend_s = 0.0
        self._resend_timer: Optional[threading.Timer] = None
        self._lock = threading.Lock()
        self.release: Callable[[], None] = nothing  # set by the sink that made it
        self.log: Callable[[bytes, int], None] = _ignore
        self.taken: Callable[[], bool] = _no
        self._bind()

    def _bind(self) -> None:
        """Bind ``log`` to the cheapest call that reaches the sinks there are, and ``taken``."""
        live, file = self._live_log, self._file_log
        if live is _ignore and file is _ignore:
            self.taken = _no
        elif file is not _ignore or self._latched.maxlen:
            self.taken = _yes
        else:
            self.taken = self._live_taken
        if self._latched.maxlen:
            self.log = self._log_latched
        elif live is not _ignore and file is not _ignore:
            self.log = self._log_both
        else:
            self.log = file if live is _ignore else live

    def stop_file(self) -> None:
        """Send nothing more to the file (it failed, or the topic is gone)."""
        self._file_log = _ignore
        self._bind()

    def stop(self) -> None:
        """Send nothing more anywhere, and no re-send either (the handle is released)."""
        with self._lock:
            timer, self._resend_timer = self._resend_timer, None
            self._live_log = self._file_log = _ignore
            self._bind()
        if timer is not None:
            timer.cancel()

    def _log_both(self, data: bytes, time_ns: int) -> None:
        self._live_log(data, time_ns)
        self._file_log(data, time_ns)

    def _log_latched(self, data: bytes, time_ns: int) -> None:
        with self._lock:
            self._latched.append((data, time_ns))
            self._latched_version += 1
        self._live_log(data, time_ns)
        self._file_log(data, time_ns)

    def request_resend(self) -> None:
        """
        Send the kept messages again for a viewer that subscribed: now, or at the period's end.

        Runs in a server thread. Every viewer subscribed gets the copy (the
        SDK sends a channel's messages to all its subscribers), so re-sends
        are at most one per ``resend_period_s``; a request meanwhile waits
        for one re-send at the period's end, which serves every viewer that
        subscribed in between.
        """
        with self._lock:
            if self._resend_timer is not None:
                return  # one is due already, and serves this viewer too
            wait_s = self._next_resend_s - time.monotonic()
            if wait_s > 0.0:
                self._resend_timer = threading.Timer(wait_s, self._resend_due)
                self._resend_timer.daemon = True
                self._resend_timer.start()
                return
            self._next_resend_s = time.monotonic() + self._resend_period_s
        self._send_latched()

    def _resend_due(self) -> None:
        with self._lock:
            if self._resend_timer is None:
                return  # released meanwhile
            self._resend_timer = None
            self._next_resend_s = time.monotonic() + self._resend_period_s
        self._send_latched()

    def _send_latched(self) -> None:
        """
        Send the kept messages to the live view again.

        No lock is held while the SDK sends (it may wait on the server); if a
        newer message came in meanwhile, the kept ones go out again, so a
        viewer's last message is always the newest.
        """
        while True:
            with self._lock:
                kept = list(self._latched)
                version = self._latched_version
                live_log = self._live_log
            for data, time_ns in kept:
                live_log(data, time_ns)
            with self._lock:
                if version == self._latched_version:
                    return

    def sibling(self, latched_depth: int) -> 'SinkChannel':
        """Return a handle of another publisher of this topic: the same channels, its own kept."""
        return SinkChannel(self.topic, self.type_name, self._live_log, self._file_log,
                           latched_depth, self._resend_period_s, self._live_taken)

    def __repr__(self) -> str:
        return f'SinkChannel({self.topic!r}, {self.type_name!r})'


def forget_channel(foxglove: Optional[ModuleType], channel: 'Channel') -> None:
    """
    Close an SDK channel and let it go.

    ``foxglove.Channel`` keeps every channel ever made in a module dict that
    ``close()`` leaves alone: without this, each robot spawned and deleted
    left its five or so channels behind (about 20 kB per robot, measured).
    """
    channel.close()
    registry = getattr(getattr(foxglove, 'channel', None), '_channels_by_id', None)
    if isinstance(registry, dict):
        registry.pop(channel.id(), None)
