"""
What the live view's owner can do about foxglove-sdk's server from outside it.

foxglove-sdk 0.30 gives Python no say over connections: no viewer limit, no
accept or connect callback, no send to one viewer. Its accept loop ends at
its first error (``while let Ok(..) = listener.accept()``): out of file
descriptors (``ulimit -n``), the live view stopped accepting viewers for
good and said nothing. And it logs through Python's ``logging`` one line per
bad client message (20,000 lines in 2 s). What can be done from outside is here:

- :func:`route_sdk_log` sends the SDK's lines (the ``foxglove`` loggers),
  throttled per kind, to the newest sink's ``warn`` (the node's logger, so
  ROS says them) instead of stderr.
- :class:`ListenerWatch` looks at the server once a second, in a thread:
  one error line when its listening socket is gone, one warning when the
  process's descriptors are close to running out, and freed memory handed
  back to the system after viewers leave (glibc kept the 72 MB of 500
  idle connections after they closed; ``malloc_trim`` returns it).

Linux only (``/proc``); elsewhere the watch does nothing.
"""

import logging
import os
import re
import resource
import sys
import threading
from typing import Callable, List, Optional, Tuple

from r2d2_sim.memory import malloc_trim
from r2d2_sim.model.timing import ThrottledLog

__all__ = ['route_sdk_log', 'ListenerWatch', 'SDK_LOG_PERIOD_S']

# Each kind of line from the SDK (addresses and numbers aside) at most this often.
SDK_LOG_PERIOD_S = 10.0
# How often the watch looks at the listener and the descriptors (wall seconds).
WATCH_PERIOD_S = 1.0
# Warn when this share of the descriptor limit is open; again only after it fell below half.
DESCRIPTORS_WARN_SHARE = 0.8
# Hand memory back once this many descriptors were closed since the last peak (viewers left).
TRIM_AFTER_CLOSED = 16

Log = Callable[[str], None]


def _stderr(text: str) -> None:
    print(f'r2d2_sim live view: {text}', file=sys.stderr, flush=True)


class _SdkLogRouter(logging.Handler):
    """The ``foxglove`` loggers' one handler: lines to the newest owner, throttled per kind."""

    def __init__(self) -> None:
        super().__init__()
        # (key, warn, its own throttle), newest last: a new sink hears each kind afresh.
        self._owners: List[Tuple[object, Log, ThrottledLog]] = []
        self._owners_lock = threading.Lock()
        self._unowned = ThrottledLog(SDK_LOG_PERIOD_S)  # lines while no sink is open

    def add(self, key: object, warn: Log) -> None:
        with self._owners_lock:
            self._owners.append((key, warn, ThrottledLog(SDK_LOG_PERIOD_S)))

    def remove(self, key: object) -> None:
        with self._owners_lock:
            self._owners = [owner for owner in self._owners if owner[0] is not key]

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno < logging.WARNING:
            # Asked for by whoever lowered the level: their handlers, unthrottled.
            logging.getLogger().handle(record)
            return
        with self._owners_lock:
            owner = self._owners[-1] if self._owners else (None, _stderr, self._unowned)
        _, warn, throttled = owner
        try:
            text = record.getMessage()
        except Exception:  # a malformed record must not break the SDK's thread
            text = str(record.msg)
        kind = re.sub(r'\d+', '#', text)[:100]  # addresses and counts vary within a kind
        # Warnings, whatever the SDK's level: its lines are about viewers (a bad
        # message, a failed handshake), not errors of the simulator.
        throttled(kind, warn, f'foxglove-sdk: {text}')


_router: Optional[_SdkLogRouter] = None
_router_lock = threading.Lock()


def route_sdk_log(key: object, warn: Log) -> Callable[[], None]:
    """
    Send the SDK's log lines to ``warn`` (the newest caller's), throttled per kind.

    Returns the call that undoes it for ``key``. Takes the ``foxglove``
    logger over for the process (``propagate`` off): the lines no longer
    reach the root logger's handlers, but lines below WARNING that someone
    asked for still do.
    """
    global _router
    with _router_lock:
        if _router is None:
            _router = _SdkLogRouter()
            logger = logging.getLogger('foxglove')
            logger.addHandler(_router)
            logger.propagate = False
        router = _router
    router.add(key, warn)
    return lambda: router.remove(key)


def _listening_socket(port: int) -> Optional[Tuple[int, str]]:
    """Return (descriptor, ``socket:[inode]``) of this process's TCP listener on ``port``."""
    inodes = set()
    for table in ('/proc/net/tcp', '/proc/net/tcp6'):
        try:
            with open(table) as rows:
                next(rows)
                for row in rows:
                    fields = row.split()
                    # local address "ADDR:PORT" in hex, state 0A = LISTEN, inode
                    if fields[3] == '0A' and int(fields[1].rsplit(':', 1)[1], 16) == port:
                        inodes.add(f'socket:[{fields[9]}]')
        except (OSError, StopIteration, IndexError, ValueError):
            continue
    for name in _descriptors():
        try:
            link = os.readlink(f'/proc/self/fd/{name}')
        except OSError:
            continue
        if link in inodes:
            return int(name), link
    return None


def _descriptors() -> List[str]:
    try:
        return os.listdir('/proc/self/fd')
    except OSError:
        return []


class ListenerWatch:
    """
    Watch the live view's listener on ``port`` from a thread; report to ``warn``/``error``.

    ``url`` names the view in the lines. :meth:`check` is one look (the
    thread calls it every ``period_s``); :meth:`stop` ends the thread.
    ``listening`` is False once the listener is gone.
    """

    def __init__(self, port: int, url: str, warn: Log, error: Log,
                 period_s: float = WATCH_PERIOD_S) -> None:
        self.url = url
        self._warn, self._error = warn, error
        self._listener = _listening_socket(port)
        self.listening = True
        self._trim = malloc_trim
        self._peak = 0
        self._warned = False
        self._stop = threading.Event()
        self._period_s = period_s
        self._thread: Optional[threading.Thread] = None
        if self._listener is not None:  # else no /proc: nothing to watch
            self._thread = threading.Thread(target=self._run, name='live-view-watch',
                                            daemon=True)
            self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self._period_s):
            self.check()

    def check(self) -> None:
        """Look once: the listener, the descriptors, memory to give back."""
        open_now = len(_descriptors())
        limit = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
        if self.listening and not self._alive():
            self.listening = False
            self._error(
                f'the live view at {self.url} stopped accepting viewers: its listening socket '
                f'closed ({open_now} of {_limit_text(limit)} file descriptors open; '
                'foxglove-sdk 0.30 stops listening for good when they run out). Connected '
                'viewers keep their view; new ones are refused until the node restarts')
        if self.listening and limit != resource.RLIM_INFINITY:
            if not self._warned and open_now >= DESCRIPTORS_WARN_SHARE * limit:
                self._warned = True
                self._warn(
                    f'{open_now} of {limit} file descriptors are open (ulimit -n): when they '
                    f'run out, the live view at {self.url} stops accepting viewers for good '
                    '(foxglove-sdk 0.30 has no viewer limit)')
            elif self._warned and open_now < limit / 2:
                self._warned = False
        self._peak = max(self._peak, open_now)
        if self._peak - open_now >= TRIM_AFTER_CLOSED:
            self._trim()  # viewers left: about 150 kB each that glibc would keep
            self._peak = open_now

    def _alive(self) -> bool:
        if self._listener is None:  # none found (no /proc): nothing says it is gone
            return True
        fd, link = self._listener
        try:
            return os.readlink(f'/proc/self/fd/{fd}') == link
        except OSError:
            return False

    def stop(self) -> None:
        """End the thread (again: nothing happens)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)


def _limit_text(limit: int) -> str:
    return 'unlimited' if limit == resource.RLIM_INFINITY else str(limit)
