"""A Foxglove WebSocket client for tests: what the app does, minus the drawing."""

from collections import defaultdict
from contextlib import ExitStack
import json
import struct
import time

from websockets.sync.client import connect

from r2d2_sim.recording.sink import SUBPROTOCOL


class Viewer:
    """A Foxglove WebSocket client: what the app does, minus the drawing."""

    def __init__(self, port: int) -> None:
        self._stack = ExitStack()
        self.ws = self._stack.enter_context(connect(
            f'ws://127.0.0.1:{port}', subprotocols=[SUBPROTOCOL], max_size=None,
            open_timeout=10))
        self.server_info = None
        self.channels = {}               # topic -> the advertised channel
        self.messages = defaultdict(list)  # topic -> [(log time, payload)]
        self.times = []
        self._topic_of_subscription = {}

    def pump(self, condition, timeout_s: float = 10.0) -> bool:
        """Read what the server sends until ``condition()`` holds or the deadline passes."""
        deadline = time.monotonic() + timeout_s
        while not condition():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            try:
                frame = self.ws.recv(timeout=min(remaining, 0.1))
            except TimeoutError:
                continue
            self._take(frame)
        return True

    def _take(self, frame) -> None:
        if isinstance(frame, str):
            message = json.loads(frame)
            if message['op'] == 'serverInfo':
                self.server_info = message
            elif message['op'] == 'advertise':
                for channel in message['channels']:
                    self.channels[channel['topic']] = channel
            return
        if frame[0] == 1:  # MessageData: op, subscription id, log time, payload
            subscription, log_time = struct.unpack_from('<IQ', frame, 1)
            self.messages[self._topic_of_subscription[subscription]].append(
                (log_time, bytes(frame[13:])))
        elif frame[0] == 2:  # Time
            self.times.append(struct.unpack_from('<Q', frame, 1)[0])

    def subscribe(self, topics) -> None:
        """Subscribe to advertised topics (one request, as the app does)."""
        subscriptions = []
        for topic in topics:
            subscription = len(self._topic_of_subscription) + 1
            self._topic_of_subscription[subscription] = topic
            subscriptions.append({'id': subscription, 'channelId': self.channels[topic]['id']})
        self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': subscriptions}))

    def close(self) -> None:
        """Disconnect."""
        self._stack.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()
