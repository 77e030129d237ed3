"""
What the live view and the recording hold on to: idle viewers, latched re-sends, robots gone.

    .venv/bin/python bench/live_view_limits.py [--viewers 500] [--cycles 3000]

Three measurements, each of a ``FoxgloveSink`` in a process of its own
(``--child``), its resident memory read from ``/proc``:

- ``viewers``: a sink with a server; the bench opens ``--viewers`` idle
  WebSocket connections, then closes them, and waits for the sink's watch
  (once a second) to hand the memory back (``malloc_trim``);
- ``latched``: one viewer subscribed to ``/robot_description``, another
  subscribing and unsubscribing 300 times; how many copies the first got;
- ``cycles``: ``--cycles`` times, a robot's five topics registered in a
  namespace of their own, logged once and released (a spawned robot
  deleted), with the live view, the recording, both.

Prints the numbers; they are never asserted. About 20 s.
"""

import argparse
from contextlib import ExitStack
import json
import os
import subprocess
import sys
import tempfile
import time

from common import REPO  # noqa: F401  (puts this checkout first on sys.path)

ROBOT_TOPICS = ('/odom', '/joint_states', '/scan', '/robot_description', '/ground_truth')


def rss_mb(pid='self'):
    """Return a process's resident memory in MB."""
    with open(f'/proc/{pid}/statm') as statm:
        return int(statm.read().split()[1]) * os.sysconf('SC_PAGE_SIZE') / 1e6


def child_server():
    """Serve a sink until stdin closes; answer each line with this process's RSS."""
    from r2d2_sim.recording.sink import FoxgloveSink
    sink = FoxgloveSink(port=0, warn=lambda text: None)
    print(sink.port, flush=True)
    for _ in sys.stdin:
        print(f'{rss_mb():.1f}', flush=True)
    sink.close()


def child_cycles(cycles, live, record):
    """Register, log and release a robot's topics ``cycles`` times; print RSS before and after."""
    sys.path.insert(0, os.path.join(REPO, 'test'))
    from sample_messages import TOPICS
    from r2d2_sim.recording.sink import FoxgloveSink
    with tempfile.TemporaryDirectory() as directory:
        sink = FoxgloveSink(port=0 if live else None,
                            record_path=os.path.join(directory, 'run.mcap') if record else None)
        before = rss_mb()
        for cycle in range(cycles):
            handles = [sink.channel(f'/robot_{cycle}{t}', *TOPICS[t]) for t in ROBOT_TOPICS]
            for handle in handles:
                handle.log(b'\x00\x01\x00\x00', cycle)
            for handle in handles:
                handle.release()
        after = rss_mb()
        sink.close()
        size = os.path.getsize(os.path.join(directory, 'run.mcap')) if record else 0
    print(json.dumps({'before': before, 'after': after, 'file': size}))


def viewers(count):
    """Open and close ``count`` idle viewers of a sink in another process; return RSS steps."""
    from websockets.sync.client import connect
    child = subprocess.Popen([sys.executable, __file__, '--child', 'server'],
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    port = int(child.stdout.readline())

    def rss():
        child.stdin.write('\n')
        child.stdin.flush()
        return float(child.stdout.readline())
    try:
        start = rss()
        with ExitStack() as connections:
            for _ in range(count):
                connections.enter_context(connect(f'ws://127.0.0.1:{port}',
                                                  subprotocols=['foxglove.sdk.v1']))
            opened = rss()
        time.sleep(3.0)  # the sink's watch looks once a second
        closed = rss()
    finally:
        child.stdin.close()
        child.wait(timeout=10)
    return start, opened, closed


def latched(cycles=300):
    """Count the copies one viewer gets while another subscribes ``cycles`` times."""
    from r2d2_sim.recording.sink import FoxgloveSink
    from r2d2_sim.testing import LiveViewClient
    with FoxgloveSink(port=0) as sink:
        from rclpy.qos import DurabilityPolicy, QoSProfile
        sink.channel('/robot_description', 'std_msgs/msg/String', QoSProfile(
            depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)).log(b'urdf', 1)
        with LiveViewClient(sink.port) as watcher, LiveViewClient(sink.port) as flicker:
            watcher.wait_for_messages('/robot_description')
            start = time.monotonic()
            for _ in range(cycles):
                flicker.subscribe(['/robot_description'])
                flicker.unsubscribe(['/robot_description'])
            flicker.wait_for_messages('/robot_description')
            watcher.pump(timeout_s=1.0)
            return len(watcher.messages['/robot_description']) - 1, time.monotonic() - start


def cycles(count, live, record):
    """Run ``child_cycles`` in a process of its own; return its numbers."""
    out = subprocess.run([sys.executable, __file__, '--child', 'cycles', str(count),
                          str(int(live)), str(int(record))],
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out.splitlines()[-1])


def main():
    """Measure and print."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--viewers', type=int, default=500)
    parser.add_argument('--cycles', type=int, default=3000)
    parser.add_argument('--child', nargs='*', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        if args.child[0] == 'server':
            return child_server()
        return child_cycles(int(args.child[1]), args.child[2] == '1', args.child[3] == '1')
    start, opened, closed = viewers(args.viewers)
    print(f'{args.viewers} idle viewers: RSS {start:.1f} MB -> {opened:.1f} MB open '
          f'({(opened - start) / args.viewers * 1000:.0f} kB each) -> {closed:.1f} MB 3 s '
          'after they closed')
    copies, elapsed = latched()
    print(f'latched: 300 subscribe/unsubscribe in {elapsed:.2f} s sent another viewer '
          f'{copies} copies')
    for live, record in ((True, False), (False, True), (True, True)):
        numbers = cycles(args.cycles, live, record)
        what = ' + '.join(n for n, on in (('live view', live), ('recording', record)) if on)
        grown = numbers['after'] - numbers['before']
        print(f'{args.cycles} robots of {len(ROBOT_TOPICS)} topics released, {what}: RSS '
              f'+{grown:.1f} MB ({grown / args.cycles / len(ROBOT_TOPICS) * 1000:.2f} kB per '
              f'channel), file {numbers["file"] / args.cycles / len(ROBOT_TOPICS):.0f} B '
              'per channel')


if __name__ == '__main__':
    main()
