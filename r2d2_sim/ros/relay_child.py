"""
The outputs process: publishes, in order, the bytes a simulator's physics thread handed over.

Started by :class:`r2d2_sim.ros.relay.OutputRelay` (never by hand): it reads
frames from an inherited pipe, makes and destroys the publishers they name,
publishes each message's bytes, writes a frame's number back when the frame
asks, and keeps the matched subscriptions of every publisher in the shared
counts (its executor thread serves the matched events). With ``--sink`` it
also holds the simulator's live view and recording: it opens them first and
reports (their address, or the one line saying why not, and then status 2),
logs every message it publishes to them at the simulated time the stream
gives (through a :class:`~r2d2_sim.recording.feeder.SinkFeeder`: the
publishing never waits for the disk), and closes them, finishing the MCAP
file, when the pipe closes. It ends, with status 0, when the pipe closes;
SIGTERM ends it at once (status 143), and a child that records then drops
what the disk has not taken yet and still finishes the file.
"""

import argparse
import json
import mmap
import os
import signal
import sys
import threading
from typing import Any, Callable, Dict, List, Optional, Sequence, TYPE_CHECKING

from r2d2_sim.recording.feeder import SinkFeeder
from r2d2_sim.recording.reader import message_class
from r2d2_sim.ros.relay import (
    ACK, ACK_RECORD, CREATE, DESTROY, FRAME, MAX_PUBLISHERS, qos_from_dict, RECORD, REPORT,
    TIME, TIME_RECORD)

if TYPE_CHECKING:  # typing only: the child imports rclpy once it runs
    from rclpy.node import Node

    from r2d2_sim.recording.channels import SinkChannel
    from r2d2_sim.recording.sink import FoxgloveSink

# How often the executor's thread asks each sink channel whether a viewer takes it (the
# live view also says so at once when a viewer subscribes or unsubscribes).
TAKEN_PERIOD_S = 0.1


def _report(fd: int, report: Dict[str, Any]) -> bool:
    """Write the start report on the acknowledgements; False if the simulator is gone."""
    data = json.dumps(report).encode()
    try:
        os.write(fd, REPORT.pack(len(data)) + data)
    except BrokenPipeError:
        return False
    return True


def open_sink(spec: Dict[str, Any], node: 'Node', acks: int,
              subscriptions_changed: Callable[[], None]) -> 'Optional[FoxgloveSink]':
    """Open the sink ``spec`` describes and report; None (reported) when it cannot open."""
    from r2d2_sim.recording.sink import FoxgloveSink, SinkError
    logger = node.get_logger()
    try:
        sink = FoxgloveSink(**spec, warn=logger.warning, error=logger.error,
                            subscriptions_changed=subscriptions_changed)
    except SinkError as exc:
        _report(acks, {'error': str(exc)})
        return None
    if not _report(acks, {'url': sink.url}):
        sink.close()
        return None
    return sink


def _read_exactly(fd: int, size: int) -> Optional[bytes]:
    """Return ``size`` bytes from ``fd``; None at the end of the stream."""
    chunks = []
    while size:
        chunk = os.read(fd, min(size, 1 << 20))
        if not chunk:
            return None
        chunks.append(chunk)
        size -= len(chunk)
    return b''.join(chunks)


def run(frames: int, acks: int, counts_fd: int, domain_id: int, node_name: str,
        namespace: str, sink_spec: Optional[Dict[str, Any]] = None) -> int:
    """Publish what the pipe ``frames`` brings until it closes; return the exit status."""
    import rclpy
    from rclpy.event_handler import PublisherEventCallbacks
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.publisher import Publisher
    from rclpy.signals import SignalHandlerOptions
    counts_map = mmap.mmap(counts_fd, 8 * MAX_PUBLISHERS)
    shared = memoryview(counts_map).cast('i')
    counts, taken = shared[:MAX_PUBLISHERS], shared[MAX_PUBLISHERS:]
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(node_name, namespace=namespace, context=context,
                             start_parameter_services=False)
    # The sink's channel of each publisher, by index: the feeder's own dict once it exists
    # (the sink that calls refresh_taken is opened before the feeder that fills it).
    channels: Dict[int, Any] = {}
    # The taken map is written from three threads (this one, the executor's, the live
    # view's server or the feeder's): one at a time, each writing what it just read, so
    # an older answer never lands after a newer one. An index destroyed here keeps its
    # channel until the feeder releases it: it is left at 0 until a new one is opened.
    taken_lock = threading.Lock()
    destroyed = set()

    def refresh_taken() -> None:
        """Say, for each sink channel, whether a message logged now goes anywhere."""
        with taken_lock:
            for index, handle in list(channels.items()):
                if index not in destroyed:
                    taken[index] = 1 if handle.taken() else 0

    def opened(index: int, channel: 'SinkChannel') -> None:
        with taken_lock:
            destroyed.discard(index)
            taken[index] = 1 if channel.taken() else 0

    def forget(index: int) -> None:
        with taken_lock:
            destroyed.add(index)
            counts[index] = taken[index] = 0
    closing = threading.Event()  # set once this run is finishing (see _terminate)
    sink = feeder = None
    if sink_spec is not None:
        sink = open_sink(sink_spec, node, acks, refresh_taken)
        if sink is None:
            node.destroy_node()
            rclpy.try_shutdown(context=context)
            return 2
        # The recording's writes on a thread of their own: the topics never wait for the disk.
        feeder = SinkFeeder(sink, node.get_logger().error, opened)
        channels = feeder.channels
        # From now on SIGTERM drops what the disk has not taken yet and still finishes the
        # file (a simulator that could not wait for the rest; see OutputRelay.close).
        signal.signal(signal.SIGTERM, _terminate(feeder, closing))
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    stop = threading.Event()

    def spin() -> None:  # stopped by the event, never by shutting the executor down under it
        while not stop.is_set():
            executor.spin_once(timeout_sec=TAKEN_PERIOD_S)
            try:
                refresh_taken()  # besides the live view's own calls: a channel that changed
            except Exception as exc:  # the matched events must go on
                node.get_logger().error(f'cannot ask the live view what it takes: {exc}')
    spinner = threading.Thread(target=spin, name='matched events', daemon=True)
    spinner.start()
    publishers: Dict[int, Publisher] = {}

    def matched(index: int, made: List[Publisher]) -> Callable[[Any], None]:
        def on_matched(info: Any) -> None:
            # Only the publisher that holds the index now: an index is reused after a
            # destroy, and a late event of the old publisher must not count for the new.
            if made and publishers.get(index) is made[0]:
                counts[index] = info.current_count
        return on_matched

    now_ns = 0  # the simulated time of the messages that follow (TIME records)
    try:
        while True:
            header = _read_exactly(frames, FRAME.size)
            if header is None:
                return 0
            length, sequence, flags = FRAME.unpack(header)
            payload = _read_exactly(frames, length) if length else b''
            if payload is None:
                return 0
            offset = 0
            while offset < length:
                index, size = RECORD.unpack_from(payload, offset)
                offset += RECORD.size
                data = payload[offset:offset + size]
                offset += size
                if index >= 0:
                    publishers[index].publish(data)
                    if feeder is not None:
                        feeder.log(index, data, now_ns)
                elif index == TIME:
                    (now_ns,) = TIME_RECORD.unpack(data)
                    if feeder is not None:  # in order with the messages, as in one process
                        feeder.set_time(now_ns)
                elif index == CREATE:
                    spec = json.loads(data)
                    new, made = spec['index'], []  # type: int, List[Publisher]
                    publisher = node.create_publisher(
                        message_class(spec['type']), spec['topic'], qos_from_dict(spec['qos']),
                        event_callbacks=PublisherEventCallbacks(matched=matched(new, made)))
                    publishers[new] = publisher
                    made.append(publisher)
                    counts[new] = publisher.get_subscription_count()
                    if feeder is not None:
                        feeder.open(new, spec['topic'], spec['type'], publisher.qos_profile)
                elif index == DESTROY:
                    gone = json.loads(data)['index']
                    node.destroy_publisher(publishers.pop(gone))
                    if feeder is not None:
                        feeder.release(gone)
                    forget(gone)
            if flags & ACK:
                try:
                    os.write(acks, ACK_RECORD.pack(sequence))
                except BrokenPipeError:  # the simulator stopped waiting: it is going
                    return 0
    finally:
        closing.set()  # a SIGTERM from here on drops the queue but lets this finish
        stop.set()
        spinner.join()  # within a spin_once's timeout
        if feeder is not None:
            feeder.close()  # every message queued is logged first (unless SIGTERM dropped it)
        if sink is not None:
            sink.close()  # the MCAP file's summary and footer: readable from now on
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def _terminate(feeder: SinkFeeder, closing: threading.Event) -> Callable[[int, Any], None]:
    """
    Return the SIGTERM handler of a child that records: drop the queue, finish the file.

    Once ``closing`` is set (run() is finishing) it only drops the queue.
    """
    def on_term(number: int, frame: Any) -> None:
        feeder.drop()  # what is being written finishes; nothing queued after it
        if not closing.is_set():
            sys.exit(128 + number)  # out of a read of the pipe, into run()'s finally
    return on_term


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Parse the relay's arguments and run; status 0 when the pipe closed."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    for name in ('frames', 'acks', 'counts', 'domain'):
        parser.add_argument(f'--{name}', type=int, required=True)
    parser.add_argument('--node', required=True)
    parser.add_argument('--namespace', default='/')
    parser.add_argument('--sink', type=json.loads, default=None,
                        help='the live view and recording to hold, as JSON')
    args = parser.parse_args(argv)
    # The simulator ends it by closing the pipe; a Ctrl-C in the terminal reaches both.
    # SIGTERM ends it at once, but as an exit: its participant's shared memory is removed.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda number, frame: sys.exit(128 + number))
    return run(args.frames, args.acks, args.counts, args.domain, args.node, args.namespace,
               args.sink)


if __name__ == '__main__':
    sys.exit(main())
