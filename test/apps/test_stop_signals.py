"""
``apps.cli.stop_on_signals``: SIGINT, SIGTERM and SIGHUP stop the executables, nohup kept.

SIGHUP (a terminal closed, an SSH session dropped) killed ``sim_node`` before
it could finish its recording. A process started ignoring it (``nohup``)
keeps ignoring it.
"""

import os
import signal
import threading

import pytest

from r2d2_sim.apps.cli import stop_on_signals


@pytest.fixture
def handlers():
    """Put the process's SIGINT, SIGTERM and SIGHUP handlers back after the test."""
    saved = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    yield
    for sig, handler in saved.items():
        signal.signal(sig, handler)


def test_a_hangup_stops_as_a_termination_does(handlers):
    signal.signal(signal.SIGHUP, signal.SIG_DFL)  # as a terminal's shell starts a program
    stop = stop_on_signals()
    os.kill(os.getpid(), signal.SIGHUP)
    assert stop.wait(5.0)


def test_a_hangup_nohup_ignores_stays_ignored(handlers):
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    stop = stop_on_signals(threading.Event())
    assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
    os.kill(os.getpid(), signal.SIGHUP)
    assert not stop.wait(0.2)
