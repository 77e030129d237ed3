"""
``sim_node`` with its live view and recording when the machine runs short: disk, descriptors.

Each test runs the real executable in a process of its own and reads what it
says on ``/rosout`` and stderr, and how it exits. The full disk is a small
tmpfs filled nearly to the brim (as root), else the file size limit
(``prlimit --fsize``: the same failed write, EFBIG instead of ENOSPC); the
descriptors run out under ``prlimit --nofile``.
"""

import os
from pathlib import Path
import shutil
import socket
import subprocess
import sys

import pytest
from rcl_interfaces.msg import Log
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from r2d2_sim.testing import LiveViewClient, SimProcess, wait_for

# What the recording may still write once the simulator runs (bytes).
ROOM_LEFT = 64 * 1024


def free_port():
    """Return a TCP port nothing listens on now (the node binds it a moment later)."""
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def mount_small_tmpfs(directory: Path) -> bool:
    """Mount a 512 kB tmpfs on ``directory`` and fill it to ROOM_LEFT; False if not allowed."""
    if os.geteuid() != 0 or shutil.which('mount') is None:
        return False
    mounted = subprocess.run(['mount', '-t', 'tmpfs', '-o', 'size=512k', 'tmpfs',
                              str(directory)], capture_output=True)
    if mounted.returncode != 0:
        return False
    stats = os.statvfs(directory)
    (directory / 'filler').write_bytes(bytes(stats.f_bavail * stats.f_frsize - ROOM_LEFT))
    return True


@pytest.fixture
def nearly_full(tmp_path):
    """Yield (a directory with ROOM_LEFT bytes of room, the command prefix that makes it so)."""
    directory = tmp_path / 'small'
    directory.mkdir()
    if mount_small_tmpfs(directory):
        try:
            yield directory, []
        finally:
            subprocess.run(['umount', '-l', str(directory)], capture_output=True)
        return
    if shutil.which('prlimit') is None:
        pytest.fail('neither a tmpfs (root) nor prlimit (util-linux) to fill a disk with')
    yield directory, ['prlimit', f'--fsize={ROOM_LEFT}']


def keep_rosout(sim, lines):
    """Subscribe the harness's node to /rosout, keeping (level, node name, text)."""
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    return sim.probe.node.create_subscription(
        Log, '/rosout', lambda m: lines.append((m.level, m.name, m.msg)), qos)


def test_a_full_disk_stops_the_recording_in_one_line_and_nothing_else(nearly_full):
    """One ERROR on /rosout; physics and the live view go on; Ctrl-C exits 0, no traceback."""
    directory, prefix = nearly_full
    path = directory / 'run.mcap'
    port = free_port()
    rosout = []
    sim = SimProcess(command=[*prefix, sys.executable, '-m', 'r2d2_sim'], record=str(path),
                     foxglove_port=port, start_paused=True, scan_rate=10.0)
    try:
        keep_rosout(sim, rosout)

        def stopped():
            return [line for line in rosout if 'recording stopped' in line[2]]
        for _ in range(20):  # 10 simulated seconds each: the disk fills in the first
            sim.step_physics(2400)
            if sim.probe.spin_until(stopped, 1.0):
                break
        assert len(stopped()) == 1, rosout
        level, name, text = stopped()[0]
        assert (level, name) == (Log.ERROR, 'r2d2_sim')
        assert f'cannot write {path}' in text
        before_ns = sim.status()['sim_time_ns']
        assert sim.step_physics(240)['sim_time_ns'] == before_ns + 10**9  # physics goes on
        with LiveViewClient(port) as view:  # and so does the live view
            view.subscribe(['/clock'])
            for _ in range(20):  # until the subscription is served: a step's /clock arrives
                sim.step_physics(24)
                if view.pump(lambda: view.messages['/clock'], timeout_s=0.5):
                    break
            assert view.messages['/clock']
    finally:
        result = sim.stop()
    assert result.returncode == 0, result.stderr
    assert 'Traceback' not in result.stderr, result.stderr
    assert result.stderr.count('recording stopped') == 1, result.stderr
    assert len(result.stderr.splitlines()) < 10, result.stderr[-2000:]
    assert 0 < path.stat().st_size <= ROOM_LEFT


def test_the_live_view_warns_then_says_once_that_it_stopped_accepting_viewers():
    """Descriptors running short: a warning; out, the listener dies: one error; physics on."""
    port = free_port()
    limit = 96
    sim = SimProcess(command=['prlimit', f'--nofile={limit}', sys.executable, '-m', 'r2d2_sim'],
                     foxglove_port=port, start_paused=True)
    connections = []

    def said(text):
        return text in sim.process.output()[1]

    def connect():
        try:
            connections.append(socket.create_connection(('127.0.0.1', port), timeout=5))
            return True
        except OSError:
            return False

    def descriptors():
        return len(os.listdir(f'/proc/{sim.process.pid}/fd'))
    try:
        # Each connection is a descriptor in the node once accepted: past 80 % of
        # them, it warns. One at a time, so that it stays below the limit meanwhile.
        while descriptors() < 0.85 * limit:
            before = descriptors()
            assert connect(), sim.process.log_tail()
            assert wait_for(lambda: descriptors() > before, 5.0)
        assert wait_for(lambda: said('file descriptors are open (ulimit -n)'), 10.0), \
            sim.process.log_tail()
        while len(connections) < 200 and connect():
            pass  # until it has none left: its listener is gone
        assert wait_for(lambda: said('stopped accepting viewers'), 10.0), sim.process.log_tail()
        before_ns = sim.status()['sim_time_ns']
        assert sim.step_physics(240)['sim_time_ns'] == before_ns + 10**9  # physics goes on
    finally:
        for connection in connections:
            connection.close()
        result = sim.stop()
    assert result.returncode == 0, result.stderr
    # Said once (seen above as it came). Counted by the message's end: a line was once
    # torn, and another lost, when polling the log moved the offset the node writes at
    # (ChildProcess.output reads without moving it now).
    assert result.stderr.count('new ones are refused until the node restarts') == 1, \
        result.stderr
    assert result.stderr.count('file descriptors are open (ulimit -n)') == 1, result.stderr
    assert 'Traceback' not in result.stderr, result.stderr
