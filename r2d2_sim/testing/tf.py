"""
TF for tests: a listener on ``/tf`` and ``/tf_static`` that answers ``lookup_transform``.

tf2_ros is not on PyPI; :class:`TfListener` does what its ``Buffer`` and
``TransformListener`` do for a test, on top of the pure
:class:`~r2d2_sim.model.tf_buffer.TransformBuffer`: it subscribes both topics on a
node (``/tf_static`` transient local, as tf2 does) and adds every transform
to the buffer, taken on demand: the messages wait in the middleware until a
lookup takes them. :class:`~r2d2_sim.testing.sim_process.SimProcess` listens
from its start; the in-process
:class:`~r2d2_sim.testing.harness.SimHarness` from its first lookup (a
subscriber on /tf from the start would cost every lockstep period a
delivery), seeded with the latest /tf its simulator sent, which it knows.
"""

from typing import Any, Callable, List, Optional, Tuple

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from rclpy.subscription import Subscription

from r2d2_sim.model.tf_buffer import (
    from_tf_message, StampedTransform, TransformBuffer, TransformException)
from r2d2_sim.testing.executor import HarnessError, import_interface, MissingInterfaceError
from r2d2_sim.testing.lockstep import TakenOnDemand

__all__ = ['TfListener', 'TransformLookup', 'TF_QOS', 'TF_STATIC_QOS']

# As tf2_ros's TransformListener subscribes.
TF_QOS = QoSProfile(depth=100)
TF_STATIC_QOS = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# Taken on demand, /tf waits in the middleware's history: this many messages, about
# 8 s of a robot publishing at 240 Hz (the buffer keeps 10 s, as tf2's does).
TF_ON_DEMAND_QOS = QoSProfile(depth=2000)
# Refused transforms whose reasons a listener keeps (a looping publisher repeats them).
_REFUSALS_KEPT = 10


class TfListener:
    """
    Fills a :class:`~r2d2_sim.model.tf_buffer.TransformBuffer` (``buffer``) from TF's topics.

    ``topics``: ``/tf`` and ``/tf_static``, or a robot's own (``/robot_a/tf``...).
    :meth:`add_serialized` adds what was sent before it listened.
    The node's executor delivers the messages, or with ``on_demand`` they wait
    in the middleware until :meth:`take`, which reading ``buffer`` does (no
    executor runs them: a lockstep period costs nothing for them);
    ``static_received`` and ``dynamic_received`` count them, ``static_publishers``
    the ``/tf_static`` publishers matched (each latches one message). A
    transform the buffer refuses (a loop, a frame its own parent, NaN) is
    left out and its reason kept in ``refused`` (the first few). Needs tf2_msgs
    (:class:`~r2d2_sim.testing.executor.MissingInterfaceError` without it:
    ``tools/build_interfaces.sh VENV`` builds it for a pip-only venv).
    """

    def __init__(self, node: Node, buffer: Optional[TransformBuffer] = None,
                 topics: Tuple[str, str] = ('/tf', '/tf_static'), *,
                 on_demand: bool = False) -> None:
        TFMessage = import_interface('tf2_msgs.msg', 'lookup_transform and listen_tf').TFMessage
        self._buffer = buffer if buffer is not None else TransformBuffer()
        self._received = [0, 0]  # dynamic, static
        self.refused: List[str] = []
        self.topics = topics
        group = TakenOnDemand() if on_demand else None
        self._subscriptions: Tuple[Subscription, ...] = (
            node.create_subscription(TFMessage, topics[0], self._on_tf,
                                     TF_ON_DEMAND_QOS if on_demand else TF_QOS,
                                     callback_group=group),
            node.create_subscription(TFMessage, topics[1], self._on_tf_static, TF_STATIC_QOS,
                                     callback_group=group))
        self._node = node
        self._on_demand = on_demand

    @property
    def buffer(self) -> TransformBuffer:
        """Return the transform buffer, with everything received so far in it."""
        self.take()
        return self._buffer

    @property
    def dynamic_received(self) -> int:
        """Return how many ``/tf`` messages arrived so far."""
        self.take()
        return self._received[0]

    @property
    def static_received(self) -> int:
        """Return how many ``/tf_static`` messages arrived so far."""
        self.take()
        return self._received[1]

    @property
    def static_publishers(self) -> int:
        """Return how many ``/tf_static`` publishers the listener matched (each latches one)."""
        return self._subscriptions[1].get_publisher_count() if self._subscriptions else 0

    def _on_tf(self, msg: Any) -> None:
        self._add(msg, static=False)
        self._received[0] += 1

    def _on_tf_static(self, msg: Any) -> None:
        self._add(msg, static=True)
        self._received[1] += 1

    def _add(self, msg: Any, static: bool) -> None:
        """Add each transform of a TFMessage; keep why one was refused, and go on."""
        for t in from_tf_message(msg):
            try:
                self._buffer.add(t.frame_id, t.child_frame_id, t.stamp_ns,
                                 t.transform.translation, t.transform.rotation, static)
            except TransformException as exc:
                if len(self.refused) < _REFUSALS_KEPT:
                    self.refused.append(str(exc))

    def add_serialized(self, data: bytes, static: bool = False) -> None:
        """Add a serialized TFMessage as if it had arrived (what was sent before this listened)."""
        from rclpy.serialization import deserialize_message
        from tf2_msgs.msg import TFMessage
        (self._on_tf_static if static else self._on_tf)(deserialize_message(data, TFMessage))

    def close(self) -> None:
        """Destroy both subscriptions (a robot's handle closing with its robot); safe twice."""
        for subscription in self._subscriptions:
            self._node.destroy_subscription(subscription)
        self._subscriptions = ()

    def take(self) -> None:
        """Take what waits in the middleware into the buffer (only ``on_demand``)."""
        if not self._on_demand:
            return
        for subscription, callback in zip(self._subscriptions, (self._on_tf,
                                                                self._on_tf_static)):
            with subscription.handle:
                while True:
                    taken = subscription.handle.take_message(subscription.msg_type, False)
                    if taken is None:
                        break
                    callback(taken[0])


class TransformLookup:
    """
    ``listen_tf`` and ``lookup_transform`` for a harness: a :class:`TfListener` on its node.

    The harness gives ``_tf_node()`` and ``_tf_wait(condition)`` (True once
    it holds, False at its deadline), and may give ``_tf_default_time_ns()``
    for a lookup at time 0 (else tf2's: the latest common time) and
    ``_tf_frozen()`` (True: nothing arrives until the harness steps).
    """

    _tf: Optional[TfListener] = None

    def _tf_node(self) -> Node:
        raise NotImplementedError

    def _tf_wait(self, condition: Callable[[], bool]) -> bool:
        raise NotImplementedError

    def _tf_default_time_ns(self) -> int:
        return 0

    def _tf_frozen(self) -> bool:
        return False

    def _tf_topics(self) -> Tuple[str, str]:
        return '/tf', '/tf_static'

    def _tf_sent_before(self) -> Tuple[bytes, ...]:
        """Return the latest /tf messages sent before the listener started (in-process: known)."""
        return ()

    def listen_tf(self) -> TfListener:
        """Start taking ``/tf`` and ``/tf_static`` into a transform buffer (once); return it."""
        node = self._tf_node()  # HarnessError (one line) once the harness is closed
        if self._tf is None:
            self._tf = TfListener(node, topics=self._tf_topics(), on_demand=True)
            for data in self._tf_sent_before():
                self._tf.add_serialized(data)
        return self._tf

    def _restart_tf(self) -> None:
        """Listen afresh if listening (time went back, or another world): old frames go."""
        if self._tf is not None:
            self._stop_tf()
            self.listen_tf()

    def _stop_tf(self) -> None:
        """Close the listener, if any: its subscriptions must not outlive the robot's handle."""
        if self._tf is not None:
            self._tf.close()
            self._tf = None

    def _listen_tf_from_now(self) -> None:
        """Listen from the harness's start when tf2_msgs is there (a first lookup then works)."""
        try:
            self.listen_tf()
        except MissingInterfaceError:
            pass  # no tf2_msgs: lookup_transform says so when it is used

    def lookup_transform(self, target_frame: str, source_frame: str,
                         time_ns: int = 0) -> StampedTransform:
        """
        Return the transform from ``source_frame`` to ``target_frame`` at ``time_ns``.

        A :class:`~r2d2_sim.model.tf_buffer.StampedTransform` (``frame_id``
        ``target_frame``, ``child_frame_id`` ``source_frame``, ``stamp_ns`` the time
        used, ``transform`` of ``translation`` and ``rotation`` tuples), not a
        geometry_msgs ``TransformStamped``: ``t.transform.translation[0]`` where tf2 has
        ``t.transform.translation.x`` (docs/testing.md builds the message from it).
        Found as tf2's ``Buffer.lookup_transform`` finds it, over what the simulator put
        on ``/tf`` and ``/tf_static`` since the harness started (or, without tf2_msgs
        then, since :meth:`listen_tf`). ``time_ns`` 0 means the latest: in the
        in-process harness the latest state publication's time, so the answer is the
        current state, never one still on its way. Waits by deadline; HarnessError with
        tf2's reason. In the in-process harness an unknown frame fails at once instead,
        once ``/tf_static`` is in: time moves only when it steps (TF that another
        process publishes there would have to be in already). A transform someone
        published that the buffer refused (a loop, a frame its own parent) makes every
        lookup a HarnessError with its reason: the tree is not what its publishers meant.
        """
        listener = self.listen_tf()
        time_ns = time_ns or self._tf_default_time_ns()

        def can_transform() -> bool:
            return listener.buffer.can_transform(target_frame, source_frame, time_ns)
        # In process (frozen), once /tf_static's latched messages are in (each comes a
        # moment after a new listener matches its publisher: one per robot), the buffer
        # holds all it will until the next step: an unknown frame is said then, not at
        # the deadline (10 s of waiting for nothing). Not after the first robot's: a
        # robot spawned later has its own publisher, its message perhaps still on its
        # way (a CI run once said "no c/base_link" so). No static transform: as before.
        frozen = self._tf_frozen()

        def decided() -> bool:
            if can_transform():
                return True
            received = listener.static_received
            return frozen and received > 0 and received >= listener.static_publishers
        if not self._tf_wait(decided) or not can_transform():
            self._raise_refused(listener, target_frame, source_frame)
            try:
                listener.buffer.lookup_transform(target_frame, source_frame, time_ns)
            except TransformException as exc:
                raise HarnessError(f'no transform {source_frame} -> {target_frame}: '
                                   f'{exc}') from None
        self._raise_refused(listener, target_frame, source_frame)
        try:
            return listener.buffer.lookup_transform(target_frame, source_frame, time_ns)
        except TransformException as exc:  # tf2's kinds, as docs/testing.md promises
            raise HarnessError(f'no transform {source_frame} -> {target_frame}: '
                               f'{exc}') from None

    @staticmethod
    def _raise_refused(listener: TfListener, target_frame: str, source_frame: str) -> None:
        """Raise HarnessError (one line) if the listener refused a transform someone published."""
        if listener.refused:
            raise HarnessError(f'no transform {source_frame} -> {target_frame}: TF is broken, '
                               f'a published transform was refused: {listener.refused[0]}')
