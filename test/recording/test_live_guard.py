"""ListenerWatch where it finds no listener to watch: one look says nothing and breaks nothing."""

import socket

from r2d2_sim.recording.live_guard import ListenerWatch


def test_a_look_without_a_listener_found_reports_nothing():
    """
    No listener found on the port (nothing listens there, or no /proc): check() does nothing.

    The module promises that the watch does nothing where it cannot look;
    check() once unpacked the missing listener (TypeError).
    """
    with socket.socket() as probe:  # a port this process does not listen on
        probe.bind(('127.0.0.1', 0))
        port = probe.getsockname()[1]
    lines = []
    watch = ListenerWatch(port, f'ws://127.0.0.1:{port}', lines.append, lines.append)
    try:
        watch.check()
    finally:
        watch.stop()
    assert watch.listening
    assert lines == []
