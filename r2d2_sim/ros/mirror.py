"""
The node's publishers with a second consumer: the same bytes to DDS and to a Foxglove sink.

With ``foxglove_port`` or ``record`` set, :meth:`SimNode.create_publisher
<r2d2_sim.ros.node.SimNode.create_publisher>` hands out a :class:`MirroredPublisher`
instead of rclpy's: every ``publish`` goes to DDS unchanged and, as bytes, to
the sink's channel of that topic (the live view and the MCAP file), stamped
with the simulated time of the step that published it. The outputs do not
know: they publish as always. Pre-serialized messages go on as they are;
typed ones (camera images, ``/tf_static``, ``robot_description``) are
serialized once, and DDS and the sink both get those bytes. Without a sink the node keeps rclpy's
publishers, so mirroring costs nothing when it is off.
"""

from typing import Any, Callable, Dict, List, Optional, Union

from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, QoSProfile
from r2d2_sim.ros.cdr import message_bytes, ros_type_name

from r2d2_sim.recording.channels import SinkChannel
from r2d2_sim.recording.sink import FoxgloveSink
from r2d2_sim.ros.quiet_node import QuietNode
from r2d2_sim.ros.relay import OutputRelay, RelayedPublisher
from r2d2_sim.sim.settings.config import SimConfig

__all__ = ['MirroredPublisher', 'ros_type_name', 'mirror', 'MirroringNode', 'start_sink',
           'sink_spec', 'say_sink', 'demand']


class MirroredPublisher:
    """An rclpy publisher whose messages also go, as bytes, to a sink channel; else the same."""

    def __init__(self, publisher: Union[Publisher, RelayedPublisher], msg_type: type,
                 channel: SinkChannel,
                 time_ns: Callable[[], int]) -> None:
        self.publisher = publisher
        # The publisher's own msg_type is typed by rclpy as a TypeVar of no generic class.
        self.msg_type = msg_type
        self.channel = channel
        self._time_ns = time_ns

    def publish(self, msg: Any) -> None:
        """Publish ``msg`` (a message or its serialized bytes) to DDS and to the sink."""
        # A typed message is serialized once, here, and both get the bytes: a
        # camera image (230-300 kB) is not serialized a second time by rclpy.
        data = message_bytes(msg, self.msg_type)
        self.publisher.publish(data)
        self.channel.log(data, self._time_ns())

    def release(self) -> None:
        """Stop feeding the sink: the publisher's node is going (a deleted robot's)."""
        self.channel.release()

    def __getattr__(self, name: str) -> Any:
        # Everything else (topic_name, get_subscription_count, destroy...) is the publisher's.
        return getattr(self.publisher, name)


def _always() -> int:
    return 1


def demand(publisher: object) -> Callable[[], int]:
    """
    Return a cheap question for an output: whether anyone takes what ``publisher`` publishes.

    The answer is a count, 0 when nobody does: an rclpy publisher's matched
    subscriptions, read from the middleware (about 0.24 us; a message built
    and published to nobody costs 5-15 us). A mirrored publisher adds its
    sink's channel (:meth:`SinkChannel.taken
    <r2d2_sim.recording.channels.SinkChannel.taken>`): the recording takes
    every message, the live view those of a topic a viewer subscribes to.
    These always answer 1: anything that is not an rclpy publisher (a test's
    recorder), and a latched (transient-local) publisher, whose late joiners
    get what it published before. A subscription a publisher has not matched
    yet would not get a message published now either (Fast DDS counts a match
    as it adds the reader), so asking changes what nobody receives only.
    """
    if isinstance(publisher, MirroredPublisher):
        over_dds = demand(publisher.publisher)
        if over_dds is _always:
            return _always
        channel = publisher.channel  # its taken() is bound again when a sink stops
        return lambda: over_dds() or channel.taken()
    if isinstance(publisher, RelayedPublisher):  # the outputs process's count (relay.py)
        if publisher.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL:
            return _always
        return publisher.subscription_counter()
    if not isinstance(publisher, Publisher):
        return _always
    if publisher.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL:
        return _always  # a late joiner gets what was published before it came
    # The handle's own method: rclpy's wrapper takes a lock first, three times the cost.
    return publisher.handle.get_subscription_count


def mirror(publisher: Union[Publisher, RelayedPublisher], msg_type: type, sink: FoxgloveSink,
           time_ns: Callable[[], int]) -> MirroredPublisher:
    """Register ``publisher``'s topic with ``sink`` and return the mirrored publisher."""
    channel = sink.channel(publisher.topic_name, ros_type_name(msg_type),
                           publisher.qos_profile)
    return MirroredPublisher(publisher, msg_type, channel, time_ns)


def start_sink(config: SimConfig, name: str,
               logger: RcutilsLogger) -> Optional[FoxgloveSink]:
    """
    Start the live view and the recording a SimConfig asks for (None: neither); say where.

    ``name`` is the server's name viewers show; ``logger`` (the node's) gets
    one info line for each (the view's address, the recording's file), and
    later what goes wrong while they run: a recording stopped by a full disk,
    the live view's listener gone, foxglove-sdk's own lines (throttled), so
    ROS says them on ``/rosout``. SinkError when either cannot start.
    """
    spec = sink_spec(config, name)
    if spec is None:
        return None
    sink = FoxgloveSink(**spec, warn=logger.warning, error=logger.error)
    say_sink(config, sink.url, logger)
    return sink


def sink_spec(config: SimConfig, name: str) -> Optional[Dict[str, Any]]:
    """Return the sink a SimConfig asks for (FoxgloveSink's keyword arguments), None for none."""
    port = config.foxglove_port or None
    record = config.record or None
    if port is None and record is None:
        return None
    return {'port': port, 'host': config.foxglove_host, 'record_path': record, 'name': name}


def say_sink(config: SimConfig, url: Optional[str], logger: RcutilsLogger) -> None:
    """Log where the live view serves (``url``) and where the recording goes, if anywhere."""
    if url is not None:
        logger.info(f'Foxglove live view at {url}')
    if config.record:
        logger.info(f'recording every output to {config.record}')


class MirroringNode(QuietNode):
    """
    A node whose publishers also feed ``sink`` (the live view and recording), if set.

    A :class:`~r2d2_sim.ros.quiet_node.QuietNode`: no default QoS event handlers.

    Subclasses set ``sink`` after ``Node.__init__`` (rclpy's own publishers,
    made there, stay unmirrored) and give the simulated time of what they
    publish with :meth:`sink_time_ns`. With ``relay`` set (``outputs_process``)
    its publishers are relayed (:class:`~r2d2_sim.ros.relay.RelayedPublisher`): the
    outputs process publishes (on the topic this node resolves) what they are
    given; they are listed in :attr:`relayed_publishers`, not rclpy's ``publishers``.
    """

    sink: Optional[FoxgloveSink] = None
    relay: Optional[OutputRelay] = None

    def sink_time_ns(self) -> int:
        """Return the simulated time (ns) that mirrored messages are logged at."""
        return 0

    def sink_status(self) -> Dict[str, Optional[str]]:
        """
        Return where the live view serves (``live_view``) and the recording goes (``recording``).

        Empty with neither; with ``outputs_process`` the outputs process holds them.
        """
        if self.sink is not None:
            return {'live_view': self.sink.url, 'recording': self.sink.record_path}
        relay = self.relay
        if relay is not None and (relay.sink_live or relay.sink_record_path is not None):
            return {'live_view': relay.sink_url, 'recording': relay.sink_record_path}
        return {}

    @property
    def relayed_publishers(self) -> List[RelayedPublisher]:
        """Return the publishers the outputs process holds for this node (none without one)."""
        return list(self.__dict__.get('_relayed', []))

    def all_publishers(self) -> list:
        """Return rclpy's publishers of this node and those the outputs process holds for it."""
        return list(self.publishers) + self.relayed_publishers

    def create_publisher(  # type: ignore[override]  # a stand-in for rclpy's Publisher
            self, msg_type: type, topic: str, qos_profile: Union[QoSProfile, int],
            **kwargs: Any) -> Union[Publisher, RelayedPublisher, MirroredPublisher]:
        """Create a publisher; with a live view or a recording on, one that feeds them too."""
        publisher: Union[Publisher, RelayedPublisher]
        if self.relay is not None:
            qos = qos_profile if isinstance(qos_profile, QoSProfile) else QoSProfile(
                depth=qos_profile)
            publisher = self.relay.create_publisher(msg_type, self.resolve_topic_name(topic), qos)
            self.__dict__.setdefault('_relayed', []).append(publisher)
        else:
            publisher = super().create_publisher(msg_type, topic, qos_profile, **kwargs)
        if self.sink is None:
            return publisher
        mirrored = mirror(publisher, msg_type, self.sink, self.sink_time_ns)
        self.__dict__.setdefault('_mirrored', []).append(mirrored)
        return mirrored

    def release_mirrors(self) -> None:
        """Release this node's publishers from the sink (before the node is destroyed)."""
        for mirrored in self.__dict__.pop('_mirrored', []):
            mirrored.release()

    def destroy_relayed(self) -> None:
        """Destroy this node's publishers in the outputs process (before the node goes)."""
        for publisher in self.__dict__.pop('_relayed', []):
            publisher.destroy()

    def destroy_publisher(
            self, publisher: Union[Publisher, RelayedPublisher, MirroredPublisher]) -> bool:
        """Destroy a publisher: rclpy's, relayed, or mirrored (first released from the sink)."""
        inner = publisher.publisher if isinstance(publisher, MirroredPublisher) else publisher
        mirrors = self.__dict__.get('_mirrored', [])
        for mirrored in [m for m in mirrors if m.publisher is inner]:
            mirrored.release()
            mirrors.remove(mirrored)
        if isinstance(inner, RelayedPublisher):
            relayed = self.__dict__.get('_relayed', [])
            if inner in relayed:
                relayed.remove(inner)
            inner.destroy()
            return True
        return super().destroy_publisher(inner)
