"""
``replay``: publish a recorded MCAP file again, with each topic's QoS, at the recorded pace.

For users without ``ros2 bag play``::

    replay run.mcap [--rate 2] [--loop] [--ros-args -r /scan:=/scan_replayed]

The bytes in the file are published as they are (``publish(bytes)``), so
nothing is decoded. Each topic gets the QoS its recorder wrote in the
``offered_qos_profiles`` channel metadata: ``/tf_static`` and
``/robot_description`` replay latched. The pace follows the log times,
which :class:`~r2d2_sim.recording.sink.FoxgloveSink` sets to simulated time;
the recording carries ``/clock``, so subscribers with ``use_sim_time``
follow the replayed time. Needs the ``mcap`` package
(``pip install "r2d2_sim[foxglove]"``).
"""

import argparse
import importlib
import sys
import time
from typing import Dict, Iterator, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.apps.cli import non_ros_args, positive_number, raise_if_stopped, stop_on_signals

NODE_NAME = 'replay'
# Exit status after Ctrl-C or SIGTERM, as a shell reports a process ended by SIGINT.
EXIT_INTERRUPTED = 130
# Wall-clock seconds the last messages get to be acknowledged before exit.
ACK_WAIT_S = 1.0
# rosbag2's publisher depth for a recording that gives none.
DEFAULT_DEPTH = 10
# Durations that mean "infinite" in recordings: rmw's RMW_DURATION_INFINITE,
# and what Foxy-era Fast DDS and Connext reported.
_INFINITE = {(9223372036, 854775807), (2147483647, 4294967295), (2147483647, 2147483647)}
# The first and last 8 bytes of an MCAP file.
_MCAP_MAGIC = b'\x89MCAP0\r\n'


class RecordingError(Exception):
    """The file cannot be replayed (the message is one line for the user)."""


class Topic(NamedTuple):
    """A recorded topic: its ROS type, message class and the QoS to publish it with."""

    name: str
    type_name: str
    message_class: type
    qos: object


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser (ROS arguments are removed before it runs)."""
    parser = argparse.ArgumentParser(
        prog=NODE_NAME,
        description='Publish the messages of an MCAP recording (rosbag2 or r2d2_sim) again, '
                    'with their recorded QoS, paced by their log times.')
    parser.add_argument('file', help='the .mcap file')
    parser.add_argument('--rate', type=positive_number, default=1.0, metavar='X',
                        help='playback speed, a multiple of the recorded pace (default 1)')
    parser.add_argument('--loop', action='store_true',
                        help='start again at the end, until Ctrl-C')
    return parser


def message_class(type_name: str) -> type:
    """Import the rclpy class of ``pkg/msg/Type`` (or ``pkg/Type``); ImportError if missing."""
    parts = type_name.split('/')
    if len(parts) == 2:
        parts.insert(1, 'msg')
    if len(parts) != 3 or not all(part.isidentifier() for part in parts):
        raise ImportError(f'{type_name!r} is not a ROS message type name')
    package, namespace, name = parts
    module = importlib.import_module(f'{package}.{namespace}')
    try:
        return getattr(module, name)
    except AttributeError:
        raise ImportError(f'{package}.{namespace} has no {name}') from None


def qos_from_metadata(text: Optional[str]):
    """
    Return the rclpy QoSProfile for a topic from its ``offered_qos_profiles`` YAML.

    The first recorded profile is used. Unknown history or depth 0 (what
    rosbag2 records from the graph) become keep-last 10, as in
    ``ros2 bag play``; infinite durations are left unspecified. No metadata:
    reliable, volatile, keep-last 10.
    """
    import yaml
    from rclpy.duration import Duration
    from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,
                           ReliabilityPolicy)
    qos = QoSProfile(depth=DEFAULT_DEPTH)
    profiles = yaml.safe_load(text) if text else None
    if not profiles:
        return qos
    profile = profiles[0]

    def policy(enum, key):
        value = profile.get(key)
        if isinstance(value, str) and value.upper() in enum.__members__ and \
                value.upper() not in ('UNKNOWN', 'SYSTEM_DEFAULT'):
            return enum[value.upper()]
        return None

    def duration(key):
        value = profile.get(key) or {}
        sec, nsec = int(value.get('sec', 0)), int(value.get('nsec', 0))
        if (sec, nsec) in _INFINITE or (sec, nsec) == (0, 0):
            return None
        return Duration(seconds=sec, nanoseconds=nsec)

    if policy(HistoryPolicy, 'history') is HistoryPolicy.KEEP_ALL:
        qos.history = HistoryPolicy.KEEP_ALL
    elif int(profile.get('depth') or 0) > 0:
        qos.depth = int(profile['depth'])
    for attribute, enum in (('reliability', ReliabilityPolicy),
                            ('durability', DurabilityPolicy),
                            ('liveliness', LivelinessPolicy)):
        value = policy(enum, attribute)
        if value is not None:
            setattr(qos, attribute, value)
    for attribute in ('deadline', 'lifespan', 'liveliness_lease_duration'):
        value = duration(attribute)
        if value is not None:
            setattr(qos, attribute, value)
    qos.avoid_ros_namespace_conventions = bool(profile.get('avoid_ros_namespace_conventions'))
    return qos


class Recording:
    """An MCAP file opened for replay: its replayable topics and its messages by log time."""

    def __init__(self, path: str) -> None:
        try:
            from mcap.reader import make_reader
        except ImportError:
            raise RecordingError('reading MCAP needs the mcap package: '
                                 'pip install "r2d2_sim[foxglove]"') from None
        self.path = path
        self._make_reader = make_reader
        self.topics: Dict[int, Topic] = {}     # by channel id
        self.skipped: Dict[str, str] = {}      # topic -> why
        self.message_count = 0
        try:
            with open(path, 'rb') as stream:
                if _unfinished(stream):
                    raise RecordingError(
                        f'{path} was not finished: its recorder stopped before closing it '
                        '(killed?), and the summary at its end is missing')
                summary = make_reader(stream).get_summary()
        except OSError as exc:
            raise RecordingError(f'cannot open {path}: {exc.strerror or exc}') from None
        except RecordingError:
            raise
        except Exception as exc:  # mcap raises assorted types for a bad file
            raise RecordingError(f'{path} is not a readable MCAP file: {_one_line(exc)}') from None
        if summary is None:
            raise RecordingError(f'{path} has no summary section: replay needs one')
        self.message_count = summary.statistics.message_count if summary.statistics else 0
        for channel_id, channel in summary.channels.items():
            schema = summary.schemas.get(channel.schema_id)
            self._add(channel_id, channel, schema)
        if not self.topics:
            reasons = '; '.join(f'{t}: {why}' for t, why in self.skipped.items()) or 'no topics'
            raise RecordingError(f'{path}: nothing to replay ({reasons})')

    def _add(self, channel_id, channel, schema) -> None:
        if channel.message_encoding != 'cdr':
            self.skipped[channel.topic] = f'encoding {channel.message_encoding!r}, not cdr'
            return
        if schema is None or not schema.name:
            self.skipped[channel.topic] = 'no ROS type'
            return
        try:
            cls = message_class(schema.name)
        except ImportError as exc:
            self.skipped[channel.topic] = f'cannot import {schema.name} ({exc})'
            return
        try:
            qos = qos_from_metadata(channel.metadata.get('offered_qos_profiles'))
        except Exception as exc:  # YAML errors come as several types
            raise RecordingError(f'{self.path}: {channel.topic}: bad offered_qos_profiles: '
                                 f'{_one_line(exc)}') from None
        self.topics[channel_id] = Topic(channel.topic, schema.name, cls, qos)

    def messages(self) -> Iterator[Tuple[int, int, bytes]]:
        """Yield (channel id, log time in ns, bytes) of the replayable topics by log time."""
        try:
            with open(self.path, 'rb') as stream:
                reader = self._make_reader(stream)
                for _, channel, message in reader.iter_messages(log_time_order=True):
                    if channel.id in self.topics:
                        yield channel.id, message.log_time, message.data
        except OSError as exc:
            raise RecordingError(f'cannot read {self.path}: {exc.strerror or exc}') from None
        except RecordingError:
            raise
        except Exception as exc:
            raise RecordingError(f'{self.path}: damaged: {_one_line(exc)}') from None


def _unfinished(stream) -> bool:
    """Return True for an MCAP file that starts like one but lacks the closing magic."""
    head = stream.read(len(_MCAP_MAGIC))
    stream.seek(0, 2)
    size = stream.tell()
    if head != _MCAP_MAGIC or size < 2 * len(_MCAP_MAGIC):
        stream.seek(0)
        return False
    stream.seek(size - len(_MCAP_MAGIC))
    tail = stream.read()
    stream.seek(0)
    return tail != _MCAP_MAGIC


def _one_line(exc: BaseException) -> str:
    text = ' '.join(str(exc).split())
    return f'{type(exc).__name__}: {text}' if text else type(exc).__name__


def play(recording: Recording, publishers: Dict[int, object], rate: float, stop) -> int:
    """
    Publish one pass of the recording, paced by log time over ``rate``; return the count.

    Each message waits for its absolute deadline (no drift); raises
    KeyboardInterrupt when ``stop`` is set.
    """
    count = 0
    start_wall = None
    start_log = 0
    for channel_id, log_time, data in recording.messages():
        if start_wall is None:
            start_wall, start_log = time.monotonic(), log_time
        wait_s = start_wall + (log_time - start_log) * 1e-9 / rate - time.monotonic()
        if wait_s > 0.0:
            stop.wait(wait_s)
        raise_if_stopped(stop)
        publishers[channel_id].publish(data)
        count += 1
    return count


def main(args: Optional[Sequence[str]] = None) -> int:
    """
    Replay a recording; return the exit status.

    0 at the end of the file, 130 after Ctrl-C or SIGTERM (the signals set an
    event that the pacing waits on), 2 for a bad file or bad arguments (one
    ``replay: error:`` line).
    """
    argv = list(sys.argv if args is None else args)
    stop = stop_on_signals()
    options = build_parser().parse_args(non_ros_args(argv, NODE_NAME))
    try:
        recording = Recording(options.file)
    except RecordingError as exc:
        print(f'{NODE_NAME}: error: {exc}', file=sys.stderr)
        return 2
    import rclpy
    from rclpy.duration import Duration
    from r2d2_sim.apps.cli import init_ros
    if not init_ros(argv, NODE_NAME):
        return 2
    node = None
    try:
        node = rclpy.create_node(NODE_NAME)
        publishers = {channel_id: node.create_publisher(t.message_class, t.name, t.qos)
                      for channel_id, t in recording.topics.items()}
        for topic, why in recording.skipped.items():
            print(f'{NODE_NAME}: skipping {topic}: {why}', file=sys.stderr)
        print(f'{NODE_NAME}: playing {len(publishers)} topics of {recording.path} at '
              f'{options.rate:g}x' + (', looping' if options.loop else ''), flush=True)
        while True:
            count = play(recording, publishers, options.rate, stop)
            if not options.loop or count == 0:
                break
        deadline = time.monotonic() + ACK_WAIT_S
        for publisher in publishers.values():
            remaining = max(deadline - time.monotonic(), 0.0)
            publisher.wait_for_all_acked(Duration(nanoseconds=int(remaining * 1e9)))
        print(f'{NODE_NAME}: done, {count} messages', flush=True)
        return 0
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except RecordingError as exc:
        print(f'{NODE_NAME}: error: {exc}', file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
