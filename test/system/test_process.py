"""The child-process layer everyone uses to run sim_node: start, watch, stop, remaps read."""

import signal
import sys
import time

from r2d2_sim.client import wait_for
from r2d2_sim.testing import ChildProcess


def test_failure_message_names_status_and_output_tail():
    child = ChildProcess([sys.executable, '-c',
                          'import sys; print("r2d2_sim: error: bad parameter", file=sys.stderr);'
                          ' sys.exit(2)']).start()
    try:
        assert wait_for(child.exited, 10.0)
        message = child.failure_message('no topics')
    finally:
        result = child.stop()
    assert message.startswith('no topics (it exited with status 2):')
    assert 'r2d2_sim: error: bad parameter' in message.splitlines()[-1]
    assert result.returncode == 2 and result.stderr == 'r2d2_sim: error: bad parameter\n'


def test_stop_kills_a_process_that_ignores_sigint():
    ready = 'import signal, sys, time; signal.signal(signal.SIGINT, signal.SIG_IGN); '
    child = ChildProcess([sys.executable, '-c', ready + 'print("ready", flush=True); '
                          'time.sleep(60)'], merge_output=True).start()
    try:
        # Wait until SIGINT is ignored, or stop() would succeed for the wrong reason.
        assert wait_for(lambda: child.log_tail() == ['ready'], 10.0, interval_s=0.05)
        started = time.monotonic()
        result = child.stop(timeout_s=0.5)
        assert result.returncode == -signal.SIGKILL
        assert time.monotonic() - started < 5.0
        assert result.stdout == 'ready\n'
    finally:
        if child.process.poll() is None:
            child.process.kill()
            child.process.wait()


def test_stop_twice_returns_the_first_result(tmp_path):
    log = tmp_path / 'child.log'
    child = ChildProcess([sys.executable, '-c', 'print("out"); import sys; '
                          'print("err", file=sys.stderr)'], log_path=str(log)).start()
    assert wait_for(child.exited, 10.0)
    first = child.stop()
    assert child.stop() is first
    assert first.returncode == 0 and sorted(first.stdout.split()) == ['err', 'out']
    assert sorted(log.read_text().split()) == ['err', 'out']


def test_reading_the_output_while_the_child_writes_loses_no_line():
    """output() polled as fast as it goes while the child writes: every line, in order, once."""
    code = ('import sys\nfor i in range(3000):\n'
            '    sys.stderr.write(f"line {i:04d} " + "x" * 60 + "\\n"); sys.stderr.flush()')
    expected = [f'line {i:04d} ' + 'x' * 60 for i in range(3000)]
    for _ in range(3):  # a seek per poll corrupted every run of three
        child = ChildProcess([sys.executable, '-c', code]).start()
        polls = 0
        while not child.exited():
            child.output()
            polls += 1
        result = child.stop()
        assert result.returncode == 0 and polls > 1
        assert result.stderr.splitlines() == expected
