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
follow the replayed time. A recording is data from anywhere: the file is read
by :mod:`r2d2_sim.recording.reader`, which imports message types only from
installed ROS interface packages, bounds what it decompresses, and recovers
every complete message of a file whose recorder never closed it. A topic
that cannot be played (an unknown type, a bad name, an impossible QoS) is
skipped with one line. Needs the ``mcap`` package's dependencies
(``pip install "r2d2_sim[foxglove]"``).
"""

import argparse
import enum
import sys
import threading
import time
from typing import Any, Dict, NamedTuple, Optional, Sequence, Type, TYPE_CHECKING

from r2d2_sim.apps.cli import non_ros_args, number_in, raise_if_stopped, stop_on_signals
from r2d2_sim.recording.message_definitions import UnknownMessageType
from r2d2_sim.recording.reader import (
    message_class, RecordedChannel, RecordingError, RecordingFile)

if TYPE_CHECKING:  # rclpy is imported once the file has been read
    from rclpy.node import Node
    from rclpy.publisher import Publisher
    from rclpy.qos import QoSProfile

NODE_NAME = 'replay'
# Exit status after Ctrl-C or SIGTERM, as a shell reports a process ended by SIGINT.
EXIT_INTERRUPTED = 130
# Wall-clock seconds the last messages get to be acknowledged before exit.
ACK_WAIT_S = 1.0
# rosbag2's publisher depth for a recording that gives none.
DEFAULT_DEPTH = 10
# The most messages a latched topic's replay keeps for late subscribers (a robot's
# /tf_static each, in a fleet's recording).
MAX_LATCHED_DEPTH = 1000
# The largest depth rmw takes (a 32-bit int); 2**40 made rclpy raise a TypeError.
MAX_DEPTH = 2**31 - 1
# Durations that mean "infinite" in recordings: rmw's RMW_DURATION_INFINITE,
# and what Foxy-era Fast DDS and Connext reported.
_INFINITE = {(9223372036, 854775807), (2147483647, 4294967295), (2147483647, 2147483647)}
_MAX_DURATION_NS = 2**63 - 1
# rosbag2 writes a few hundred bytes of offered_qos_profiles per topic.
_MAX_QOS_TEXT = 64 * 1024
_GIB = 2**30
# Topics a "nothing to replay" line names (a file may have thousands).
MAX_REASONS = 3
# --rate: 1e-12 made a wait between two messages longer than the platform can sleep.
RATE_RANGE = (1.0e-6, 1.0e6)
# --max-gib: 1e300 GiB is no number of bytes (int(inf)).
MAX_GIB_RANGE = (1.0e-6, 1.0e6)  # from about a kilobyte
# The longest single wait for a message's time (wall s); threading's waits refuse more than
# threading.TIMEOUT_MAX (292 years), which a file's log times (uint64 ns) may be apart.
MAX_WAIT_S = 3600.0


class Topic(NamedTuple):
    """A recorded topic: its ROS type, message class and the QoS to publish it with."""

    name: str
    type_name: str
    message_class: type
    qos: 'QoSProfile'


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser (ROS arguments are removed before it runs)."""
    parser = argparse.ArgumentParser(
        prog=NODE_NAME,
        description='Publish the messages of an MCAP recording (rosbag2 or r2d2_sim) again, '
                    'with their recorded QoS, paced by their log times.')
    parser.add_argument('file', help='the .mcap file')
    parser.add_argument('--rate', type=number_in(*RATE_RANGE), default=1.0, metavar='X',
                        help='playback speed, a multiple of the recorded pace, '
                             f'{RATE_RANGE[0]:g} to {RATE_RANGE[1]:g} (default 1)')
    parser.add_argument('--loop', action='store_true',
                        help='start again at the end, until Ctrl-C')
    parser.add_argument('--max-gib', type=number_in(*MAX_GIB_RANGE, 'GiB'), default=None,
                        metavar='G',
                        help='refuse a file that decompresses to more than G GiB in one pass, '
                             f'{MAX_GIB_RANGE[0]:g} to {MAX_GIB_RANGE[1]:g} (default: the '
                             'larger of 1 GiB and 100 times its size)')
    return parser


def qos_from_metadata(text: Optional[str]) -> 'QoSProfile':
    """
    Return the rclpy QoSProfile for a topic from its ``offered_qos_profiles`` YAML.

    The first recorded profile is used, its policies named (Jazzy's rosbag2,
    ours) or numbered as rmw numbers them (rosbag2 of Humble and Iron). Unknown
    history or depth 0 (what rosbag2 records from the graph) become keep-last 10, as in
    ``ros2 bag play``; infinite durations are left unspecified. No metadata:
    reliable, volatile, keep-last 10. Raises ValueError, saying why, for
    metadata that is not such a profile (a depth of 2**40, a duration past
    rcl's int64 nanoseconds, text that is not YAML).
    """
    import yaml
    from rclpy.duration import Duration
    from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,
                           ReliabilityPolicy)
    qos = QoSProfile(depth=DEFAULT_DEPTH)
    if text and len(text) > _MAX_QOS_TEXT:
        raise ValueError(f'{len(text)} characters of offered_qos_profiles, more than '
                         f'{_MAX_QOS_TEXT}')
    try:
        profiles = yaml.safe_load(text) if text else None
    except yaml.YAMLError as exc:
        raise ValueError(f'offered_qos_profiles is not YAML ({type(exc).__name__})') from None
    if not profiles:
        return qos
    if not isinstance(profiles, list) or not isinstance(profiles[0], dict):
        raise ValueError('offered_qos_profiles is not a list of QoS profiles')
    profile = profiles[0]

    def policy(policies: Type[enum.Enum], key: str) -> Optional[enum.Enum]:
        value = profile.get(key)
        chosen = None
        if isinstance(value, str) and value.upper() in policies.__members__:
            chosen = policies[value.upper()]
        elif isinstance(value, int) and not isinstance(value, bool):
            # rosbag2 before Jazzy writes rmw's enum numbers (reliability: 1), which
            # rclpy's policies share.
            chosen = next((p for p in policies if p.value == value), None)
        if chosen is None or chosen.name in ('UNKNOWN', 'SYSTEM_DEFAULT'):
            return None
        return chosen

    def integer(value: Any, key: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f'{key} {str(value)[:40]!r} is not an integer')
        return value

    def duration(key: str) -> Optional[Duration]:
        value = profile.get(key) or {}
        if not isinstance(value, dict):
            raise ValueError(f'{key} is not a duration')
        sec = integer(value.get('sec', 0), f'{key}.sec')
        nsec = integer(value.get('nsec', 0), f'{key}.nsec')
        if (sec, nsec) in _INFINITE or (sec, nsec) == (0, 0):
            return None
        if not 0 <= sec * 10**9 + nsec <= _MAX_DURATION_NS or sec < 0 or nsec < 0:
            raise ValueError(f'{key} of {str(sec)[:40]} s {str(nsec)[:40]} ns is out of range')
        return Duration(seconds=sec, nanoseconds=nsec)

    if policy(HistoryPolicy, 'history') is HistoryPolicy.KEEP_ALL:
        qos.history = HistoryPolicy.KEEP_ALL
    else:
        depth = integer(profile.get('depth') or 0, 'depth')
        if not 0 <= depth <= MAX_DEPTH:
            raise ValueError(f'depth {str(depth)[:40]} is out of range 0..{MAX_DEPTH}')
        if depth > 0:
            qos.depth = depth
    for attribute, policies in (('reliability', ReliabilityPolicy),
                                ('durability', DurabilityPolicy),
                                ('liveliness', LivelinessPolicy)):
        chosen = policy(policies, attribute)
        if chosen is not None:
            setattr(qos, attribute, chosen)
    for attribute in ('deadline', 'lifespan', 'liveliness_lease_duration'):
        span = duration(attribute)
        if span is not None:
            setattr(qos, attribute, span)
    qos.avoid_ros_namespace_conventions = bool(profile.get('avoid_ros_namespace_conventions'))
    return qos


class Recording:
    """
    An MCAP file opened for replay: its replayable topics and its messages.

    ``topics`` by channel id; ``skipped``: topic -> why, for the channels that
    cannot be replayed; ``file``: the :class:`RecordingFile` (``cut_short``,
    counts). Raises :class:`RecordingError` for a file with nothing to replay.
    """

    def __init__(self, path: str, max_bytes: Optional[int] = None) -> None:
        self.path = path
        self.file = RecordingFile(path, max_bytes)
        self.topics: Dict[int, Topic] = {}
        self.skipped: Dict[str, str] = {}
        for channel in self.file.channels.values():
            self._add(channel)
        self.message_count = sum(self.file.message_counts.get(c, 0) for c in self.topics)
        if self.file.message_count == 0:
            cut = f', cut short after {self.file.readable_bytes} of its {self.file.size} ' \
                'bytes' if self.file.cut_short else ''
            raise RecordingError(f'{path}: nothing to replay: no complete message{cut}')
        if self.message_count == 0:
            raise RecordingError(nothing_playable(self))

    def _add(self, channel: RecordedChannel) -> None:
        from rclpy.qos import DurabilityPolicy, HistoryPolicy
        if channel.message_encoding != 'cdr':
            self.skipped[channel.topic] = \
                f'encoding {channel.message_encoding[:40]!r}, not cdr'
            return
        if not channel.type_name:
            self.skipped[channel.topic] = 'no ROS type'
            return
        try:
            cls = message_class(channel.type_name)
        except UnknownMessageType as exc:
            self.skipped[channel.topic] = f'unknown type: {exc}'
            return
        try:
            qos = qos_from_metadata(channel.metadata.get('offered_qos_profiles'))
        except ValueError as exc:
            self.skipped[channel.topic] = f'bad offered_qos_profiles: {exc}'
            return
        if qos.durability == DurabilityPolicy.TRANSIENT_LOCAL \
                and qos.history == HistoryPolicy.KEEP_LAST:
            # Several publishers' latched messages on one topic (each robot's /tf_static,
            # depth 1 each) are one channel here, and one publisher replays them: it keeps
            # them all, so a late subscriber gets every robot's, as from the simulator.
            count = self.file.message_counts.get(channel.id, 0)
            qos.depth = max(qos.depth, min(count, MAX_LATCHED_DEPTH))
        self.topics[channel.id] = Topic(channel.topic, channel.type_name, cls, qos)


def _one_line(exc: BaseException) -> str:
    text = ' '.join(str(exc).split())
    return f'{type(exc).__name__}: {text}' if text else type(exc).__name__


def play(recording: Recording, publishers: Dict[int, 'Publisher'], rate: float,
         stop: threading.Event) -> int:
    """
    Publish one pass of the recording, paced by log time over ``rate``; return the count.

    Messages come in file order (recorders write in log-time order); each
    waits for its absolute deadline (no drift), and one logged before the
    message ahead of it goes at once. Raises KeyboardInterrupt when ``stop`` is set.
    """
    count = 0
    start_wall = None
    start_log = 0
    for channel_id, log_time, data in recording.file.messages(publishers):
        if start_wall is None:
            start_wall, start_log = time.monotonic(), log_time
        due = start_wall + (log_time - start_log) * 1e-9 / rate
        while not stop.is_set() and (wait_s := due - time.monotonic()) > 0.0:
            stop.wait(min(wait_s, MAX_WAIT_S))  # in parts: the platform's waits are bounded
        raise_if_stopped(stop)
        publishers[channel_id].publish(data)
        count += 1
    return count


def nothing_playable(recording: Recording) -> str:
    """Return the one line for a file whose messages are all on topics that cannot be played."""
    reasons = [f'{topic!r}: {why}' for topic, why in recording.skipped.items()]
    if len(reasons) > MAX_REASONS:
        reasons[MAX_REASONS:] = [f'and {len(reasons) - MAX_REASONS} more']
    return f'{recording.path}: nothing to replay: no topic can be played ({"; ".join(reasons)})'


def create_publishers(node: 'Node', recording: Recording) -> Dict[int, 'Publisher']:
    """
    Return a publisher per replayable channel, by channel id.

    A topic rclpy refuses (a name that is not a ROS name, a type that clashes
    with another topic's of the same name) is moved to ``recording.skipped``.
    """
    from rclpy.exceptions import NameValidationException
    publishers: Dict[int, Publisher] = {}
    for channel_id, topic in recording.topics.items():
        try:
            publishers[channel_id] = node.create_publisher(
                topic.message_class, topic.name, topic.qos)
        except NameValidationException as exc:  # its text ends with the name and a caret
            recording.skipped[topic.name] = str(exc).splitlines()[0].rstrip(':')
        except Exception as exc:  # rclpy raises assorted types
            recording.skipped[topic.name] = f'cannot publish it: {_one_line(exc)}'
    return publishers


def main(args: Optional[Sequence[str]] = None) -> int:
    """
    Replay a recording; return the exit status.

    0 at the end of the file (also for a file cut short: one line says how
    much of it was recovered), 130 after Ctrl-C or SIGTERM (the signals set
    an event that the pacing waits on), 2 for a bad or refused file, one with
    nothing playable, or bad arguments (one ``replay: error:`` line).
    """
    argv = list(sys.argv if args is None else args)
    stop = stop_on_signals()
    options = build_parser().parse_args(non_ros_args(argv, NODE_NAME))
    max_bytes = None if options.max_gib is None else int(options.max_gib * _GIB)
    try:
        recording = Recording(options.file, max_bytes)
    except RecordingError as exc:
        print(f'{NODE_NAME}: error: {exc}', file=sys.stderr)
        return 2
    if stop.is_set():  # Ctrl-C while the file was read through (about 3 us a message)
        return EXIT_INTERRUPTED
    import rclpy
    from rclpy.duration import Duration
    from rclpy.exceptions import ParameterException
    from r2d2_sim.apps.cli import init_ros
    from r2d2_sim.ros.parameters import rclpy_parameter_problem
    if not init_ros(argv, NODE_NAME):
        return 2
    node = None
    try:
        node = rclpy.create_node(NODE_NAME)
        publishers = create_publishers(node, recording)
        if not publishers:
            print(f'{NODE_NAME}: error: {nothing_playable(recording)}', file=sys.stderr)
            return 2
        for topic, why in recording.skipped.items():
            print(f'{NODE_NAME}: skipping {topic!r}: {why}', file=sys.stderr)
        if recording.file.cut_short:
            print(f'{NODE_NAME}: {recording.file.describe_cut()}', file=sys.stderr)
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
    except ParameterException as exc:  # rclpy's own, such as use_sim_time:=1, as it builds node
        print(f'{NODE_NAME}: error: {rclpy_parameter_problem(exc)}', file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
