"""
The ``sim_node`` entry point, which catches SIGINT and SIGTERM before anything else.

Importing rclpy and PyBullet takes about a quarter of a second. A signal in that
window used to end the process with a ``KeyboardInterrupt`` traceback (SIGINT)
or status -15 (SIGTERM). This module imports only the standard library, so its
handlers are in place from the first line the package runs. They only set an
event: the node's loop sees it as soon as it starts and exits with status 0.
"""

import signal
import sys
import threading
from typing import List, Optional


def stop_on_signals() -> threading.Event:
    """Return an event that SIGINT and SIGTERM set from now on."""
    stop = threading.Event()

    def handler(signum, frame):
        stop.set()
    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return stop


def sim_node(argv: Optional[List[str]] = None) -> None:
    """Run the simulator node and exit with its status (``ros2 run r2d2_sim sim_node``)."""
    stop = stop_on_signals()
    from r2d2_sim.node import main  # heavy imports, now covered by the handlers
    sys.exit(main(argv if argv is not None else sys.argv, stop=stop))
