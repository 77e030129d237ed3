"""
The ``replay`` command against a recording made by FoxgloveSink, heard by another process.

Three processes: this test records a file, ``python -m r2d2_sim.apps.replay``
publishes it, and ``topic_listener.py`` subscribes (raw bytes, so content
is compared byte for byte with the recording) on a leased ROS domain.
"""

import signal
import subprocess
import sys

import pytest
from rclpy.serialization import deserialize_message

from r2d2_sim.recording.sink import FoxgloveSink
from r2d2_sim.testing import lease_domain, ros_child_env, stop_process
from sample_messages import message_class, Sample, samples, tf_message_bytes, TOPICS, transform
from topic_listener import read_listener, start_listener

DURATION_S = 2.0
CLOCK_HZ = 50


def importable(type_name):
    """Return True when this venv has the message class (tf2_msgs may be missing)."""
    try:
        message_class(type_name)
    except ImportError:
        return False
    return True


def on_the_wire(data):
    """Return serialized bytes as a DDS subscriber gets them: padded to a multiple of 4."""
    return data + b'\0' * (-len(data) % 4)


@pytest.fixture(scope='module')
def recording(tmp_path_factory):
    """Record a 2 s drive with the sink; return (path, {topic: [bytes subscribers get]})."""
    path = tmp_path_factory.mktemp('replay') / 'run.mcap'
    recorded = {}
    # A second robot's /tf_static: each robot's publisher latches its own (depth 1), and
    # both are one channel in the file.
    second = Sample('/tf_static', TOPICS['/tf_static'][0], 0, tf_message_bytes(
        [transform('r1/base_footprint', 'r1/base_link', 0, z=0.5)])) \
        if importable(TOPICS['/tf_static'][0]) else None
    with FoxgloveSink(record_path=path) as sink:
        channels = {t: sink.channel(t, *TOPICS[t]) for t in TOPICS}
        for index, sample in enumerate(samples(DURATION_S, clock_hz=CLOCK_HZ)):
            channels[sample.topic].log(sample.data, sample.time_ns)
            recorded.setdefault(sample.topic, []).append(on_the_wire(sample.data))
            if index == 1 and second is not None:
                channels[second.topic].log(second.data, second.time_ns)
                recorded[second.topic].append(on_the_wire(second.data))
    return path, recorded


def replay_command(path, *args):
    """Return the command line of the replay tool (the module behind the ``replay`` script)."""
    return [sys.executable, '-m', 'r2d2_sim.apps.replay', str(path), *args]


def test_replay_publishes_each_topic_with_its_bytes_at_the_recorded_pace(recording, tmp_path):
    """Every recorded message reaches a subscriber in another process; a pass takes 2 s / rate."""
    path, recorded = recording
    rate = 2.0
    topics = {t: {'type': TOPICS[t][0], 'distinct': len(set(recorded[t])),
                  'durability': TOPICS[t][1].durability.name.lower()}
              for t in TOPICS if importable(TOPICS[t][0])}
    assert len(topics) >= len(TOPICS) - 2, 'only tf2_msgs may be missing'
    # Three passes' worth of clocks: whatever discovery missed, two passes are whole.
    topics['/clock']['count'] = 3 * len(recorded['/clock'])
    out_path = tmp_path / 'heard.json'
    with lease_domain() as lease:
        listener = start_listener(lease.domain_id, topics, out_path)
        replay = subprocess.Popen(replay_command(path, '--rate', str(rate), '--loop'),
                                  env=ros_child_env(lease.domain_id), stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)
        try:
            heard = read_listener(listener, out_path, timeout_s=90.0)
        finally:
            result = stop_process(replay, signal.SIGINT)
    assert result.returncode == 130, result.stderr
    assert 'playing' in result.stdout
    for topic in topics:
        assert {data for _, data in heard[topic]} == set(recorded[topic]), topic
        cls = message_class(TOPICS[topic][0])
        for _, data in heard[topic][:5]:
            assert isinstance(deserialize_message(data, cls), cls)
    # Pace: the wall time from a pass's first clock to its last is the
    # recorded 2 s over the rate (the first pass may have been partly missed
    # during discovery: the last complete pass is timed).
    first, last = recorded['/clock'][0], recorded['/clock'][-1]
    spans, started = [], None
    for received_s, data in heard['/clock']:
        if data == first:
            started = received_s
        elif data == last and started is not None:
            spans.append(received_s - started)
            started = None
    assert spans, 'no complete pass'
    # Paced, not as fast as possible nor at another rate; the exact schedule is
    # apps/test_replay_pacing.py's (a loaded machine delays what the listener hears).
    assert DURATION_S / rate * 0.85 <= spans[-1] <= DURATION_S / rate * 1.5, spans


def test_a_late_subscriber_gets_the_latched_topics(recording, tmp_path):
    """/robot_description and both robots' /tf_static reach a subscriber that comes later."""
    path, recorded = recording
    latched = {t: {'type': TOPICS[t][0], 'distinct': len(set(recorded[t])),
                   'durability': 'transient_local'}
               for t in ('/robot_description', '/tf_static') if importable(TOPICS[t][0])}
    out_path = tmp_path / 'late.json'
    with lease_domain() as lease:
        # A slow pass (40 s) without --loop: the latched messages are sent once, first.
        replay = subprocess.Popen(replay_command(path, '--rate', '0.05'),
                                  env=ros_child_env(lease.domain_id), stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)
        try:
            assert 'playing' in replay.stdout.readline(), replay.stderr.read()
            listener = start_listener(lease.domain_id, latched, out_path, timeout_s=30.0)
            heard = read_listener(listener, out_path, timeout_s=40.0)
            assert replay.poll() is None, 'replay ended first'
        finally:
            result = stop_process(replay, signal.SIGTERM)
    assert result.returncode == 130, result.stderr
    for topic in latched:
        assert [data for _, data in heard[topic]] == recorded[topic]


def test_a_whole_pass_ends_with_status_0(recording):
    """Without --loop the command exits 0 after the last message."""
    path, recorded = recording
    with lease_domain() as lease:
        result = subprocess.run(replay_command(path, '--rate', '8'),
                                env=ros_child_env(lease.domain_id), capture_output=True,
                                text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    expected = sum(len(m) for t, m in recorded.items() if importable(TOPICS[t][0]))
    assert f'done, {expected} messages' in result.stdout


@pytest.mark.parametrize('content, words', [
    (None, ['cannot open', 'No such file']),
    (b'', ['not a readable MCAP file']),
    (b'this is not an mcap file, it is text\n' * 10, ['not a readable MCAP file']),
    ('truncated', ['nothing to replay', 'cut short']),
])
def test_a_bad_file_is_one_error_line_and_status_2(recording, tmp_path, content, words):
    """Missing, empty, foreign files, or one cut inside its first chunk: one line, exit 2."""
    path = tmp_path / 'bad.mcap'
    if content == 'truncated':  # a recorder killed inside its first (and only) chunk
        good = recording[0].read_bytes()
        path.write_bytes(good[:len(good) // 3])
    elif content is not None:
        path.write_bytes(content)
    result = subprocess.run(replay_command(path), env=ros_child_env(), capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('replay: error: '), result.stderr
    for word in words:
        assert word in lines[0]


@pytest.mark.parametrize('args, words', [
    (['--rate', '0'], ["replay: error: argument --rate: must be in [1e-06, 1e+06], got '0'"]),
    # These two passed, then crashed: a wait past what the platform sleeps, int(inf).
    (['--rate', '1e-12'], ["argument --rate: must be in [1e-06, 1e+06], got '1e-12'"]),
    (['--max-gib', '1e300'], ["argument --max-gib: must be in [1e-06, 1e+06] GiB, got '1e300'"]),
    (['--ros-args', '-r'], ['replay: error: bad ROS arguments']),
    (['--ros-args', '-p', 'use_sim_time:=1'],
     ['replay: error: parameter use_sim_time must be true or false, got 1 (an integer)']),
])
def test_bad_arguments_exit_2(recording, args, words):
    """Bad arguments (a rate, malformed ROS arguments, use_sim_time:=1): one line, exit 2."""
    with lease_domain() as lease:
        result = subprocess.run(replay_command(recording[0], *args),
                                env=ros_child_env(lease.domain_id), capture_output=True,
                                text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    assert 'Traceback' not in result.stderr
    for word in words:
        assert word in result.stderr.strip().splitlines()[-1]
