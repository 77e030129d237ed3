"""
A ``sim_node`` recording cut off by SIGKILL (a CI timeout), replayed and read back.

Issue 30, S4 and its friction: the killed run is the one people most want to
see. The simulator records through ``-p record:=...`` and is stepped while
paused until ``mcap``'s own sequential reader finds a complete message in
the file, then killed; what that reader gets before the cut is the
reference.
"""

import os
import signal
import subprocess
import sys
import time

from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock

from r2d2_sim.testing import lease_domain, read_recording, ros_child_env, SimProcess
from recording_files import complete_messages

STEPS_PER_CALL = 24
DEADLINE_S = 120.0


def record_and_kill(path):
    """Record with sim_node, step until a chunk is on disk, SIGKILL it; return its exit status."""
    deadline = time.monotonic() + DEADLINE_S
    with SimProcess(record=str(path), start_paused=True) as sim:
        while not complete_messages(path):
            assert time.monotonic() < deadline, 'no complete chunk reached the file'
            sim.step(STEPS_PER_CALL)
        sim.step(STEPS_PER_CALL)  # and some more, which the kill cuts off
        os.kill(sim.process.pid, signal.SIGKILL)
        return sim.process.process.wait(timeout=30)


def test_a_killed_recording_replays_what_it_holds_and_reads_back(tmp_path):
    """Replay plays every complete message (exit 0, one line); read_recording types them."""
    path = tmp_path / 'killed.mcap'
    assert record_and_kill(path) == -signal.SIGKILL
    reference = complete_messages(path)
    assert reference
    with lease_domain() as lease:
        result = subprocess.run(
            [sys.executable, '-m', 'r2d2_sim.apps.replay', str(path), '--rate', '20'],
            env=ros_child_env(lease.domain_id), capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and 'was cut short' in lines[0], result.stderr
    assert f'recovered {len(reference)} messages' in lines[0]
    assert result.stdout.splitlines()[-1] == f'replay: done, {len(reference)} messages'

    recording = read_recording(path)
    assert sum(len(messages) for messages in recording.values()) == len(reference)
    clocks = recording['/clock']
    assert all(isinstance(m.message, Clock) for m in clocks)
    times = [m.message.clock.sec * 10**9 + m.message.clock.nanosec for m in clocks]
    assert times == sorted(times) and times == [m.log_time_ns for m in clocks]
    odometry = recording['/odom'][-1].message
    assert isinstance(odometry, Odometry) and odometry.header.frame_id == 'odom'
