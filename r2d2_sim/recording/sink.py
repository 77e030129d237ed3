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
  and sends them again to the live view when a viewer subscribes (the SDK
  has no latching); the file gets each message once. The SDK cannot send to
  one viewer, so every viewer subscribed gets the copy: at most one re-send
  per ``latched_resend_period_s`` (a viewer subscribing meanwhile gets the
  next, at the period's end), however often viewers subscribe.
- Release each handle when its publisher goes (a deleted robot): the
  topic's last release closes its channels (viewers see it unadvertised)
  and frees them. The MCAP file keeps the channel records it wrote, as
  every MCAP file must (its summary lists them all): about 1.4 kB each.
- A write error (a full disk) ends the recording, not the sink: one line to
  ``error``, the file closed where it stopped, the live view going on
  (:mod:`.mcap_file`). The SDK's own log lines, and the live view's health
  (a listener gone, descriptors running out), go to ``warn`` and ``error``,
  throttled (:mod:`.live_guard`).
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

from contextlib import nullcontext
import os
import sys
import time
from types import ModuleType
from typing import Any, Callable, Dict, List, Optional, TYPE_CHECKING
import weakref

from r2d2_sim.recording.channels import (
    forget_channel, LATCHED_RESEND_PERIOD_S, locked, nothing, SinkChannel)
from r2d2_sim.recording.live_guard import ListenerWatch, route_sdk_log
from r2d2_sim.recording.mcap_file import McapOutput
from r2d2_sim.recording.message_definitions import (
    message_definition, offered_qos_profiles, type_hash, UnknownMessageType)

if TYPE_CHECKING:  # an optional dependency: imported for the checker only
    from foxglove import Context
    from foxglove.mcap import MCAPWriter
    from foxglove.websocket import ChannelView, Client, ServerListener, WebSocketServer
    from rclpy.qos import QoSProfile

__all__ = ['FoxgloveSink', 'SinkError']

# The subprotocol foxglove-sdk 0.30 speaks (it refuses the older foxglove.websocket.v1).
SUBPROTOCOL = 'foxglove.sdk.v1'
# Time broadcasts per wall-clock second at most: the app redraws at about
# 60 Hz, and a 240 Hz clock would otherwise be 240 messages per second per viewer.
DEFAULT_TIME_RATE_HZ = 30.0


class SinkError(RuntimeError):
    """The sink cannot start or cannot take a channel (one line, for a startup error)."""


def _import_foxglove() -> ModuleType:
    try:
        import foxglove
        import foxglove.mcap
        import foxglove.websocket
    except ImportError as exc:
        raise SinkError(f'the live view and recording need foxglove-sdk 0.30 '
                        f'(pip install "r2d2_sim[foxglove]"): {exc}') from None
    return foxglove


def _to_stderr(text: str) -> None:
    """Say something about the sink where nobody gave it a logger."""
    print(f'r2d2_sim: {text}', file=sys.stderr, flush=True)


class _Closer:
    """
    What a sink holds outside Python (a watch thread, the file, the server), and ends it.

    The sink's finalizer calls it (close(), garbage collection, exit), so it
    holds no reference to the sink. The file first (the part that matters),
    then the server; never raises: a failure is one line to ``error``.
    """

    def __init__(self, foxglove: ModuleType, error: Callable[[str], None]) -> None:
        self.foxglove = foxglove
        self.error = error
        self.watch: Optional[ListenerWatch] = None
        self.file: Optional[McapOutput] = None
        self.writer: Optional['MCAPWriter'] = None  # writes to file, made after it
        self.server: Optional['WebSocketServer'] = None
        self.handles: Dict[str, List[SinkChannel]] = {}
        self.sdk_channels: Dict[str, list] = {}
        self.unroute: Callable[[], None] = nothing

    def __call__(self) -> None:
        if self.watch is not None:
            self.watch.stop()
        for handles in self.handles.values():
            for handle in handles:
                handle.stop()
        file, writer = self.file, self.writer
        try:
            if writer is not None and file is not None:
                try:
                    with file.lock:
                        writer.close()
                except Exception as exc:  # the SDK raises assorted types (RuntimeError...)
                    self.error(f'the recording {file.path} could not be finished: {exc}')
        finally:
            if self.file is not None:
                self.file.close()
            if self.server is not None:
                self.server.stop()
            with self.file.lock if self.file is not None else nullcontext():
                for channels in self.sdk_channels.values():
                    for channel in channels:
                        forget_channel(self.foxglove, channel)
            self.unroute()


class FoxgloveSink:
    """
    A Foxglove WebSocket server and/or an MCAP file fed with already-serialized ROS messages.

    ``port``: None for no server, 0 for any free port (read :attr:`port`).
    ``host``: the address to bind, loopback by default (``0.0.0.0`` shows the
    robot to the whole network). ``record_path``: an MCAP file to write, or
    None; an existing file is refused unless ``overwrite``. ``name``: the
    server name viewers show. ``warn`` and ``error`` take one-line reports
    while it runs (the recording stopped by a write error, the live view's
    listener gone, the SDK's own lines, throttled); stderr by default.
    ``latched_resend_period_s``: how often at most a latched topic goes to
    the live view again. ``subscriptions_changed`` is called after a
    viewer subscribes or unsubscribes, when the channels' ``taken()``
    already says so: on the server's thread, or, when a channel a viewer
    takes is released, on the releasing thread while it holds the
    recording's lock (so the callback must not log to this sink). Raises
    :class:`SinkError` (one line) when foxglove-sdk is missing, the port is
    taken or the file cannot be made.
    """

    def __init__(self, port: Optional[int] = None, host: str = '127.0.0.1',
                 record_path: Optional[str] = None, name: str = 'r2d2_sim', *,
                 overwrite: bool = False,
                 time_rate_hz: float = DEFAULT_TIME_RATE_HZ,
                 warn: Callable[[str], None] = _to_stderr,
                 error: Callable[[str], None] = _to_stderr,
                 latched_resend_period_s: float = LATCHED_RESEND_PERIOD_S,
                 subscriptions_changed: Callable[[], None] = nothing) -> None:
        if port is not None and not 0 <= port <= 65535:
            raise SinkError(f'port must be 0-65535 (0: any free port), got {port}')
        if time_rate_hz <= 0.0:
            raise SinkError(f'time_rate_hz must be > 0, got {time_rate_hz}')
        if not latched_resend_period_s >= 0.0:
            raise SinkError(f'latched_resend_period_s must be >= 0, got {latched_resend_period_s}')
        self.host = host
        self.record_path = None if record_path is None else os.fspath(record_path)
        self._warn, self._error = warn, error
        self._resend_period_s = latched_resend_period_s
        self._subscriptions_changed = subscriptions_changed
        self._foxglove: Optional[ModuleType] = None
        self._live_context: Optional['Context'] = None
        self._file_context: Optional['Context'] = None
        self._server: Optional['WebSocketServer'] = None
        self._file: Optional[McapOutput] = None
        # Why the recording stopped before close (a write error), or None.
        self.record_error: Optional[OSError] = None
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
        self._finalizer: Optional[weakref.finalize] = None
        if port is None and self.record_path is None:
            return  # nothing to feed: every channel ignores its messages
        foxglove = self._foxglove = _import_foxglove()
        closer = _Closer(foxglove, error)
        closer.handles, closer.sdk_channels = self._handles, self._sdk_channels
        try:
            self._open(foxglove, port, host, name, overwrite, closer)
        except BaseException:
            closer()
            raise
        self._finalizer = weakref.finalize(self, closer)

    def _open(self, foxglove: ModuleType, port: Optional[int], host: str, name: str,
              overwrite: bool, closer: _Closer) -> None:
        """Start the server and open the file asked for (SinkError if not; closer undoes)."""
        closer.unroute = route_sdk_log(closer, self._warn)
        # Two contexts, so that messages sent again for a late viewer reach
        # the server but not the file (the SDK gives Python no per-sink log).
        # The server first: a taken port then leaves no file behind.
        doing = f'cannot serve on {host}:{port}'
        try:
            if port is not None:
                self._live_context = foxglove.Context()
                server = foxglove.start_server(
                    name=name, host=host, port=port, context=self._live_context,
                    capabilities=[foxglove.websocket.Capability.Time],
                    server_listener=_make_listener(foxglove, self._latched_by_id,
                                                   self._subscriptions_changed))
                self._server = closer.server = server
                closer.watch = ListenerWatch(server.port, _address(host, server.port),
                                             self._warn, self._error)
            if self.record_path is not None:
                doing = f'cannot record to {self.record_path}'
                failed = weakref.WeakMethod(self._file_failed)
                self._file = closer.file = McapOutput(
                    self.record_path, overwrite, lambda exc: _call_if_alive(failed, exc))
                self._file_context = foxglove.Context()
                with self._file.lock:
                    closer.writer = foxglove.open_mcap(
                        self._file, context=self._file_context,
                        writer_options=foxglove.mcap.MCAPWriteOptions(profile='ros2'))
                    closer.writer.flush()  # the header now: a full disk is a startup error
                if self._file.error is not None:
                    os.unlink(self.record_path)  # ours, and empty: leave nothing behind
                    raise SinkError(f'{doing}: {self._file.error.strerror or self._file.error}')
        except SinkError:
            raise
        except FileExistsError:
            raise SinkError(f'{self.record_path} exists: choose another file name') from None
        except Exception as exc:  # the SDK raises assorted types (RuntimeError, OSError...)
            raise SinkError(f'{doing}: {exc}') from None

    def _file_failed(self, exc: OSError) -> None:
        """
        Stop feeding the recording's file, which failed (a full disk), and say so once.

        Called by the file inside the SDK's write, in whichever thread logged:
        nothing here calls the SDK.
        """
        self.record_error = exc
        if self._finalizer is None:
            return  # still opening: _open raises it, a startup error
        for handles in list(self._handles.values()):
            for handle in handles:
                handle.stop_file()
        reason = exc.strerror or str(exc)
        self._error(f'recording stopped: cannot write {self.record_path}: {reason}; it '
                    'holds what was written before, unfinished (no summary). The simulation '
                    'and the live view go on')

    @property
    def port(self) -> Optional[int]:
        """Return the port the server listens on (None without a server, or once closed)."""
        if self._server is None or (self._finalizer is not None and not self._finalizer.alive):
            return None
        return self._server.port

    @property
    def url(self) -> Optional[str]:
        """Return the WebSocket address viewers connect to (``ws://host:port``), or None."""
        port = self.port
        return None if port is None else _address(self.host, port)

    @property
    def topics(self) -> List[str]:
        """Return the topics registered so far."""
        return list(self._channels)

    def channel(self, topic: str, type_name: str, qos: 'QoSProfile') -> SinkChannel:
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
        live_log, file_log, live_id, live_taken = self._open_channels(topic, type_name, qos)
        depth = max(qos.depth, 1) if latched else 0
        handle = SinkChannel(topic, type_name, live_log, file_log, depth, self._resend_period_s,
                             live_taken)
        self._channels[topic] = handle
        self._live_ids[topic] = live_id
        return self._track(handle, latched)

    def _open_channels(self, topic: str, type_name: str, qos: 'QoSProfile') -> tuple:
        """
        Advertise ``topic`` to the live view and the file.

        Return their logs, the live channel's id and its ``has_sinks`` (a viewer subscribes).
        """
        live_log = file_log = live_id = live_taken = None
        if self._foxglove is None:
            return live_log, file_log, live_id, live_taken
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
        channels = self._sdk_channels.setdefault(topic, [])
        if self._live_context is not None:
            channel = self._foxglove.Channel(topic, schema=schema, message_encoding='cdr',
                                             context=self._live_context, metadata=metadata)
            channels.append(channel)
            live_log, live_id = channel.base.log, channel.base.id()
            live_taken = channel.base.has_sinks
        file = self._file  # there is a file context only with a file
        if self._file_context is not None and file is not None and self.record_error is None:
            with file.lock:
                channel = self._foxglove.Channel(topic, schema=schema, message_encoding='cdr',
                                                 context=self._file_context, metadata=metadata)
            channels.append(channel)
            file_log = locked(channel.base.log, file.lock)
        return live_log, file_log, live_id, live_taken

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
        topic's last publisher the channels are closed, which unadvertises
        them, and let go (the file keeps the channel record it wrote).
        """
        topic = handle.topic
        handles = self._handles.get(topic, [])
        if handle not in handles:
            return
        handles.remove(handle)
        handle.release = nothing
        handle.stop()
        live_id = self._live_ids.get(topic)
        latched = [] if live_id is None else self._latched_by_id.get(live_id, [])
        if handle in latched:
            latched.remove(handle)
        if handles:
            # The next publisher of the topic is made from a live handle, not this stopped one.
            self._channels[topic] = handles[0]
            return
        with self._file.lock if self._file is not None else nullcontext():
            for channel in self._sdk_channels.pop(topic, []):
                forget_channel(self._foxglove, channel)
        if live_id is not None:
            self._latched_by_id.pop(live_id, None)
        self._live_ids.pop(topic, None)
        self._channels.pop(topic, None)
        self._handles.pop(topic, None)

    def _share(self, first: SinkChannel, type_name: str, qos: 'QoSProfile') -> SinkChannel:
        """Return a handle of another publisher on ``first``'s channel."""
        if type_name != first.type_name:
            raise SinkError(f'topic {first.topic} is registered as {first.type_name}, '
                            f'not {type_name}')
        latched = qos.durability.name == 'TRANSIENT_LOCAL'
        return self._track(first.sibling(max(qos.depth, 1) if latched else 0), latched)

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
        """Finish the MCAP file and stop the server; safe to call again; never raises."""
        if self._finalizer is not None:
            self._finalizer()

    def __enter__(self) -> 'FoxgloveSink':
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return (f'FoxgloveSink(url={self.url!r}, record_path={self.record_path!r}, '
                f'topics={len(self._channels)})')


def _address(host: str, port: int) -> str:
    """Return the WebSocket address viewers connect to (an IPv6 host in brackets, RFC 3986)."""
    if ':' in host and not host.startswith('['):
        host = f'[{host}]'
    return f'ws://{host}:{port}'


def _call_if_alive(method: weakref.WeakMethod, *args: Any) -> None:
    """Call a weakly held method if its object still exists (a sink the file reports to)."""
    bound = method()
    if bound is not None:
        bound(*args)


def _make_listener(foxglove: Any, latched_by_id: Dict[int, List[SinkChannel]],
                   subscriptions_changed: Callable[[], None] = nothing) -> 'ServerListener':
    """
    Return a server listener that re-sends latched topics when a viewer subscribes.

    ``subscriptions_changed`` is called after a viewer subscribes or unsubscribes.
    """
    class LatchingListener(foxglove.websocket.ServerListener):
        # A subclass, not a plain class: the server calls every method of the
        # protocol, and a missing one fails ("AttributeError: on_unsubscribe").
        def on_subscribe(self, client: 'Client', channel: 'ChannelView') -> None:
            for handle in list(latched_by_id.get(channel.id, ())):
                handle.request_resend()
            subscriptions_changed()

        def on_unsubscribe(self, client: 'Client', channel: 'ChannelView') -> None:
            subscriptions_changed()
    return LatchingListener()
