"""
TF for tests: a listener on ``/tf`` and ``/tf_static`` that answers ``lookup_transform``.

tf2_ros is not on PyPI; :class:`TfListener` does what its ``Buffer`` and
``TransformListener`` do for a test, on top of the pure
:class:`~r2d2_sim.model.tf_buffer.TransformBuffer`: it subscribes both topics on a
node (``/tf_static`` transient local, as tf2 does) and adds every transform
to the buffer. The harnesses make one on first use
(:meth:`SimHarness.lookup_transform <r2d2_sim.testing.harness.SimHarness.lookup_transform>`,
:meth:`SimProcess.lookup_transform <r2d2_sim.testing.sim_process.SimProcess.lookup_transform>`).
"""

from typing import Callable, Optional, Tuple

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile

from r2d2_sim.testing.executor import HarnessError
from r2d2_sim.model.tf_buffer import StampedTransform, TransformBuffer, TransformException

__all__ = ['TfListener', 'TransformLookup', 'TF_QOS', 'TF_STATIC_QOS']

# As tf2_ros's TransformListener subscribes.
TF_QOS = QoSProfile(depth=100)
TF_STATIC_QOS = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class TfListener:
    """
    Fills a :class:`~r2d2_sim.model.tf_buffer.TransformBuffer` (``buffer``) from TF's topics.

    ``topics``: ``/tf`` and ``/tf_static``, or a robot's own (``/robot_a/tf``...).
    The node's executor delivers the messages; ``static_received`` and
    ``dynamic_received`` count them. Needs tf2_msgs (ImportError without it:
    ``tools/build_tf2_msgs.sh`` builds it for a pip-only venv).
    """

    def __init__(self, node: Node, buffer: TransformBuffer = None,
                 topics: Tuple[str, str] = ('/tf', '/tf_static')) -> None:
        from tf2_msgs.msg import TFMessage
        self.buffer = buffer if buffer is not None else TransformBuffer()
        self.static_received = 0
        self.dynamic_received = 0
        self.topics = topics
        node.create_subscription(TFMessage, topics[0], self._on_tf, TF_QOS)
        node.create_subscription(TFMessage, topics[1], self._on_tf_static, TF_STATIC_QOS)

    def _on_tf(self, msg) -> None:
        self.buffer.add_tf_message(msg, static=False)
        self.dynamic_received += 1

    def _on_tf_static(self, msg) -> None:
        self.buffer.add_tf_message(msg, static=True)
        self.static_received += 1


class TransformLookup:
    """
    ``listen_tf`` and ``lookup_transform`` for a harness: a :class:`TfListener` on its node.

    The harness gives ``_tf_node()`` and ``_tf_wait(condition)`` (True once
    it holds, False at its deadline), and may give ``_tf_default_time_ns()``
    for a lookup at time 0 (else tf2's: the latest common time).
    """

    _tf: Optional[TfListener] = None

    def _tf_node(self) -> Node:
        raise NotImplementedError

    def _tf_wait(self, condition: Callable[[], bool]) -> bool:
        raise NotImplementedError

    def _tf_default_time_ns(self) -> int:
        return 0

    def _tf_topics(self) -> Tuple[str, str]:
        return '/tf', '/tf_static'

    def listen_tf(self) -> TfListener:
        """Start taking ``/tf`` and ``/tf_static`` into a transform buffer (once); return it."""
        if self._tf is None:
            self._tf = TfListener(self._tf_node(), topics=self._tf_topics())
        return self._tf

    def lookup_transform(self, target_frame: str, source_frame: str,
                         time_ns: int = 0) -> StampedTransform:
        """
        Return the transform from ``source_frame`` to ``target_frame`` at ``time_ns``.

        As tf2's ``Buffer.lookup_transform``, over what the simulator put on
        ``/tf`` and ``/tf_static`` since :meth:`listen_tf` (called by the
        first lookup: advance once after it for /tf to arrive). ``time_ns``
        0 means the latest: in the in-process harness the latest state
        publication's time, so the answer is the current state, never one
        still on its way. Waits by deadline; HarnessError with tf2's reason.
        """
        buffer = self.listen_tf().buffer
        time_ns = time_ns or self._tf_default_time_ns()
        if not self._tf_wait(lambda: buffer.can_transform(target_frame, source_frame, time_ns)):
            try:
                buffer.lookup_transform(target_frame, source_frame, time_ns)
            except TransformException as exc:
                raise HarnessError(f'no transform {source_frame} -> {target_frame}: {exc} '
                                   '(the harness listens from its first lookup_transform '
                                   'or listen_tf(): advance() after it)') from None
        return buffer.lookup_transform(target_frame, source_frame, time_ns)
