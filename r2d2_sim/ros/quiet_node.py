"""
A node whose own publishers and subscriptions carry no QoS event handlers.

rclpy gives every publisher and subscription two event handlers by default
(incompatible QoS, incompatible type: each logs a warning), and an executor
adds both to the wait set on every wait: the simulator's node alone brought
22 of the 45 waitables a lockstep harness gathered per wait. The warnings
come from both ends of a mismatch, so the peer (a user's node, ``ros2 topic
echo``) still says it; ``cmd_vel`` publishers of the wrong type are named by
the node's own graph check. Explicit ``event_callbacks`` are kept as given.
"""

from typing import Any, Callable, Union

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription

__all__ = ['QuietNode', 'NO_TYPE_DESCRIPTION_SERVICE']

# For a node nobody asks about (the standard's, a harness's): no
# ~/get_type_description service, one entity fewer in every wait set.
NO_TYPE_DESCRIPTION_SERVICE = Parameter('start_type_description_service', value=False)


class QuietNode(Node):
    """An rclpy Node whose publishers and subscriptions have no default event handlers."""

    def create_publisher(self, msg_type: type, topic: str, qos_profile: Union[QoSProfile, int],
                         **kwargs: Any) -> Publisher:
        """Create a publisher without the default QoS event handlers (see the module)."""
        if kwargs.get('event_callbacks') is None:
            kwargs['event_callbacks'] = PublisherEventCallbacks(use_default_callbacks=False)
        return super().create_publisher(msg_type, topic, qos_profile, **kwargs)

    def create_subscription(self, msg_type: type, topic: str, callback: Callable[[Any], None],
                            qos_profile: Union[QoSProfile, int],
                            **kwargs: Any) -> Subscription:
        """Create a subscription without the default QoS event handlers (see the module)."""
        if kwargs.get('event_callbacks') is None:
            kwargs['event_callbacks'] = SubscriptionEventCallbacks(use_default_callbacks=False)
        return super().create_subscription(msg_type, topic, callback, qos_profile, **kwargs)
