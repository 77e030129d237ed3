"""
A client of the simulator's live view, for CI checks: what Foxglove does, minus the drawing.

The node's live view (``foxglove_port``) is a Foxglove WebSocket server
(foxglove-sdk, subprotocol ``foxglove.sdk.v1``). :class:`LiveViewClient`
connects to it, lists the channels it advertises, subscribes to topics and
keeps each message's bytes (the CDR the node publishes over DDS) with its
log time (simulated nanoseconds), and the server's time messages::

    with LiveViewClient(8765) as view:
        view.subscribe(['/odom'])
        odom = view.wait_for_messages('/odom', count=5)
        msg = rclpy.serialization.deserialize_message(odom[-1].data, Odometry)

It reads only when asked (:meth:`pump` and the waits), in the caller's
thread: no background thread, every wait bounded by a deadline. It needs the
``websockets`` package (``pip install websockets``).
"""

from collections import defaultdict
from contextlib import ExitStack
import json
import struct
import time
from typing import Any, Callable, Dict, Iterable, List, NamedTuple, Optional, Union

__all__ = ['LiveViewClient', 'LiveMessage', 'LiveViewError', 'SUBPROTOCOL']

# The live view's subprotocol (foxglove-sdk 0.30 refuses the older foxglove.websocket.v1).
SUBPROTOCOL = 'foxglove.sdk.v1'
# Binary opcodes the server sends (the Foxglove WebSocket protocol).
_MESSAGE_DATA = 1
_TIME = 2


class LiveMessage(NamedTuple):
    """One message as the live view sent it: its log time (simulated ns) and its bytes."""

    log_time_ns: int
    data: bytes


class LiveViewError(RuntimeError):
    """The client cannot connect, or was asked for a topic the server does not advertise."""


def _websockets_at_least(*wanted: int) -> bool:
    """Return True if the installed websockets is at least version ``wanted``."""
    from websockets.version import version
    numbers = []
    for part in version.split('.')[:len(wanted)]:
        digits = ''.join(c for c in part if c.isdigit()) or '0'
        numbers.append(int(digits))
    return tuple(numbers) >= wanted


class LiveViewClient:
    """
    A Foxglove WebSocket client of the live view at ``address``: a port on this host, or a URL.

    Attributes, filled as frames are read: ``server_info`` (the server's
    hello, a dict), ``channels`` (topic -> its advertisement: ``id``,
    ``topic``, ``encoding`` (``cdr``), ``schemaName`` (the ROS type),
    ``schema``, ``schemaEncoding`` (``ros2msg``)), ``messages`` (topic -> the
    :class:`LiveMessage` list received, in order), ``times`` (the simulated
    times the server broadcast, ns). ``timeout_s`` bounds connecting and is
    the default deadline of every wait. Raises :class:`LiveViewError` (one
    line) when it cannot connect.
    """

    def __init__(self, address: Union[int, str], *, timeout_s: float = 10.0,
                 subprotocol: str = SUBPROTOCOL) -> None:
        try:
            from websockets.sync.client import connect
            from websockets.typing import Subprotocol
        except ImportError:
            raise LiveViewError('LiveViewClient needs the websockets package '
                                '(pip install websockets)') from None
        self.url = f'ws://127.0.0.1:{address}' if isinstance(address, int) else address
        self.timeout_s = timeout_s
        self.server_info: Optional[dict] = None
        self.channels: Dict[str, dict] = {}
        self.messages: Dict[str, List[LiveMessage]] = defaultdict(list)
        self.times: List[int] = []
        self._topic_of_subscription: Dict[int, str] = {}
        self._subscription_of_topic: Dict[str, int] = {}
        self._next_subscription = 1
        self._stack = ExitStack()  # websockets wants its connection used as a context
        try:
            # max_queue=None: frames the reader takes while nobody pumps are buffered
            # without bound, as ``messages`` keeps them. A bounded queue (websockets'
            # default: 16 frames) stops reading once full, so the end of the connection
            # was never read and every close after a busy subscription waited out
            # close_timeout (10 s).
            # (websockets 14.1 first took max_queue=None here; older ones keep their queue.)
            unbounded = {'max_queue': None} if _websockets_at_least(14, 1) else {}
            self._ws = self._stack.enter_context(connect(
                self.url, subprotocols=[Subprotocol(subprotocol)], max_size=None,
                open_timeout=timeout_s, **unbounded))
        except Exception as exc:  # websockets and the OS raise assorted types
            raise LiveViewError(f'cannot connect to the live view at {self.url}: {exc}') from None

    def pump(self, condition: Callable[[], bool] = lambda: False,
             timeout_s: Optional[float] = None) -> bool:
        """
        Read what the server sends until ``condition()`` holds or the deadline passes.

        Returns whether the condition held. With the default condition it
        simply reads for ``timeout_s``. A closed connection ends the wait
        (False unless the condition holds).
        """
        from websockets.exceptions import ConnectionClosed
        deadline = time.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)
        while not condition():
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                return False
            try:
                frame = self._ws.recv(timeout=min(remaining, 0.1))
            except TimeoutError:
                continue
            except ConnectionClosed:
                return condition()
            self._take(frame)
        return True

    def wait_for_channels(self, topics: Iterable[str],
                          timeout_s: Optional[float] = None) -> Dict[str, dict]:
        """Return the advertisements of ``topics`` once all are there; LiveViewError if not."""
        topics = list(topics)
        if not self.pump(lambda: all(t in self.channels for t in topics), timeout_s):
            missing = [t for t in topics if t not in self.channels]
            raise LiveViewError(f'the live view does not advertise {", ".join(missing)}; '
                                f'it has {", ".join(sorted(self.channels)) or "nothing"}')
        return {topic: self.channels[topic] for topic in topics}

    def subscribe(self, topics: Iterable[str], timeout_s: Optional[float] = None) -> None:
        """Subscribe to ``topics`` (waiting for their advertisements; LiveViewError if none)."""
        topics = [t for t in topics if t not in self._subscription_of_topic]
        advertised = self.wait_for_channels(topics, timeout_s)
        subscriptions: List[Dict[str, int]] = []
        for topic in topics:
            subscriptions.append({'id': self._next_subscription + len(subscriptions),
                                  'channelId': advertised[topic]['id']})
        if not subscriptions:
            return
        self._send({'op': 'subscribe', 'subscriptions': subscriptions})
        # Noted once sent: a connection that is gone subscribes nothing.
        for topic, sent in zip(topics, subscriptions):
            self._topic_of_subscription[sent['id']] = topic
            self._subscription_of_topic[topic] = sent['id']
        self._next_subscription += len(subscriptions)

    def unsubscribe(self, topics: Iterable[str]) -> None:
        """Stop receiving ``topics`` (what was received stays in ``messages``)."""
        topics = [t for t in topics if t in self._subscription_of_topic]
        if topics:
            self._send({'op': 'unsubscribe',
                        'subscriptionIds': [self._subscription_of_topic[t] for t in topics]})
            for topic in topics:
                del self._subscription_of_topic[topic]

    def _send(self, message: dict) -> None:
        """Send a JSON operation; LiveViewError (one line) when the connection is gone."""
        from websockets.exceptions import ConnectionClosed
        try:
            self._ws.send(json.dumps(message))
        except ConnectionClosed as exc:
            raise LiveViewError(f'the live view at {self.url} closed the connection '
                                f'({exc}): connect again') from None

    def wait_for_messages(self, topic: str, count: int = 1,
                          timeout_s: Optional[float] = None) -> List[LiveMessage]:
        """Subscribe to ``topic`` if needed; return its messages once ``count`` arrived."""
        self.subscribe([topic], timeout_s)
        if not self.pump(lambda: len(self.messages[topic]) >= count, timeout_s):
            raise LiveViewError(f'{topic}: {len(self.messages[topic])} of {count} messages '
                                f'from the live view at {self.url} before the deadline')
        return list(self.messages[topic])

    def _take(self, frame: Union[str, bytes]) -> None:
        if isinstance(frame, str):
            message = json.loads(frame)
            op = message.get('op')
            if op == 'serverInfo':
                self.server_info = message
            elif op == 'advertise':
                for channel in message['channels']:
                    self.channels[channel['topic']] = channel
            elif op == 'unadvertise':
                gone = set(message['channelIds'])
                for name in [t for t, c in self.channels.items() if c['id'] in gone]:
                    del self.channels[name]
                    self._subscription_of_topic.pop(name, None)
            return
        if frame[0] == _MESSAGE_DATA:  # op, subscription id, log time, payload
            subscription, log_time = struct.unpack_from('<IQ', frame, 1)
            topic = self._topic_of_subscription.get(subscription)
            if topic is not None and self._subscription_of_topic.get(topic) == subscription:
                self.messages[topic].append(LiveMessage(log_time, bytes(frame[13:])))
        elif frame[0] == _TIME:
            self.times.append(struct.unpack_from('<Q', frame, 1)[0])

    def close(self) -> None:
        """Disconnect (again: nothing happens)."""
        self._stack.close()

    def __enter__(self) -> 'LiveViewClient':
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        return f'LiveViewClient({self.url!r}, channels={len(self.channels)})'
