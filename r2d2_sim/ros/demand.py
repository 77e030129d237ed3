"""
Whether anyone takes what a publisher publishes: outputs nobody takes are not built.

A message published with no subscriber matched goes nowhere: every output of
the node is volatile (``/tf_static`` and ``robot_description``, which keep
theirs for late joiners, are published once and always), so a late
subscriber never sees one published before it matched. Building it costs
the node's step (a robot's joint states, odometry, ground truth and ``/tf``
are about 50 us of every step at 240 Hz), and nothing else changes with it:
the measurements, and so every random stream, are the core's and run as
always. The sink of the live view and the recording takes every message of
a mirrored publisher.
"""

from typing import Any

from rclpy.publisher import Publisher

__all__ = ['taken']


def taken(publisher: Any) -> bool:
    """Return True when a subscriber (or, mirrored, the sink) takes what ``publisher`` sends."""
    if type(publisher) is Publisher:
        return publisher.get_subscription_count() > 0
    return publisher.taken()
