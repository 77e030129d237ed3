"""
A second consumer of the node's serialized messages: a Foxglove live view and an MCAP recording.

:class:`FoxgloveSink` takes the CDR bytes the node already publishes over DDS
and sends the same bytes, unconverted, to a Foxglove WebSocket server (for
Foxglove, Lichtblick or PlotJuggler) and to an MCAP file in rosbag2's ``ros2``
profile (``ros2msg`` schemas, ``cdr`` messages, ``offered_qos_profiles`` and
``topic_type_hash`` channel metadata, zstd chunks), which ``ros2 bag play``,
Foxglove, rosbags and :mod:`r2d2_sim.apps.replay` open with no ``metadata.yaml``.

How an owner (the node) uses it::

    sink = FoxgloveSink(port=8765, record_path='run.mcap')   # either may be None
    scan = sink.channel(publisher.topic_name, 'sensor_msgs/msg/LaserScan', qos)
    ...
    publisher.publish(data); scan.log(data, sim_time_ns)     # same bytes, simulated time
    sink.set_time(sim_time_ns)                               # on each clock tick
    ...
    sink.close()                                             # in destroy_node

- Topic names must be absolute: pass the publisher's resolved ``topic_name``.
- Register a latched topic (``/robot_description``, ``/tf_static``) with the
  publisher's transient-local QoS: the sink keeps its last ``depth`` messages
  and sends them again to the live view whenever a viewer subscribes (the
  SDK has no latching); the file gets each message once.
- Close it. An MCAP file is only readable once closed (its summary and
  footer come last: a file left open by a killed process made ``mcap``
  fail with "CHUNK record has length 18446744073709551615"). :meth:`close`
  is idempotent and also runs at interpreter exit and on garbage
  collection, but not when a signal's default action kills the process: the
  owner must turn SIGINT and SIGTERM into a normal return (as
  ``sim_node.stop_on_signals`` does) and close in a ``finally``. SIGKILL
  always loses the file's end.

foxglove-sdk (``pip install "r2d2_sim[foxglove]"``) is imported only when a
sink is made, so the package works without it.
"""

from collections import deque
import os
import threading
import time
from typing import Callable, Deque, Dict, List, Optional, Tuple
import weakref

from r2d2_sim.recording.message_definitions import (
    message_definition, offered_qos_profiles, type_hash, UnknownMessageType)

__all__ = ['FoxgloveSink', 'SinkChannel', 'SinkError']

# The subprotocol foxglove-sdk 0.30 speaks (it refuses the older foxglove.websocket.v1).
SUBPROTOCOL = 'foxglove.sdk.v1'
# Time broadcasts per wall-clock second at most: the app redraws at about
# 60 Hz, and a 240 Hz clock would otherwise be 240 messages per second per viewer.
DEFAULT_TIME_RATE_HZ = 30.0


class SinkError(RuntimeError):
    """The sink cannot start or cannot take a channel (one line, for a startup error)."""


def _import_foxglove():
    try:
        import foxglove
        import foxglove.mcap
        import foxglove.websocket
    except ImportError as exc:
        raise SinkError(f'the live view and recording need foxglove-sdk 0.30 '
                        f'(pip install "r2d2_sim[foxglove]"): {exc}') from None
    return foxglove


def _ignore(data: bytes, time_ns: int) -> None:
    """Stand in for a sink that is not there."""


def _nothing() -> None:
    """Release a handle no sink tracks."""


class SinkChannel:
    """
    One topic of a :class:`FoxgloveSink`: ``log(data, time_ns)`` sends the bytes on.

    ``data`` is one serialized message as ``bytes`` (the SDK refuses a
    ``bytearray`` or ``memoryview`` with TypeError: pass the object given to
    ``publish``), ``time_ns`` the simulated time in nanoseconds (>= 0), which
    becomes the MCAP log time and the WebSocket message time. ``log`` is
    bound at construction to the cheapest call for the sinks that exist (the
    SDK's own method when there is one).
    """

    def __init__(self, topic: str, type_name: str, live_log: Optional[Callable],
                 file_log: Optional[Callable], latched_depth: int = 0) -> None:
        self.topic = topic
        self.type_name = type_name
        self._live_log = live_log or _ignore
        self._file_log = file_log or _ignore
        self._latched: Optional[Deque[Tuple[bytes, int]]] = (
            deque(maxlen=latched_depth) if latched_depth > 0 else None)
        self._latched_version = 0
        self._lock = threading.Lock()
        self.release: Callable[[], None] = _nothing  # set by the sink that made it
        if self._latched is not None:
            self.log = self._log_latched
        elif live_log is not None and file_log is not None:
            self.log = self._log_both
        else:
            self.log = live_log or file_log or _ignore

    def _log_both(self, data: bytes, time_ns: int) -> None:
        self._live_log(data, time_ns)
        self._file_log(data, time_ns)

    def _log_latched(self, data: bytes, time_ns: int) -> None:
        with self._lock:
            self._latched.append((data, time_ns))
            self._latched_version += 1
        self._live_log(data, time_ns)
        self._file_log(data, time_ns)

    def _send_latched(self) -> None:
        """
        Send the kept messages to the live view again (called when a viewer subscribes).

        Runs in a server thread. No lock is held while the SDK sends (it may
        wait on the server); if a newer message came in meanwhile, the kept
        ones go out again, so a viewer's last message is always the newest.
        """
        while True:
            with self._lock:
                kept = list(self._latched)
                version = self._latched_version
            for data, time_ns in kept:
                self._live_log(data, time_ns)
            with self._lock:
                if version == self._latched_version:
                    return

    def __repr__(self) -> str:
        return f'SinkChannel({self.topic!r}, {self.type_name!r})'


def _close(writer, server) -> None:
    """Finish the file first (the part that matters), then stop the server."""
    try:
        if writer is not None:
            writer.close()
    finally:
        if server is not None:
            server.stop()


class FoxgloveSink:
    """
    A Foxglove WebSocket server and/or an MCAP file fed with already-serialized ROS messages.

    ``port``: None for no server, 0 for any free port (read :attr:`port`).
    ``host``: the address to bind, loopback by default (``0.0.0.0`` shows the
    robot to the whole network). ``record_path``: an MCAP file to write, or
    None; an existing file is refused unless ``overwrite``. ``name``: the
    server name viewers show. Raises :class:`SinkError` (one line) when
    foxglove-sdk is missing, the port is taken or the file cannot be made.
    """

    def __init__(self, port: Optional[int] = None, host: str = '127.0.0.1',
                 record_path: Optional[str] = None, name: str = 'r2d2_sim', *,
                 overwrite: bool = False,
                 time_rate_hz: float = DEFAULT_TIME_RATE_HZ) -> None:
        if port is not None and not 0 <= port <= 65535:
            raise SinkError(f'port must be 0-65535 (0: any free port), got {port}')
        if time_rate_hz <= 0.0:
            raise SinkError(f'time_rate_hz must be > 0, got {time_rate_hz}')
        self.host = host
        self.record_path = None if record_path is None else os.fspath(record_path)
        self._foxglove = None
        self._live_context = None
        self._file_context = None
        self._server = None
        self._writer = None
        self._channels: Dict[str, SinkChannel] = {}
        # Each publisher's handle of a latched topic, by the SDK's channel id.
        self._latched_by_id: Dict[int, List[SinkChannel]] = {}
        self._live_ids: Dict[str, Optional[int]] = {}
        # Each topic's publisher handles, and the SDK channels to close with the last one.
        self._handles: Dict[str, List[SinkChannel]] = {}
        self._sdk_channels: Dict[str, list] = {}
        self._time_period_s = 1.0 / time_rate_hz
        self._next_time_s = 0.0
        self._last_time_ns = -1
        self._finalizer = None
        if port is None and self.record_path is None:
            return  # nothing to feed: every channel ignores its messages
        self._foxglove = _import_foxglove()
        self._open(port, host, name, overwrite)
        self._finalizer = weakref.finalize(self, _close, self._writer, self._server)

    def _open(self, port: Optional[int], host: str, name: str, overwrite: bool) -> None:
        """Start the server and open the file asked for (SinkError, leaving neither, if not)."""
        foxglove = self._foxglove
        # Two contexts, so that messages sent again for a late viewer reach
        # the server but not the file (the SDK gives Python no per-sink log).
        # The server first: a taken port then leaves no file behind.
        doing = f'cannot serve on {host}:{port}'
        try:
            if port is not None:
                self._live_context = foxglove.Context()
                self._server = foxglove.start_server(
                    name=name, host=host, port=port, context=self._live_context,
                    capabilities=[foxglove.websocket.Capability.Time],
                    server_listener=_make_listener(foxglove, self._latched_by_id))
            if self.record_path is not None:
                doing = f'cannot record to {self.record_path}'
                if os.path.exists(self.record_path) and not overwrite:
                    raise SinkError(f'{self.record_path} exists: choose another file name')
                self._file_context = foxglove.Context()
                self._writer = foxglove.open_mcap(
                    self.record_path, allow_overwrite=overwrite, context=self._file_context,
                    writer_options=foxglove.mcap.MCAPWriteOptions(profile='ros2'))
        except SinkError:
            _close(self._writer, self._server)
            raise
        except Exception as exc:  # the SDK raises assorted types (RuntimeError, OSError...)
            _close(self._writer, self._server)
            raise SinkError(f'{doing}: {exc}') from None

    @property
    def port(self) -> Optional[int]:
        """Return the port the server listens on (None without a server, or once closed)."""
        if self._server is None or not self._finalizer.alive:
            return None
        return self._server.port

    @property
    def url(self) -> Optional[str]:
        """Return the WebSocket address viewers connect to (``ws://host:port``), or None."""
        port = self.port
        return None if port is None else f'ws://{self.host}:{port}'

    @property
    def topics(self) -> List[str]:
        """Return the topics registered so far."""
        return list(self._channels)

    def channel(self, topic: str, type_name: str, qos) -> SinkChannel:
        """
        Register a publisher of ``topic`` (absolute) of ROS type ``type_name`` with ``qos``.

        ``qos`` is the rclpy ``QoSProfile`` of the DDS publisher: it goes into
        the recording, and transient-local durability makes the topic
        latched here too (its last ``qos.depth`` messages are re-sent to
        viewers that subscribe later). A topic that several publishers share
        (several robots' ``/tf`` and ``/tf_static``) is one channel; each
        publisher's handle keeps its own latched messages, as each DDS
        publisher does. Raises :class:`SinkError` for a relative topic, a
        topic registered with another type, or a type with no definition
        installed.
        """
        if not topic.startswith('/'):
            raise SinkError(f'topic {topic!r} is relative: pass the resolved name '
                            '(the publisher\'s topic_name)')
        first = self._channels.get(topic)
        if first is not None:
            return self._share(first, type_name, qos)
        latched = qos.durability.name == 'TRANSIENT_LOCAL'
        live_log, file_log, live_id = self._open_channels(topic, type_name, qos)
        depth = max(qos.depth, 1) if latched else 0
        handle = SinkChannel(topic, type_name, live_log, file_log, depth)
        self._channels[topic] = handle
        self._live_ids[topic] = live_id
        return self._track(handle, latched)

    def _open_channels(self, topic: str, type_name: str, qos) -> tuple:
        """Advertise ``topic`` to the live view and the file; return their logs and live id."""
        live_log = file_log = live_id = None
        if self._foxglove is None:
            return live_log, file_log, live_id
        try:
            definition = message_definition(type_name)
        except UnknownMessageType as exc:
            raise SinkError(f'{topic}: {exc}') from None
        metadata = {'offered_qos_profiles': offered_qos_profiles(qos)}
        try:
            metadata['topic_type_hash'] = type_hash(type_name)
        except UnknownMessageType:
            pass  # rosbag2 writes no hash either when it has none
        schema = self._foxglove.Schema(name=type_name, encoding='ros2msg',
                                       data=definition.encode('utf-8'))
        for context in (self._live_context, self._file_context):
            if context is None:
                continue
            channel = self._foxglove.Channel(topic, schema=schema, message_encoding='cdr',
                                             context=context, metadata=metadata)
            self._sdk_channels.setdefault(topic, []).append(channel)
            if context is self._live_context:
                live_log, live_id = channel.base.log, channel.base.id()
            else:
                file_log = channel.base.log
        return live_log, file_log, live_id

    def _track(self, handle: SinkChannel, latched: bool) -> SinkChannel:
        """Keep ``handle`` among its topic's publishers (and latched ones) until released."""
        topic = handle.topic
        self._handles.setdefault(topic, []).append(handle)
        live_id = self._live_ids.get(topic)
        if latched and live_id is not None:
            self._latched_by_id.setdefault(live_id, []).append(handle)
        handle.release = lambda: self._release(handle)
        return handle

    def _release(self, handle: SinkChannel) -> None:
        """
        Forget one publisher's handle (its node is gone: a deleted robot).

        Its latched messages are no longer re-sent to new viewers; with its
        topic's last publisher the channel is closed, which unadvertises it.
        """
        topic = handle.topic
        handles = self._handles.get(topic, [])
        if handle not in handles:
            return
        handles.remove(handle)
        handle.release = _nothing
        live_id = self._live_ids.get(topic)
        latched = self._latched_by_id.get(live_id, [])
        if handle in latched:
            latched.remove(handle)
        if handles:
            return
        for channel in self._sdk_channels.pop(topic, []):
            channel.close()
        self._latched_by_id.pop(live_id, None)
        self._live_ids.pop(topic, None)
        self._channels.pop(topic, None)
        self._handles.pop(topic, None)

    def _share(self, first: SinkChannel, type_name: str, qos) -> SinkChannel:
        """Return a handle of another publisher on ``first``'s channel."""
        if type_name != first.type_name:
            raise SinkError(f'topic {first.topic} is registered as {first.type_name}, '
                            f'not {type_name}')
        latched = qos.durability.name == 'TRANSIENT_LOCAL'
        logs = [None if log is _ignore else log for log in (first._live_log, first._file_log)]
        handle = SinkChannel(first.topic, type_name, *logs, max(qos.depth, 1) if latched else 0)
        return self._track(handle, latched)

    def set_time(self, time_ns: int) -> None:
        """
        Tell viewers the simulated time (nanoseconds), at most ``time_rate_hz`` times a second.

        A time that goes back (a reset) is sent at once.
        """
        if self._server is None:
            return
        now = time.monotonic()
        if now >= self._next_time_s or time_ns < self._last_time_ns:
            self._server.broadcast_time(time_ns)
            self._next_time_s = now + self._time_period_s
        self._last_time_ns = time_ns

    def close(self) -> None:
        """Finish the MCAP file and stop the server; safe to call again."""
        if self._finalizer is not None:
            self._finalizer()

    def __enter__(self) -> 'FoxgloveSink':
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def __repr__(self) -> str:
        return (f'FoxgloveSink(url={self.url!r}, record_path={self.record_path!r}, '
                f'topics={len(self._channels)})')


def _make_listener(foxglove, latched_by_id: Dict[int, List[SinkChannel]]):
    """Return a server listener that re-sends latched topics to a viewer that subscribes."""
    class LatchingListener(foxglove.websocket.ServerListener):
        # A subclass, not a plain class: the server calls every method of the
        # protocol, and a missing one fails ("AttributeError: on_unsubscribe").
        def on_subscribe(self, client, channel) -> None:
            for handle in latched_by_id.get(channel.id, ()):
                handle._send_latched()
    return LatchingListener()
