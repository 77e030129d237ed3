"""
The farm runner against executors that fail: a fake executor, no simulator runs.

- the clean-up after Ctrl-C fails (a Dask worker going away: CommClosedError):
  the report of what finished is still written, the run is interrupted;
- the report directory cannot hold a report (``outcomes`` a file): one line;
- a controller or verdict that is a ``functools.partial`` or a callable object
  is the same farm in another process (a resume is not refused);
- a worker that cannot load the farm stops the run in one line (no variation
  reported crashed), and a resume runs again the variations an older runner
  reported crashed for that reason;
- a run of some seeds into a fuller directory counts and exits on what its
  report holds.
"""

import functools
import json
from pathlib import Path
import socket
import subprocess
import sys

import pytest

from r2d2_sim.farm import runner
from r2d2_sim.farm.job import describe, FarmJob, JobSource, run_variation, TaskResult
from r2d2_sim.farm.runner import FarmError, run_farm
from r2d2_sim.farm.scenario import Scenario, ScenarioSpace


def drive(harness, scenario):
    """Command nothing (these tests never run the controller)."""


SPACE = ScenarioSpace(obstacles=(0, 2))
JOB = FarmJob(SPACE, drive, seconds=1.0, name='idle')


def outcome_of(seed: int, passed: bool = True) -> dict:
    """Return an outcome's JSON for the report, as a run gives it."""
    return {'scenario': Scenario(seed=seed).to_dict(), 'passed': passed,
            'reason': '' if passed else 'touched box_0 at 1.000 s (base, 3 N)', 'seconds': 1.0,
            'time_to_goal_s': 0.5 if passed else None, 'clearance_m': 0.2, 'closest': 'box_0',
            'closest_s': 1.0, 'contacts': [], 'tipped_s': None,
            'trajectory': [[0, 0.0, 0.0, 0.0], [10**8, 0.1, 0.0, 0.0]], 'steps': 240,
            'wall_s': 0.1, 'recording': None}


class FakePool:
    """An executor that gives each item the result ``results`` says, then what it is told."""

    name = 'fake'

    def __init__(self, results=None, interrupt_after=None, clean_raises=None,
                 close_raises=None, payload=None):
        self.results = results or {}
        self.payload = payload  # run for real (a job whose loading fails runs nothing)
        self.interrupt_after = interrupt_after
        self.clean_raises = clean_raises
        self.close_raises = close_raises
        self.queue = []
        self.given = 0
        self.stopped = self.closed = False

    def start(self):
        """Start nothing."""

    def submit(self, items):
        """Queue the items."""
        self.queue += list(items)

    def pending(self):
        """Return what is queued."""
        return len(self.queue)

    def wait(self, timeout_s):
        """Give one item's result, or a Ctrl-C once ``interrupt_after`` were given."""
        if self.interrupt_after is not None and self.given >= self.interrupt_after:
            raise KeyboardInterrupt
        item = self.queue.pop(0)
        self.given += 1
        if self.payload is not None:
            return [(item, run_variation(self.payload, item, 'none'))]
        made = self.results.get(item.key, True)
        if isinstance(made, TaskResult):
            return [(item, made)]
        return [(item, TaskResult(item.key, item.seed, outcome_of(item.seed, made), None, None,
                                  None, None, socket.gethostname(), 1, 0.1))]

    def stop(self):
        """Drop the queue."""
        self.stopped = True
        self.queue.clear()

    def close(self):
        """Let go, or fail to."""
        self.closed = True
        if self.close_raises is not None:
            raise self.close_raises

    def clean_hosts(self):
        """Sweep, or fail to."""
        if self.clean_raises is not None:
            raise self.clean_raises
        return []


@pytest.fixture
def fake(monkeypatch):
    """Have the runner use the FakePool set in the returned list's first place."""
    pools = []
    monkeypatch.setattr(runner, 'choose', lambda *args, **kwargs: pools[0])
    return pools


def test_a_clean_up_that_fails_after_ctrl_c_still_writes_the_report(tmp_path, fake, capsys):
    """Dask's client.run on a worker going away raises CommClosedError (an OSError)."""
    fake.append(FakePool(interrupt_after=2, clean_raises=OSError('Stream is closed'),
                         close_raises=RuntimeError('the cluster is gone')))
    run = run_farm(JOB, variations=4, out=tmp_path, progress=False, picture=False)
    assert run.interrupted and run.exit_status == 130
    assert fake[0].stopped and fake[0].closed
    report = json.loads((tmp_path / 'report.json').read_text())
    assert report['summary']['runs'] == 2
    err = capsys.readouterr().err
    assert 'warning: the Fast DDS files of crashed tasks were not swept' in err
    assert 'Stream is closed' in err and 'the cluster is gone' in err


def test_outcomes_that_is_a_file_is_one_line(tmp_path, fake):
    fake.append(FakePool())
    (tmp_path / 'outcomes').write_text('not a folder')
    with pytest.raises(FarmError) as raised:
        run_farm(JOB, variations=1, out=tmp_path, progress=False)
    assert 'cannot hold a farm\'s report' in str(raised.value)
    assert 'outcomes' in str(raised.value) and '\n' not in str(raised.value)
    assert fake[0].closed  # started, so let go


# -- what counts as the same farm ---------------------------------------------------

def stopper(harness, scenario, stop_m=0.5):
    """Command nothing, at a distance (a controller with a parameter)."""


class Within:
    """A verdict object with a parameter and the default repr (an address in it)."""

    def __init__(self, metres):
        self.metres = metres

    def __call__(self, outcome):
        """Pass every run."""
        return ''


PARTIAL = FarmJob(SPACE, functools.partial(stopper, stop_m=0.3), seconds=1.0,
                  verdict=Within(0.2), name='partial')


def test_a_partial_and_a_callable_object_are_the_same_farm_in_another_process(tmp_path):
    here = describe(PARTIAL)
    assert '0x' not in json.dumps(here)
    assert here['controller'] == f'{__name__}:stopper(stop_m=0.3)'
    assert here['verdict'] == f'{__name__}:Within(metres=0.2)'
    other = FarmJob(SPACE, functools.partial(stopper, stop_m=0.4), seconds=1.0,
                    verdict=Within(0.2), name='partial')
    assert describe(other)['controller'] != here['controller']
    there = subprocess.run(
        [sys.executable, '-c', 'import json, sys; sys.path.insert(0, sys.argv[1]); '
         f'import {__name__} as t; from r2d2_sim.farm.job import describe; '
         'print(json.dumps(describe(t.PARTIAL)))', str(Path(__file__).parent)],
        capture_output=True, text=True, timeout=60)
    assert there.returncode == 0, there.stderr
    assert json.loads(there.stdout) == here


# -- a run of some seeds into a fuller directory -------------------------------------

def test_a_run_of_some_seeds_counts_and_exits_as_its_report_says(tmp_path, fake, capsys):
    """Seeds 0-3 ran before (1 and 3 failed); --seeds 0,2 reports, counts and exits on all 4."""
    from r2d2_sim.farm.__main__ import main
    fake.append(FakePool(results={1: False, 3: False}))
    out = str(tmp_path / 'report')
    assert main(['run', f'{__name__}:JOB', '--seeds', '0-3', '--out', out,
                 '--no-progress']) == 1
    fake[0] = FakePool()
    capsys.readouterr()
    assert main(['run', f'{__name__}:JOB', '--seeds', '0,2', '--out', out,
                 '--no-progress']) == 1
    said = capsys.readouterr().out
    assert ('4 variations reported (0 run now on fake, 2 resumed, 2 run before and not asked '
            'now): 2 passed, 2 failed, 0 crashed') in said, said
    report = json.loads((tmp_path / 'report' / 'report.json').read_text())
    assert report['summary']['runs'] == 4 and report['summary']['failed'] == 2
    fake[0] = FakePool()
    run = run_farm(JOB, seeds=[4], out=out, progress=False, picture=False)
    assert (run.ran, run.resumed, run.others) == (1, 0, 4)
    assert run.count('failed') == 2 and run.exit_status == 1 and len(run.records) == 5


# -- a farm the workers cannot load --------------------------------------------------

def test_a_farm_the_workers_cannot_load_stops_the_run_in_one_line(tmp_path, fake):
    """As the local pool says it: no variation is reported crashed for it."""
    farm = tmp_path / 'farm.py'
    farm.write_text('from r2d2_sim.farm import FarmJob, ScenarioSpace\n'
                    'def drive(harness, scenario):\n    pass\n'
                    'FARM = FarmJob(ScenarioSpace(), drive, seconds=1.0)\n')
    source = JobSource.parse(f'{farm}:FARM')
    broken = JobSource(str(tmp_path / 'missing_on_the_workers.py'), 'FARM')
    fake.append(FakePool(payload=broken))
    with pytest.raises(FarmError) as raised:
        run_farm(source, variations=3, out=tmp_path / 'report', progress=False)
    said = str(raised.value)
    assert said.startswith('a worker could not load the farm on ') and '\n' not in said
    assert 'missing_on_the_workers.py: no such file' in said
    assert fake[0].stopped and fake[0].closed
    lines = [p.read_text() for p in (tmp_path / 'report' / 'outcomes').glob('*.jsonl')]
    assert ''.join(lines) == ''


def test_a_resume_runs_again_what_an_older_runner_called_crashed_for_a_farm_not_loaded(
        tmp_path, fake, capsys):
    fake.append(FakePool())
    run_farm(JOB, variations=3, out=tmp_path, progress=False, picture=False)
    (path,) = (tmp_path / 'outcomes').glob('*.jsonl')
    records = [json.loads(line) for line in path.read_text().splitlines()]
    records[1].update(outcome=None, crashed={  # as a runner before 0.2.0 wrote it
        'reason': 'raised ScenarioError: /farms/farm.py: importing it raised ImportError: '
                  'no module named stopper', 'host': 'node2', 'pid': 7})
    path.write_text(''.join(json.dumps(r) + '\n' for r in records))
    fake[0] = FakePool()
    run = run_farm(JOB, variations=3, out=tmp_path, progress=False, picture=False)
    assert (run.ran, run.resumed) == (1, 2) and run.count('passed') == 3
    assert 'were a worker that could not load the farm' in capsys.readouterr().err
    report = json.loads((tmp_path / 'report.json').read_text())
    assert report['summary']['runs'] == 3 and report['summary']['crashed'] == 0


# -- SIGTERM outside the variations' run ---------------------------------------------

def terminate_me(*args, **kwargs):
    """Send this process SIGTERM, as a cancelled CI job does, and wait for it to land."""
    import os
    import signal
    import time
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(5)
    raise AssertionError('SIGTERM never landed')


def test_sigterm_while_shrinking_exits_143_with_the_counts(tmp_path, fake, monkeypatch, capsys):
    from r2d2_sim.farm import shrink
    from r2d2_sim.farm.__main__ import main
    fake.append(FakePool(results={1: False}))
    monkeypatch.setattr(shrink, 'shrink_failure', terminate_me)
    status = main(['run', f'{__name__}:JOB', '--variations', '2', '--shrink', '--out',
                   str(tmp_path), '--no-progress'])
    said = capsys.readouterr()
    assert status == 143, said.err
    assert 'interrupted: 2 variations reported' in said.out and '1 failed' in said.out
    assert (tmp_path / 'report.md').exists()


def test_sigterm_before_the_variations_run_exits_143(tmp_path, monkeypatch, capsys):
    """As while a Ray instance starts: run_farm gives no run back."""
    from r2d2_sim.farm.__main__ import main
    monkeypatch.setattr(runner, 'run_farm', terminate_me)
    status = main(['run', f'{__name__}:JOB', '--variations', '2', '--out', str(tmp_path)])
    assert status == 143
    assert capsys.readouterr().err.startswith('r2d2_sim.farm: interrupted')


# -- parameters ----------------------------------------------------------------------

def test_numpy_numbers_in_the_parameters_become_pythons_and_the_rest_is_one_line(tmp_path):
    import numpy
    from r2d2_sim.farm.scenario import ScenarioError
    job = FarmJob(SPACE, drive, seconds=1.0, parameters={
        'publish_rate': numpy.int64(50), 'physics_rate': numpy.float64(240.0),
        'gui': numpy.bool_(False), 'battery_dock_pose': (numpy.int32(1), 2.5, 0.0)})
    assert job.parameters == {'publish_rate': 50, 'physics_rate': 240.0, 'gui': False,
                              'battery_dock_pose': [1, 2.5, 0.0]}
    assert type(job.parameters['publish_rate']) is int
    assert json.dumps(describe(job))
    with pytest.raises(ScenarioError) as raised:
        FarmJob(SPACE, drive, seconds=1.0, parameters={'odd': object()})
    assert 'parameter odd: a object is no ROS parameter value' in str(raised.value)


def test_a_misspelled_simulator_parameter_is_one_line_before_anything_runs(tmp_path, capsys):
    """Inside each variation it failed every one of them: now the job refuses it, once."""
    from r2d2_sim.farm.scenario import ScenarioError
    with pytest.raises(ScenarioError, match=r'^unknown parameter scan_rat \(did you mean '
                                            r'scan_rate\?\)$'):
        FarmJob(SPACE, drive, seconds=1.0, parameters={'scan_rat': 10.0})
    with pytest.raises(ScenarioError, match=r'unknown parameter b\.scan_rate \(robots lists a\)'):
        FarmJob(SPACE, drive, seconds=1.0, parameters={'robots': ['a'], 'b.scan_rate': 1.0})
    FarmJob(SPACE, drive, seconds=1.0, parameters={'robots': ['a'], 'a.scan_rate': 1.0})
