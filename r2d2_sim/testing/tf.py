"""
TF for tests: a listener on ``/tf`` and ``/tf_static`` that answers ``lookup_transform``.

tf2_ros is not on PyPI; :class:`TfListener` does what its ``Buffer`` and
``TransformListener`` do for a test, on top of the pure
:class:`~r2d2_sim.tf_buffer.TransformBuffer`: it subscribes both topics on a
node (``/tf_static`` transient local, as tf2 does) and adds every transform
to the buffer. The harnesses make one on first use
(:meth:`SimHarness.lookup_transform <r2d2_sim.testing.harness.SimHarness.lookup_transform>`,
:meth:`SimProcess.lookup_transform <r2d2_sim.testing.sim_process.SimProcess.lookup_transform>`).
"""

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile

from r2d2_sim.tf_buffer import TransformBuffer

__all__ = ['TfListener', 'TF_QOS', 'TF_STATIC_QOS']

# As tf2_ros's TransformListener subscribes.
TF_QOS = QoSProfile(depth=100)
TF_STATIC_QOS = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class TfListener:
    """
    Fills a :class:`~r2d2_sim.tf_buffer.TransformBuffer` (``buffer``) from the two TF topics.

    The node's executor delivers the messages; ``static_received`` and
    ``dynamic_received`` count them. Needs tf2_msgs (ImportError without it:
    ``tools/build_tf2_msgs.sh`` builds it for a pip-only venv).
    """

    def __init__(self, node: Node, buffer: TransformBuffer = None) -> None:
        from tf2_msgs.msg import TFMessage
        self.buffer = buffer if buffer is not None else TransformBuffer()
        self.static_received = 0
        self.dynamic_received = 0
        node.create_subscription(TFMessage, '/tf', self._on_tf, TF_QOS)
        node.create_subscription(TFMessage, '/tf_static', self._on_tf_static, TF_STATIC_QOS)

    def _on_tf(self, msg) -> None:
        self.buffer.add_tf_message(msg, static=False)
        self.dynamic_received += 1

    def _on_tf_static(self, msg) -> None:
        self.buffer.add_tf_message(msg, static=True)
        self.static_received += 1
