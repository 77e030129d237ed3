"""
The kit's front ends as a user meets them: a run that checked nothing, a bad option, Ctrl-C.

The command line (``main``, in this process) and the pytest plugin (a pytest of its own, in a
child process) against the toy simulator of ``test/toy_simulator.py`` or against nobody: a run
that checked nothing is an error in both, never a pass; a bad option is one readable line.
"""

from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

import pytest

from helpers import next_domain_id
from r2d2_sim.client import ros_child_env, wait_for
from r2d2_sim.conformance import BY_ID, FAIL, Kit, KitError, KitOptions
from r2d2_sim.conformance.cli import main
from toy_simulator import S, ToySimulator

PYTEST_S = 120
TEST_FILE = 'from r2d2_sim.conformance.pytest_plugin import test_simulation_standard  # noqa\n'


def plugin_run(tmp_path: Path, domain: int, *args: str) -> subprocess.CompletedProcess:
    """Run pytest with the plugin on the ready-made test in a child process; return it."""
    (tmp_path / 'test_standard.py').write_text(TEST_FILE)
    return subprocess.run(
        [sys.executable, '-m', 'pytest', '-p', 'r2d2_sim.conformance.pytest_plugin',
         '-p', 'no:cacheprovider', '-p', 'no:xdist', '-q', '-rfEs', '--rootdir', str(tmp_path),
         *args, str(tmp_path / 'test_standard.py')],
        env=ros_child_env(domain), cwd=tmp_path, capture_output=True, text=True,
        timeout=PYTEST_S)


# -- a run that checked nothing -----------------------------------------------------------------

def test_an_absent_simulator_fails_feat_01_even_past_the_time_limit():
    """Nobody there, the run's time up during discovery: FEAT-01 fails, naming the real wait."""
    domain = next_domain_id()
    options = KitOptions(prefix='/nobody', domain_id=domain, timeout_s=2.0, total_timeout_s=0.5)
    with Kit(options) as kit:
        outcomes = kit.run([BY_ID['FEAT-01'], BY_ID['STATE-03']])
    assert outcomes[0].status == FAIL, outcomes[0]
    assert "within 0.5 s (the run's time limit)" in outcomes[0].reason, outcomes[0]
    assert kit.unchecked().startswith('nothing was checked: no service of type')


def test_a_command_line_run_whose_clauses_all_skip_exits_1(capsys):
    """Only FILTER-09, moot on the toy: no clause ran, so exit 1 and one line, never a pass."""
    domain = next_domain_id()
    with ToySimulator(domain):
        status = main(['--prefix', '/toy', '--domain', str(domain), '--asset', 'toy://box',
                       '--only', 'FILTER-09', '--timeout', '3'])
    err = capsys.readouterr().err
    assert status == 1, err
    assert err == ('sim_conformance: error: nothing was checked: all clauses skipped '
                   '(1 chosen)\n'), err


def test_the_plugin_fails_every_clause_when_no_simulator_is_there(tmp_path):
    """-k picks some clauses, nobody answers: they fail (not skip), and pytest exits 1."""
    result = plugin_run(tmp_path, next_domain_id(), '-k', 'STATE-01 or STATE-02',
                        '--conformance-prefix', '/nobody', '--conformance-timeout', '1')
    assert result.returncode == 1, result.stdout[-3000:] + result.stderr[-2000:]
    assert '2 failed' in result.stdout and 'skipped' not in result.stdout, result.stdout[-3000:]
    assert 'nothing was checked: no service of type GetSimulatorFeatures' in result.stdout


def test_the_plugin_fails_a_session_whose_clauses_all_skip(tmp_path):
    """Only FILTER-09, moot on the toy: one skipped test, and the session fails with a line."""
    domain = next_domain_id()
    with ToySimulator(domain):
        result = plugin_run(tmp_path, domain, '-k', 'FILTER-09', '--conformance-prefix', '/toy',
                            '--conformance-asset', 'toy://box', '--conformance-timeout', '3')
    assert result.returncode == 1, result.stdout[-3000:] + result.stderr[-2000:]
    assert '1 skipped' in result.stdout, result.stdout[-3000:]
    assert 'conformance: nothing was checked: all clauses skipped (1 chosen)' in result.stdout


# -- bad options --------------------------------------------------------------------------------

def test_an_output_the_kit_cannot_write_is_refused_before_it_connects(capsys, tmp_path):
    """--junit in no directory, --markdown on a directory: one line, status 2, nothing run."""
    for argv, says in ((['--junit', '/nonexistent/dir/out.xml'],
                        '--junit /nonexistent/dir/out.xml: no such directory /nonexistent/dir'),
                       (['--markdown', str(tmp_path)], f'--markdown {tmp_path}: is a directory')):
        assert main(argv + ['--prefix', '/nobody', '--timeout', '5']) == 2
        out, err = capsys.readouterr()
        assert out == '' and err == f'sim_conformance: error: {says}\n', (out, err)


@pytest.mark.parametrize('option', ['--junit', '--markdown'])
def test_an_output_whose_write_fails_is_named_in_one_line(capsys, option):
    """A full disk (/dev/full): the line names the file the user gave, status 2."""
    status = main([option, '/dev/full', '--prefix', '/nobody', '--domain',
                   str(next_domain_id()), '--only', 'FEAT-01', '--timeout', '1'])
    err = capsys.readouterr().err
    assert status == 2, err
    assert err.splitlines()[-1] == ('sim_conformance: error: cannot write /dev/full: No space '
                                    'left on device'), err


@pytest.mark.parametrize('world', ['yard', None])
def test_a_world_the_simulator_refuses_exits_2_with_one_setup_line(capsys, world):
    """
    --world naming no world of the toy's: the user's mistake (status 2), not the toy's.

    Also where the toy had no world, so that nothing could be checked: the
    setup line comes first, and the status is still 2.
    """
    domain = next_domain_id()
    with ToySimulator(domain, world=world):
        status = main(['--prefix', '/toy', '--domain', str(domain), '--asset', 'toy://box',
                       '--world', 'toy://worlds/nowhere', '--only', 'STATE-03,WORLD-04',
                       '--timeout', '3'])
    out, err = capsys.readouterr()
    assert status == 2, out + err
    lines = err.splitlines()
    assert lines[0] == ("sim_conformance: error: the world given, 'toy://worlds/nowhere', could "
                        "not be loaded: LoadWorld answered NO_RESOURCE (102): 'no world "
                        "toy://worlds/nowhere'"), err
    if world is None:
        assert lines[1:] == ['sim_conformance: error: nothing was checked: all clauses skipped '
                             '(2 chosen)'], err
        assert '2 clauses: 0 passed, 0 failed, 2 skipped' in out, out
    else:
        assert lines[1:] == [] and '2 clauses: 1 passed, 0 failed, 1 skipped' in out, out


@pytest.mark.parametrize('field, value, says', [
    ('timeout_s', -1.0, 'timeout_s must be a finite number of seconds > 0'),
    ('timeout_s', float('nan'), 'timeout_s must be a finite number of seconds > 0'),
    ('timeout_s', 0.0, 'timeout_s must be a finite number of seconds > 0'),
    ('total_timeout_s', 0.0, 'total_timeout_s must be a finite number of seconds > 0'),
    ('total_timeout_s', float('inf'), 'total_timeout_s must be a finite number of seconds > 0'),
    ('domain_id', 999, 'domain_id must be in 0..231, got 999'),
    ('clock_topic', 'bad topic!', "clock_topic 'bad topic!': topic name must not contain"),
    ('prefix', '/bad prefix!', "prefix '/bad prefix!': namespace must not contain"),
])
def test_the_api_refuses_a_bad_option_in_one_line(field, value, says):
    """A timeout not above 0 or not finite, a domain id past 231, a bad name: one KitError line."""
    with pytest.raises(KitError) as refused:
        Kit(KitOptions(**{field: value}))
    assert says in str(refused.value) and '\n' not in str(refused.value), refused.value


@pytest.mark.parametrize('value, says', [('-3', 'must be in 0..231, got -3'),
                                         ('999', 'must be in 0..231, got 999'),
                                         ('abc', "must be an integer, got 'abc'")])
def test_a_bad_ros_domain_id_is_one_line_and_status_2(monkeypatch, capsys, value, says):
    """ROS_DOMAIN_ID -3 or 999 (Fast DDS would end the process in lines of its own): one line."""
    monkeypatch.setenv('ROS_DOMAIN_ID', value)
    assert main(['--only', 'FEAT-01']) == 2
    err = capsys.readouterr().err
    assert err == f'sim_conformance: error: ROS_DOMAIN_ID {says}\n', err


@pytest.mark.parametrize('option, value', [('--conformance-timeout', '-1'),
                                           ('--conformance-timeout', 'nan'),
                                           ('--conformance-total-timeout', '0'),
                                           ('--conformance-domain', '999')])
def test_the_plugin_takes_only_good_numbers(tmp_path, option, value):
    """A timeout not above 0, a domain id past 231: pytest's usage error, a line naming it."""
    result = plugin_run(tmp_path, next_domain_id(), option, value)
    assert result.returncode == pytest.ExitCode.USAGE_ERROR, result.stdout + result.stderr
    assert f'argument {option}: must be' in result.stderr, result.stderr
    assert 'Traceback' not in result.stdout + result.stderr


def test_the_plugin_reports_what_it_could_not_put_back(tmp_path):
    """A toy that cannot stop once playing: the kit cannot leave it as found, and says so."""
    domain = next_domain_id()
    with ToySimulator(domain, defect='STATE-05'):
        result = plugin_run(tmp_path, domain, '-k', 'STATE-03', '--conformance-prefix', '/toy',
                            '--conformance-asset', 'toy://box', '--conformance-timeout', '3')
    assert result.returncode == 1, result.stdout[-3000:] + result.stderr[-2000:]
    assert '1 passed' in result.stdout and '1 error' in result.stdout, result.stdout[-3000:]
    assert 'could not leave the simulator as found: SetSimulationState' in result.stdout, (
        result.stdout[-3000:])


# -- Ctrl-C ------------------------------------------------------------------------------------

class KitProcess:
    """``python -m r2d2_sim.conformance`` in a child process, its lines read as they come."""

    def __init__(self, domain: int, *args: str) -> None:
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'r2d2_sim.conformance', '--prefix', '/toy', '--asset',
             'toy://box', *args], env=ros_child_env(domain), stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True)
        self.lines = {'out': [], 'err': []}
        self.changed = threading.Condition()
        self.readers = [threading.Thread(target=self._read, args=(stream, name), daemon=True)
                        for stream, name in ((self.process.stdout, 'out'),
                                             (self.process.stderr, 'err'))]
        for reader in self.readers:
            reader.start()

    def _read(self, stream, name: str) -> None:
        for line in stream:
            with self.changed:
                self.lines[name].append(line.rstrip('\n'))
                self.changed.notify_all()

    def wait_for(self, name: str, text: str, timeout_s: float = 60.0) -> None:
        """Wait (by deadline) until a line of ``name`` ('out', 'err') holds ``text``."""
        with self.changed:
            seen = self.changed.wait_for(
                lambda: any(text in line for line in self.lines[name]), timeout_s)
        assert seen, (text, self.lines)

    def interrupt(self) -> None:
        """Send Ctrl-C (SIGINT); return once the kit says it puts the simulator back."""
        self.process.send_signal(signal.SIGINT)
        self.wait_for('err', 'interrupted: leaving the simulator as found')

    def end(self, timeout_s: float = 60.0) -> int:
        """Wait for the process to end; return its exit status (its output all read)."""
        status = self.process.wait(timeout=timeout_s)
        for reader in self.readers:
            reader.join(timeout=timeout_s)
        return status


INTERRUPTED = ('sim_conformance: interrupted: leaving the simulator as found (Ctrl-C again to '
               'leave it as it is)')


def kit_held_by(toy: ToySimulator, domain: int, only: str) -> KitProcess:
    """Run the kit on ``only``'s clauses; return it once the toy holds a reply to it."""
    kit = KitProcess(domain, '--only', only, '--timeout', '20')
    assert wait_for(lambda: toy.held, 60.0), kit.lines
    return kit


def spawned_by_the_kit(toy: ToySimulator):
    """Return the names of the entities the kit spawned on the toy, sorted."""
    with toy.lock:
        return sorted(n for n in toy.entities if n.startswith('conformance_'))


def test_ctrl_c_leaves_the_simulator_as_found():
    """
    Ctrl-C while a spawning clause waits for a reply: the toy is PLAYING again, nothing left.

    The toy holds GetEntities' replies (SPAWN-01 lists what it spawned) until the signal
    is sent, so that the kit is surely in the middle of a clause, whatever the load.
    """
    domain = next_domain_id()
    with ToySimulator(domain, hold='GetEntities') as toy:
        toy.state = S.STATE_PLAYING
        kit = kit_held_by(toy, domain, 'SPAWN,ENTITY')
        during = (toy.state, spawned_by_the_kit(toy))
        kit.process.send_signal(signal.SIGINT)
        toy.release.set()
        status = kit.end()
        after = (toy.state, spawned_by_the_kit(toy))
    assert during[0] == S.STATE_STOPPED and len(during[1]) == 1, during  # the run changed it
    assert status == 130, kit.lines
    assert kit.lines['err'] == [INTERRUPTED], kit.lines['err']
    assert after == (S.STATE_PLAYING, []), after


def test_a_second_ctrl_c_skips_putting_the_simulator_back():
    """
    Ctrl-C, then Ctrl-C again while the kit puts the toy back: the kit ends at once.

    The toy holds every SetSimulationState (STATE-01's STOPPED) until the end: both
    signals surely come while the kit waits for its reply, first to run STATE-01, then to
    put the toy back (the restore begins with it).
    """
    domain = next_domain_id()
    with ToySimulator(domain, hold='SetSimulationState') as toy:
        toy.state = S.STATE_PLAYING
        kit = kit_held_by(toy, domain, 'STATE')
        kit.interrupt()
        kit.process.send_signal(signal.SIGINT)
        started = time.monotonic()
        status = kit.end()
        took = time.monotonic() - started
    assert status == 130, kit.lines
    assert kit.lines['err'] == [INTERRUPTED, 'sim_conformance: interrupted again: the '
                                'simulator was left as it is'], kit.lines['err']
    assert took < 5.0, took  # the restore would wait for its reply for 20 s


def test_ctrl_c_while_the_kit_puts_the_simulator_back_lets_it_finish():
    """
    One Ctrl-C during the clean-up after the last clause: the restore goes on, then 130.

    FEAT-01 only asks; the first SetSimulationState is the restore's, held by the toy
    until the signal is sent.
    """
    domain = next_domain_id()
    with ToySimulator(domain, hold='SetSimulationState') as toy:
        toy.state = S.STATE_PLAYING
        kit = kit_held_by(toy, domain, 'FEAT-01')
        kit.interrupt()
        toy.release.set()
        status = kit.end()
        after = toy.state
    assert status == 130, kit.lines
    assert kit.lines['err'] == [INTERRUPTED], kit.lines['err']
    assert after == S.STATE_PLAYING, after
