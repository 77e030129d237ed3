"""
The outputs process: publishes, in order, the bytes a simulator's physics thread handed over.

Started by :class:`r2d2_sim.ros.relay.OutputRelay` (never by hand): it reads
frames from an inherited pipe, makes and destroys the publishers they name,
publishes each message's bytes, writes a frame's number back when the frame
asks, and keeps the matched subscriptions of every publisher in the shared
counts (its executor thread serves the matched events). It ends, with status
0, when the pipe closes.
"""

import argparse
import json
import mmap
import os
import sys
import threading
from typing import Any, Callable, Dict, List, Optional, Sequence

from r2d2_sim.recording.reader import message_class
from r2d2_sim.ros.relay import (
    ACK, ACK_RECORD, CREATE, DESTROY, FRAME, MAX_PUBLISHERS, qos_from_dict, RECORD)


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
        namespace: str) -> int:
    """Publish what the pipe ``frames`` brings until it closes; return the exit status."""
    import rclpy
    from rclpy.event_handler import PublisherEventCallbacks
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.publisher import Publisher
    from rclpy.signals import SignalHandlerOptions
    counts_map = mmap.mmap(counts_fd, 4 * MAX_PUBLISHERS)
    counts = memoryview(counts_map).cast('i')
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(node_name, namespace=namespace, context=context,
                             start_parameter_services=False)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    stop = threading.Event()

    def spin() -> None:  # stopped by the event, never by shutting the executor down under it
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.1)
    spinner = threading.Thread(target=spin, name='matched events', daemon=True)
    spinner.start()
    publishers: Dict[int, Publisher] = {}

    def matched(index: int, made: List[Publisher]) -> Callable[[Any], None]:
        def on_matched(info) -> None:
            # Only the publisher that holds the index now: an index is reused after a
            # destroy, and a late event of the old publisher must not count for the new.
            if made and publishers.get(index) is made[0]:
                counts[index] = info.current_count
        return on_matched

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
                elif index == CREATE:
                    spec = json.loads(data)
                    new, made = spec['index'], []  # type: int, List[Publisher]
                    publisher = node.create_publisher(
                        message_class(spec['type']), spec['topic'], qos_from_dict(spec['qos']),
                        event_callbacks=PublisherEventCallbacks(matched=matched(new, made)))
                    publishers[new] = publisher
                    made.append(publisher)
                    counts[new] = publisher.get_subscription_count()
                elif index == DESTROY:
                    gone = json.loads(data)['index']
                    node.destroy_publisher(publishers.pop(gone))
                    counts[gone] = 0
            if flags & ACK:
                try:
                    os.write(acks, ACK_RECORD.pack(sequence))
                except BrokenPipeError:  # the simulator stopped waiting: it is going
                    return 0
    finally:
        stop.set()
        spinner.join()  # within a spin_once's timeout
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Parse the relay's arguments and run; status 0 when the pipe closed."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    for name in ('frames', 'acks', 'counts', 'domain'):
        parser.add_argument(f'--{name}', type=int, required=True)
    parser.add_argument('--node', required=True)
    parser.add_argument('--namespace', default='/')
    args = parser.parse_args(argv)
    # The simulator ends it by closing the pipe; a Ctrl-C in the terminal reaches both.
    # SIGTERM ends it at once, but as an exit: its participant's shared memory is removed.
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda number, frame: sys.exit(128 + number))
    return run(args.frames, args.acks, args.counts, args.domain, args.node, args.namespace)


if __name__ == '__main__':
    sys.exit(main())
