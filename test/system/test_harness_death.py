"""
A test process that dies without cleaning up: its simulator ends too, its domain is never shared.

A CI timeout SIGKILLs the test process, and an exception outside ``with``
ends it without ``stop()``: nothing of the harness runs on the way out. The
``sim_node`` it started must end by itself, and for as long as such a
simulator still runs, no other harness may lease its domain (the lease's lock
file and port are inherited by the simulator). Each test runs the harness in
a Python process of its own, leases in a lock directory of its own, and ends
every process it caused, also when it fails.
"""

import os
import select
import signal
import subprocess
import sys
import threading
import time

import pytest

from r2d2_sim.testing import (
    domains, DomainUnavailable, HarnessError, lease_domain, ros_child_env, SimProcess)

# A test process with one simulator: prints "<domain id> <sim_node pid>", then
# waits for a line on stdin ("raise": die of an uncaught exception, outside any
# with). argv[1] "outlive": a simulator that ignores its parent's end, as one
# started through a wrapper that drops R2D2_SIM_PARENT_PID would.
HARNESS = '''
import os
import sys

from r2d2_sim.testing import SimProcess

OUTLIVE = ("import os, sys; os.environ.pop('R2D2_SIM_PARENT_PID', None); "
           "os.execv(sys.executable, [sys.executable, '-m', 'r2d2_sim'] + sys.argv[1:])")
command = [sys.executable, '-c', OUTLIVE] if sys.argv[1] == 'outlive' else None
sim = SimProcess(start_paused=True, use_env_domain=False, command=command,
                 scan_rate=0.0, publish_rate=10.0)
print(sim.domain_id, sim.process.pid, flush=True)
if sys.stdin.readline().strip() == 'raise':
    raise RuntimeError('a test that died outside its with')
'''
START_TIMEOUT_S = 90.0  # sim_node's start-up on a loaded 2-core machine
EXIT_TIMEOUT_S = 30.0   # for a simulator whose parent has gone to stop


def start_time(pid):
    """Return the kernel's start time of ``pid`` (None if gone), to tell it from a reused pid."""
    try:
        with open(f'/proc/{pid}/stat', 'rb') as stat_file:
            fields = stat_file.read().rsplit(b')', 1)[1].split()
    except OSError:
        return None
    return None if fields[0] == b'Z' else int(fields[19])  # a zombie has ended


def running(pid, started):
    return started is not None and start_time(pid) == started


def read_line(process, timeout_s):
    """Return the next line ``process`` prints, or fail at the deadline."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and process.poll() is None:
        ready, _, _ = select.select([process.stdout], [], [], 0.1)
        if ready:
            return process.stdout.readline()
    pytest.fail(f'the harness process printed nothing within {timeout_s:g} s '
                f'(exit status {process.poll()}): {process.stderr.read()[-2000:]}')


@pytest.fixture
def harness(tmp_path, monkeypatch):
    """
    Provide ``start(kind) -> (process, domain id, sim_node pid, its start time)``.

    The harness process leases in this test's lock directory; after the test,
    the harness and its simulator are killed if they still run.
    """
    monkeypatch.setenv(domains.DOMAIN_LOCK_DIR_ENV, str(tmp_path / 'locks'))
    started = []

    def start(kind):
        process = subprocess.Popen([sys.executable, '-c', HARNESS, kind], env=ros_child_env(),
                                   stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, text=True)
        started.append((process, None, None))
        domain_id, sim_pid = (int(word) for word in read_line(process, START_TIMEOUT_S).split())
        started[-1] = (process, sim_pid, start_time(sim_pid))
        return process, domain_id, sim_pid, started[-1][2]
    yield start
    for process, sim_pid, sim_started in started:
        if process.poll() is None:
            process.kill()
        process.communicate()
        if running(sim_pid, sim_started):
            os.kill(sim_pid, signal.SIGKILL)


def wait_until_gone(pid, started, timeout_s):
    deadline = time.monotonic() + timeout_s
    while running(pid, started) and time.monotonic() < deadline:
        time.sleep(0.05)
    return not running(pid, started)


@pytest.mark.parametrize('death', ['sigkill', 'uncaught_exception'])
def test_a_simulator_ends_with_the_test_process_that_started_it(harness, death):
    """SIGKILL (a CI timeout) or an exception outside with: its sim_node stops by itself."""
    process, domain_id, sim_pid, sim_started = harness('sim_node')
    assert running(sim_pid, sim_started)
    if death == 'sigkill':
        process.kill()
    else:
        process.stdin.write('raise\n')
        process.stdin.flush()
    process.wait(timeout=EXIT_TIMEOUT_S)
    assert wait_until_gone(sim_pid, sim_started, EXIT_TIMEOUT_S), (
        f'sim_node {sim_pid} still runs {EXIT_TIMEOUT_S:g} s after its test process died')
    with lease_domain(domain_id, timeout_s=10.0) as lease:  # free again once it has gone
        assert lease.domain_id == domain_id


def test_a_domain_stays_leased_while_a_simulator_of_a_dead_harness_runs(harness):
    """The lease's lock and port live on in the simulator: nobody else gets its domain."""
    process, domain_id, sim_pid, sim_started = harness('outlive')
    process.kill()
    process.wait(timeout=EXIT_TIMEOUT_S)
    assert running(sim_pid, sim_started)  # the leaser is dead, its simulator is not
    with pytest.raises(DomainUnavailable):
        lease_domain(domain_id, timeout_s=0.5)
    port = domains._try_coordinator_port(domain_id)  # as domain_coordinator would
    if port is not None:
        port.close()
    assert port is None, 'a ROS tool could take the domain of a running simulator'
    assert running(sim_pid, sim_started)  # all of that while it ran
    os.kill(sim_pid, signal.SIGKILL)
    assert wait_until_gone(sim_pid, sim_started, EXIT_TIMEOUT_S)
    with lease_domain(domain_id, timeout_s=10.0) as lease:  # its end ends the lease
        assert lease.domain_id == domain_id


def test_a_harness_started_from_a_thread_that_ended_keeps_its_simulator(tmp_path, monkeypatch):
    """The simulator watches the test process, not the thread that started it (as PDEATHSIG)."""
    monkeypatch.setenv(domains.DOMAIN_LOCK_DIR_ENV, str(tmp_path / 'locks'))
    made = []

    def start():
        made.append(SimProcess(start_paused=True, use_env_domain=False, scan_rate=0.0,
                               publish_rate=10.0))
    starter = threading.Thread(target=start)
    starter.start()
    starter.join()
    assert made, 'the SimProcess could not start (see the thread\'s exception above)'
    sim = made[0]
    try:
        # For a second after its starting thread ended it keeps answering; a simulator
        # tied to that thread would have had SIGTERM at once and be gone in 0.3 s.
        deadline = time.monotonic() + 1.0
        while time.monotonic() < deadline:
            try:
                assert sim.status()['paused']
            except HarnessError as exc:
                pytest.fail(f'the simulator ended with the thread that started it: {exc}')
        assert not sim.process.exited()
    finally:
        sim.stop()


def test_a_malformed_parent_id_is_one_line_and_status_2():
    """R2D2_SIM_PARENT_PID that is not a process id: sim_node refuses to start, in one line."""
    env = dict(ros_child_env(), R2D2_SIM_PARENT_PID='not a pid')
    result = subprocess.run([sys.executable, '-m', 'r2d2_sim'], env=env, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        "r2d2_sim: error: R2D2_SIM_PARENT_PID must be a process id, got 'not a pid'"]
