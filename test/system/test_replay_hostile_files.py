"""
``replay`` against recordings from anywhere: hostile names, bombs, bad metadata, cut-off files.

Each file is written here (``recording_files.py``, or FoxgloveSink); replay
runs in a child (``children/replay_child.py``) with its address space
limited to 1.5 GiB, which prints its peak memory and whether Python's
``this`` module was imported. Issue 30: S1, S2 and replay's half of S4.
"""

from pathlib import Path
import random
import subprocess
import sys

import pytest
from rclpy.qos import QoSProfile

from r2d2_sim.recording.message_definitions import offered_qos_profiles
from r2d2_sim.recording.sink import FoxgloveSink
from r2d2_sim.testing import lease_domain, ros_child_env
from recording_files import (bomb_chunk, complete_messages, GIB, MIB, plain_messages, Topic,
                             write_mcap)
from sample_messages import samples, TOPICS

CHILD = Path(__file__).resolve().parent.parent / 'children' / 'replay_child.py'
LIMIT_MIB = 1536
# What replay may use while refusing a bomb that decompresses to 2 GiB or more:
# the interpreter, the reader and one 64 MiB chunk (about 100 MiB measured).
MAX_RSS_MIB = 256
GOOD = Topic(1, '/chatter')


class Run:
    """What a replay child did: status, stdout and stderr lines, peak memory, ``this`` imported."""

    def __init__(self, result: subprocess.CompletedProcess) -> None:
        self.returncode = result.returncode
        lines = result.stdout.splitlines()
        report = lines.pop() if lines and lines[-1].startswith('replay_child:') else ''
        assert report, result.stdout + result.stderr
        facts = dict(word.split('=') for word in report.split()[1:])
        self.maxrss_mib = int(facts['maxrss_kib']) / 1024
        self.this_imported = facts['this_imported'] == 'True'
        self.stdout = lines
        self.stderr = result.stderr.splitlines()
        self.text = result.stdout + result.stderr


def replay(path, *args) -> Run:
    """Run replay on ``path`` in a child on a leased domain, at 20 times the recorded pace."""
    with lease_domain() as lease:
        result = subprocess.run(
            [sys.executable, str(CHILD), str(LIMIT_MIB), str(path), '--rate', '20', *args],
            env=ros_child_env(lease.domain_id), capture_output=True, text=True, timeout=120)
    return Run(result)


def assert_one_error_line(run: Run, *words: str) -> None:
    assert run.returncode == 2, run.text
    assert len(run.stderr) == 1 and run.stderr[0].startswith('replay: error: '), run.text
    for word in words:
        assert word in run.stderr[0], run.stderr[0]


# -- S1: types only from installed ROS interface packages ------------------------------


def test_a_schema_named_after_a_python_module_is_never_imported(tmp_path):
    """A 'this/Foo' schema: one line, exit 2; the Zen of Python never prints."""
    path = write_mcap(tmp_path / 'this.mcap', [Topic(2, '/zen', 'this/Foo')],
                      plain_messages(2, ['a', 'b']))
    run = replay(path)
    assert not run.this_imported and 'Zen of Python' not in run.text
    assert_one_error_line(run, 'nothing to replay', "'/zen'", 'this/Foo')


def test_a_topic_of_an_unknown_type_is_skipped_with_one_line(tmp_path):
    """Beside a playable topic, the unknown one is skipped by name and the rest plays (exit 0)."""
    path = write_mcap(tmp_path / 'this.mcap', [GOOD, Topic(2, '/zen', 'this/Foo')],
                      plain_messages(1, ['a', 'b']) + plain_messages(2, ['c']))
    run = replay(path)
    assert not run.this_imported and 'Zen of Python' not in run.text
    assert run.returncode == 0, run.text
    assert len(run.stderr) == 1 and run.stderr[0].startswith("replay: skipping '/zen': ")
    assert 'this/Foo' in run.stderr[0]
    assert run.stdout[-1] == 'replay: done, 2 messages'


# -- S2: bounded decompression -----------------------------------------------------------


@pytest.mark.parametrize('chunks', [
    pytest.param(lambda: [bomb_chunk(1, 2 * GIB)], id='one-2GiB-chunk'),
    pytest.param(lambda: [bomb_chunk(1, 2 * GIB, declared_size=MIB)], id='a-chunk-that-lies'),
    pytest.param(lambda: [bomb_chunk(1, 64 * MIB)] * 40, id='40-chunks-of-64MiB'),
])
def test_a_compression_bomb_is_refused_in_little_memory(tmp_path, chunks):
    """A file of about 70 KB that decompresses to 2 GiB or more: refused, with little memory."""
    path = write_mcap(tmp_path / 'bomb.mcap', [Topic(1, '/bomb')], chunks())
    assert path.stat().st_size < 100_000
    run = replay(path)
    assert_one_error_line(run, 'refused', 'compression bomb')
    assert run.maxrss_mib < MAX_RSS_MIB


def test_the_bound_of_one_pass_can_be_set(tmp_path):
    """``--max-gib``: the 337 KB a 2 s sink recording decompresses to is over 0.0001 GiB."""
    path = record(tmp_path / 'run.mcap', 2.0)[0]
    assert_one_error_line(replay(path, '--max-gib', '0.0001'), 'more than 107374 bytes')


# -- S2: what the metadata says ----------------------------------------------------------


def qos_text(**changes):
    text = offered_qos_profiles(QoSProfile(depth=10))
    for old, new in changes.items():
        text = text.replace(old, new)
    return text


BAD_TOPICS = [
    pytest.param(Topic(2, '/bad topic!!'), 'Invalid topic name', id='bad-name'),
    pytest.param(Topic(2, '/deep', qos_text=qos_text(**{'depth: 10': f'depth: {2**40}'})),
                 'depth 1099511627776 is out of range', id='depth-2**40'),
    pytest.param(Topic(2, '/late', qos_text=qos_text(**{'sec: 9223372036': f'sec: {2**70}'})),
                 'out of range', id='duration-2**70-s'),
    pytest.param(Topic(2, '/yaml', qos_text='- {depth: [unclosed'), 'not YAML', id='not-yaml'),
    pytest.param(Topic(2, '/list', qos_text='depth: 10'), 'not a list', id='not-a-list'),
]


@pytest.mark.parametrize('topic, why', BAD_TOPICS)
def test_a_topic_that_cannot_be_published_alone_is_one_line_and_status_2(tmp_path, topic, why):
    """Its name or QoS is impossible and nothing else is there: one line naming it, exit 2."""
    path = write_mcap(tmp_path / 'bad.mcap', [topic], plain_messages(2, ['a']))
    run = replay(path)
    assert_one_error_line(run, 'nothing to replay', repr(topic.topic))
    assert why in run.stderr[0]


@pytest.mark.parametrize('topic, why', BAD_TOPICS)
def test_a_topic_that_cannot_be_published_is_skipped_with_one_line(tmp_path, topic, why):
    """Beside a playable topic: one ``skipping`` line naming it, the rest plays, exit 0."""
    path = write_mcap(tmp_path / 'bad.mcap', [GOOD, topic],
                      plain_messages(1, ['a', 'b', 'c']) + plain_messages(2, ['d']))
    run = replay(path)
    assert run.returncode == 0, run.text
    assert len(run.stderr) == 1, run.text
    assert run.stderr[0].startswith(f'replay: skipping {topic.topic!r}: ')
    assert why in run.stderr[0]
    assert run.stdout[-1] == 'replay: done, 3 messages'


# -- S4: a recording whose recorder never closed it ------------------------------------


def record(path, duration_s):
    """Record ``duration_s`` of the sample drive with FoxgloveSink; return (path, samples)."""
    drive = samples(duration_s)
    with FoxgloveSink(record_path=path) as sink:
        channels = {t: sink.channel(t, *TOPICS[t]) for t in TOPICS}
        for sample in drive:
            channels[sample.topic].log(sample.data, sample.time_ns)
    return path, drive


def test_a_cut_off_recording_plays_what_it_holds_with_status_0(tmp_path):
    """Cut after its first 1 MiB chunk: every message of the complete chunk, one line, exit 0."""
    path, drive = record(tmp_path / 'run.mcap', 8.0)
    whole = path.read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(whole[:len(whole) * 3 // 4])
    recovered = len(complete_messages(cut))
    assert 0 < recovered < len(drive)
    run = replay(cut, '--rate', '50')
    assert run.returncode == 0, run.text
    assert len(run.stderr) == 1, run.text
    assert 'was cut short' in run.stderr[0] and 'killed?' not in run.stderr[0]
    assert f'recovered {recovered} messages' in run.stderr[0]
    assert run.stdout[-1] == f'replay: done, {recovered} messages'


@pytest.mark.parametrize('content', [
    pytest.param(b'\x89MCAP0\r\n', id='magic-only'),
    pytest.param(b'\x89MCAP0\r\n' + bytes(4096), id='magic-and-zeros'),
    pytest.param(b'\x89MCAP0\r\n' + random.Random(30).randbytes(4096), id='magic-and-garbage'),
    pytest.param('half-chunk', id='cut-inside-the-first-chunk'),
])
def test_a_file_with_nothing_to_recover_is_one_line_and_status_2(tmp_path, content):
    """Truncated to nothing, or garbage after a valid start: ``replay: error: ...``, exit 2."""
    path = tmp_path / 'nothing.mcap'
    if content == 'half-chunk':
        whole = record(tmp_path / 'run.mcap', 2.0)[0].read_bytes()
        content = whole[:len(whole) // 2]
    path.write_bytes(content)
    assert_one_error_line(replay(path), 'nothing to replay')
