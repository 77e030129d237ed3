"""
FoxgloveSink in processes of its own: without foxglove-sdk, and a recorder stopped by signals.

The sink in this process is recording/test_foxglove_sink.py's.
"""

import os
from pathlib import Path
import signal
import subprocess
import sys

import pytest
from rosbags.highlevel import AnyReader

from common import read_with_mcap
from r2d2_sim.testing import ProcessResult, ros_child_env, stop_process, wait_for
from sample_messages import TOPICS

# Where sample_messages.py is, for the recorder child's sys.path.
TEST_DIR = Path(__file__).resolve().parent.parent


def test_foxglove_is_imported_only_for_a_sink():
    """Without foxglove-sdk, an empty sink works and a real one says what to install."""
    code = '\n'.join([
        'import sys',
        'sys.modules["foxglove"] = None',
        'from rclpy.qos import QoSProfile',
        'from r2d2_sim.recording.sink import FoxgloveSink, SinkError',
        'sink = FoxgloveSink()',
        'sink.channel("/scan", "sensor_msgs/msg/LaserScan", QoSProfile(depth=5)).log(b"x", 1)',
        'sink.set_time(1); sink.close()',
        'try:',
        '    FoxgloveSink(port=0)',
        'except SinkError as exc:',
        '    print(exc)',
    ])
    result = subprocess.run([sys.executable, '-c', code], env=ros_child_env(),
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert 'pip install "r2d2_sim[foxglove]"' in result.stdout


RECORDER = '''
import signal, sys, time
mode, path, test_dir = sys.argv[1:4]
if mode == 'handlers':
    from r2d2_sim.apps.cli import stop_on_signals
    signal.signal(signal.SIGHUP, signal.SIG_DFL)  # as a terminal's shell starts it (CI: nohup)
    stop = stop_on_signals()
elif mode.endswith('keyboard_interrupt'):
    # Python's own Ctrl-C, as in a terminal. A CI job started in the background
    # (cmd & in a script) passes SIGINT on ignored, and Python keeps it so.
    signal.signal(signal.SIGINT, signal.default_int_handler)
sys.path.insert(0, test_dir)
from r2d2_sim.recording.sink import FoxgloveSink
from sample_messages import samples, TOPICS
batch = samples(0.5)
sink = FoxgloveSink(record_path=path)
channels = {t: sink.channel(t, *TOPICS[t]) for t in TOPICS}
logged = 0

def log_batch(offset_ns):
    global logged
    for sample in batch:
        channels[sample.topic].log(sample.data, sample.time_ns + offset_ns)
        logged += 1

try:
    for rounds in range(1, 10**6):
        log_batch(rounds * 10**9)
        if rounds == 3:
            print('recording', flush=True)
            if mode == 'forgotten':  # no close(): the finalizer (or the SDK's own) must finish
                break
        if mode == 'handlers':
            if stop.wait(0.02):
                break
        else:
            time.sleep(0.02)
finally:
    print(logged, flush=True)
    if not mode.startswith('forgotten'):
        sink.close()
'''


@pytest.mark.parametrize('mode, sig', [
    ('handlers', signal.SIGINT), ('handlers', signal.SIGTERM), ('handlers', signal.SIGHUP),
    ('keyboard_interrupt', signal.SIGINT), ('forgotten', None),
    ('forgotten_keyboard_interrupt', signal.SIGINT)])
def test_a_stopped_recorder_leaves_a_complete_file(tmp_path, mode, sig):
    """
    A process that records until a SIGINT, SIGTERM or SIGHUP leaves every message and a summary.

    ``handlers``: the owner turns both signals into an event (sim_node's
    way) and closes in ``finally``. ``keyboard_interrupt``: Python's own
    SIGINT handling, closed in ``finally``. ``forgotten``: never closed,
    normal exit; ``forgotten_keyboard_interrupt``: never closed, Ctrl-C.
    """
    path = tmp_path / 'run.mcap'
    process = subprocess.Popen([sys.executable, '-c', RECORDER, mode, str(path), str(TEST_DIR)],
                               env=ros_child_env(), stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        assert process.stdout.readline().strip() == 'recording', process.stderr.read()
        if sig is None:
            # Not communicate(): it reads the pipe's fd and would miss what
            # readline() already buffered; the output is small.
            process.wait(timeout=20.0)
            result = ProcessResult(process.returncode, process.stdout.read(),
                                   process.stderr.read())
        else:
            result = stop_process(process, sig, timeout_s=20.0)  # one signal only
    finally:
        if process.poll() is None:
            process.kill()
    logged = int(result.stdout.split()[-1])
    if mode == 'handlers' or mode == 'forgotten':
        assert result.returncode == 0, result.stderr
    assert wait_for(lambda: path.stat().st_size > 0, 1.0)
    header, summary, messages = read_with_mcap(path)
    assert summary is not None, 'no summary: the file was not closed'
    assert summary.statistics.message_count == len(messages)
    if mode.endswith('keyboard_interrupt'):  # it may land between a log and its count
        assert logged <= len(messages) <= logged + 1
    else:
        assert len(messages) == logged
    assert len(messages) >= 3 * len(TOPICS)
    with AnyReader([path]) as reader:
        assert sum(info.msgcount for info in reader.topics.values()) == len(messages)
    assert os.path.getsize(path) > 1000
