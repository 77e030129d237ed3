"""
A stand-in for the simulator's live view: FoxgloveSink fed with a real-time drive.

    python standin.py [--record FILE] [--duration S]

Prints the server's port on the first line, then logs /robot_description
and /tf_static once and the rest of ``sample_messages.drive`` paced by the
wall clock (simulated time from 0), broadcasting the time, until SIGINT or
SIGTERM (exit 0) or the duration. Every message is real serialized bytes:
the package's URDF, TF odom -> base_footprint -> base_link, a scan, odometry,
joint states and a camera image.
"""

import argparse
from pathlib import Path
import sys
import time

# sample_messages (test/) and this checkout's r2d2_sim.
sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parents[2])]

from r2d2_sim.sim_node import stop_on_signals  # noqa: E402 (handlers first)


def main() -> int:
    """Serve until stopped."""
    stop = stop_on_signals()
    parser = argparse.ArgumentParser()
    parser.add_argument('--record', default=None)
    parser.add_argument('--duration', type=float, default=600.0)
    options = parser.parse_args()
    from r2d2_sim.foxglove_sink import FoxgloveSink
    from sample_messages import drive, TOPICS
    with FoxgloveSink(port=0, record_path=options.record) as sink:
        channels = {topic: sink.channel(topic, *TOPICS[topic]) for topic in TOPICS}
        print(sink.port, flush=True)
        start = time.monotonic()
        for sample in drive(options.duration):
            wait_s = start + sample.time_ns * 1e-9 - time.monotonic()
            if wait_s > 0 and stop.wait(wait_s):
                break
            channels[sample.topic].log(sample.data, sample.time_ns)
            if sample.topic == '/clock':
                sink.set_time(sample.time_ns)
            if stop.is_set():
                break
    return 0


if __name__ == '__main__':
    sys.exit(main())
