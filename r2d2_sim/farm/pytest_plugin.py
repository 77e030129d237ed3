"""
The farm under pytest: the ``r2d2_farm`` fixture, the outcomes of every worker, one report.

Opt-in: installed (pip, colcon), pytest loads it (a ``pytest11`` entry point,
like :mod:`r2d2_sim.pytest_plugin`); from a source tree run pytest with
``-p r2d2_sim.farm.pytest_plugin``, or name it in ``pytest_plugins`` of your
top ``conftest.py``. It must be loaded in pytest's main process: under
pytest-xdist that process writes the report, and it never imports test modules.

- ``r2d2_farm.run(scenario, controller, seconds=..., ...)`` runs a scenario
  (:func:`r2d2_sim.farm.run.run_scenario`; same keywords), records its
  outcome for the report and returns it. A failed run is run again recording
  its MCAP into the farm directory, and must come out the same (else
  :class:`~r2d2_sim.farm.run.DeterminismError`). Session-scoped, so
  Hypothesis's ``@given`` tests may use it: there, only the final (shrunk)
  example of a failing property is reported, always recorded, with its
  scenario in the failure's notes. A run that raises is reported crashed.
  The report's pass or fail of a run is its verdict's and its test's: a test
  that fails on its own (an assertion, every verdict passed) fails its runs.
- ``--farm-dir DIR``: where outcomes, recordings and the report go (default
  ``farm_report`` under pytest's base temporary directory). Each xdist worker
  appends its outcomes there; at the end the main process writes
  ``report.md``, ``report.json`` and ``trajectories.png`` and names them in
  the summary. Files of an earlier farm in that directory are removed first.
  One directory per pytest session: CI shards (pytest-split) each write their
  own report of their own cases.
- ``--farm-record DIR``: record every farm run into DIR, passed or not (of a
  property, its final example; what ``python -m r2d2_sim.farm rerun`` uses).

This module imports neither rclpy nor PyBullet until a run is asked for.
"""

import hashlib
import json
import os
from pathlib import Path
import re
import traceback
import warnings
from typing import Any, Dict, Generator, List, Optional, TYPE_CHECKING

import pytest

if TYPE_CHECKING:  # typing only: nothing heavy is imported until a run is asked for
    import r2d2_sim.farm.run  # its Outcome named in full: the docs know two others
    from r2d2_sim.farm.run import Controller
    from r2d2_sim.farm.scenario import Scenario

__all__ = ['Farm', 'r2d2_farm']

FARM_KEY = pytest.StashKey['Farm']()
WORKER_INPUT_KEY = 'r2d2_farm_dir'
OUTCOMES = 'outcomes'
RECORDINGS = 'recordings'
SCENARIOS = 'scenarios'
DEFAULT_DIR_NAME = 'farm_report'


def pytest_addoption(parser: pytest.Parser) -> None:
    """Add --farm-dir and --farm-record."""
    group = parser.getgroup('r2d2_farm', 'r2d2_sim scenario farm')
    group.addoption('--farm-dir', metavar='DIR', default=None,
                    help='directory of the farm\'s outcomes, failure recordings and report '
                    '(default: farm_report under pytest\'s base temporary directory)')
    group.addoption('--farm-record', metavar='DIR', default=None,
                    help='record every farm run (not only failures) into DIR')


def _slug(nodeid: str) -> str:
    """
    Return a file name of a node id, unique to it: its readable part and a hash of it whole.

    The readable part (folders, file, test name, parameters) is cut to fit and
    may be shared (``nav/test_farm.py::test[0]`` and ``nav-test_farm.py::test[0]``,
    or two long ids alike at first); the hash of the whole id is not. Each node
    id runs in one process, under xdist too, so its name is never taken by another.
    """
    readable = nodeid.replace('.py::', '-').replace('::', '-')
    readable = re.sub(r'[^A-Za-z0-9_.=-]+', '-', readable).strip('-.')[:80].rstrip('-.')
    digest = hashlib.sha256(nodeid.encode('utf-8')).hexdigest()[:10]
    return f'{readable or "case"}-{digest}'


class Farm:
    """
    The farm of one pytest process: runs scenarios, keeps their outcomes, writes the report.

    ``config`` is pytest's. In the main process (or without xdist) it owns
    the farm directory (cleared of an earlier farm's files when first used);
    in a worker it appends to that directory.
    """

    def __init__(self, config: pytest.Config) -> None:
        self.config = config
        self.worker: Optional[str] = None
        self._directory: Optional[Path] = None
        self._runs: Dict[str, int] = {}  # node id -> runs so far
        self._first_failures: Dict[str, Any] = {}  # node id -> a property's first failing scenario
        self._pending: Dict[str, List[Dict[str, Any]]] = {}  # node id -> records, result unknown
        self.written: Dict[str, Path] = {}
        self._orphan = False  # a worker whose main process has no farm: no report
        workerinput = getattr(config, 'workerinput', None)
        if workerinput is not None:
            self.worker = workerinput.get('workerid', 'gw')
            given = workerinput.get(WORKER_INPUT_KEY)
            self._directory = Path(given) if given else None
            self._orphan = not given
        record = config.getoption('farm_record', None)
        self.record_dir = Path(record).resolve() if record else None

    @property
    def directory(self) -> Path:
        """Return where the farm writes (made, and cleared of an earlier farm, on first use)."""
        if self._directory is None:
            given = self.config.getoption('farm_dir', None)
            if given:
                directory = Path(given).resolve()
            else:
                # pytest's TempPathFactory: its tmp_path plugin sets it on the config, undeclared.
                directory = (self.config._tmp_path_factory  # type: ignore[attr-defined]
                             .getbasetemp() / DEFAULT_DIR_NAME)
            if self.worker is None:
                _clear(directory)
            self._directory = directory
        return self._directory

    def _outcomes_file(self) -> Path:
        folder = self.directory / OUTCOMES
        folder.mkdir(parents=True, exist_ok=True)
        return folder / f'{self.worker or "main"}-{os.getpid()}.jsonl'

    def run(self, scenario: 'Scenario', controller: 'Controller', *, seconds: float,
            **keywords: Any) -> 'r2d2_sim.farm.run.Outcome':
        """
        Run ``scenario`` (see :func:`~r2d2_sim.farm.run.run_scenario`); record and return it.

        The outcome is appended to this process's outcomes file with the
        calling test's node id. In a Hypothesis test, only the final example
        of a failing property is recorded (its scenario saved as JSON and
        noted in the failure with its seed and recording). A run that raises
        is recorded as crashed (what it raised, the traceback, the scenario),
        and the exception goes on to fail the test.
        """
        from r2d2_sim.farm.run import run_scenario
        if self._orphan:
            self._orphan = False
            warnings.warn('r2d2_farm: pytest\'s main process has not loaded the farm plugin, '
                          'so no report will be written: run pytest with '
                          '-p r2d2_sim.farm.pytest_plugin (or name it in your top conftest.py)')
        nodeid = os.environ.get('PYTEST_CURRENT_TEST', 'unknown').rsplit(' (', 1)[0]
        final = _hypothesis_final()
        exploring = final is False
        run = self._runs.get(nodeid, 0)
        self._runs[nodeid] = run + 1
        name = _slug(nodeid) + (f'-{run}' if run else '')
        record = record_failure = None
        if exploring:
            pass  # Hypothesis is still searching: only its final example is kept
        elif self.record_dir is not None or final:
            # A property's final example is run only because its test failed, maybe on
            # the test's own assertion with a passing verdict: it is always recorded.
            folder = self.record_dir or self.directory / RECORDINGS
            folder.mkdir(parents=True, exist_ok=True)
            record = str(folder / f'{name}.mcap')
        else:
            folder = self.directory / RECORDINGS
            folder.mkdir(parents=True, exist_ok=True)
            record_failure = str(folder / f'{name}.mcap')
        # The node id is relative to this process's rootdir, which may not be the main
        # process's: pytest chose it from the command line before it knew --farm-dir.
        line: Dict[str, Any] = {'nodeid': nodeid, 'rootdir': str(self.config.rootpath),
                                'run': run, 'worker': self.worker or '',
                                'property': final is True}
        try:
            outcome = run_scenario(scenario, controller, seconds=seconds, record=record,
                                   record_failure=record_failure, **keywords)
        except Exception as exc:
            # No verdict (the user's node raised in a callback, the verdict raised, the
            # simulator refused a parameter): a crashed case, so that the report does not
            # count it among none; the test fails with the exception, as without the farm.
            if not exploring:
                self._keep(dict(line, outcome=None, scenario=scenario.to_dict(), crashed={
                    'reason': 'raised ' + f'{type(exc).__name__}: {exc}'.splitlines()[0],
                    'seed': scenario.seed, 'traceback': traceback.format_exc()}))
            raise
        if exploring:
            if not outcome.passed:
                self._first_failures.setdefault(nodeid, outcome.scenario)
            return outcome
        line['outcome'] = outcome.to_dict()
        first = self._first_failures.get(nodeid)
        if final and first is not None:
            line['first_failure'] = first.to_dict()
        self._keep(line)
        if final:
            self._note(name, nodeid, outcome)
        return outcome

    def _keep(self, line: Dict[str, Any]) -> None:
        """Keep a record until its test's result is known (:meth:`test_done`)."""
        self._pending.setdefault(line['nodeid'], []).append(line)

    def test_done(self, report: pytest.TestReport) -> None:
        """
        Write the records of a test that has its result, with that result merged in.

        ``test``: ``failed``, ``when`` (setup, call, teardown), ``message`` (the
        failure's first line) and ``own``: it failed while every run's verdict
        passed, so on its own (an assertion of the test's), which fails those
        runs in the report; a failed verdict or a crash explains a failure
        otherwise, and the test's other runs keep their verdicts. A passed setup
        leaves the records waiting for the call.
        """
        if report.when == 'setup' and not report.failed:
            return
        lines = self._pending.pop(report.nodeid, None)
        if not lines:
            return
        message = ''
        if report.failed:
            crash = getattr(report.longrepr, 'reprcrash', None)
            text = str(getattr(crash, 'message', None) or report.longrepr or 'failed')
            message = (text.strip().splitlines() or ['failed'])[0][:200]
        own = report.failed and all(line['outcome'] is not None and line['outcome']['passed']
                                    for line in lines)
        for line in lines:
            line['test'] = {'failed': report.failed, 'when': report.when, 'message': message,
                            'own': own}
        self._write(lines)

    def flush(self) -> None:
        """Write the records still waiting for a result (of a session cut short): without one."""
        for nodeid in list(self._pending):
            self._write(self._pending.pop(nodeid))

    def _write(self, lines: List[Dict[str, Any]]) -> None:
        """Append records to this process's outcomes file."""
        with open(self._outcomes_file(), 'a', encoding='utf-8') as out:
            out.writelines(json.dumps(line, sort_keys=True) + '\n' for line in lines)

    def _note(self, name: str, nodeid: str, outcome: 'r2d2_sim.farm.run.Outcome') -> None:
        """Save a property's shrunk scenario and say in the failure how to replay it."""
        from hypothesis import note
        from r2d2_sim.farm.strategies import REPLAY_ENV
        folder = self.directory / SCENARIOS
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f'{name}.json'
        path.write_text(outcome.scenario.to_json() + '\n', encoding='utf-8')
        first = self._first_failures.get(nodeid)
        if first is not None:
            note(f'r2d2_farm: the first failing scenario had {_boxes(first)}: '
                 f'{first.to_json()}')
        verdict = outcome.reason or 'the verdict passed: the test failed on its own'
        note(f'r2d2_farm: the shrunk scenario (seed {outcome.scenario.seed}, '
             f'{_boxes(outcome.scenario)}) {outcome.scenario.to_json()}\n'
             f'r2d2_farm: {verdict}; recording: {outcome.recording}\n'
             f'r2d2_farm: replay it: {REPLAY_ENV}={path} pytest \'{nodeid}\' '
             f'-p r2d2_sim.farm.pytest_plugin --farm-record DIR '
             '(or python -m r2d2_sim.farm rerun on the report)')

    def records(self) -> List[Dict[str, Any]]:
        """Return every outcome record of this farm directory (all workers')."""
        folder = self.directory / OUTCOMES
        records = []
        for path in sorted(folder.glob('*.jsonl')) if folder.is_dir() else ():
            for line in path.read_text(encoding='utf-8').splitlines():
                if line.strip():
                    records.append(json.loads(line))
        return records

    def write_report(self) -> Dict[str, Path]:
        """Write the report of every outcome recorded (nothing when there are none)."""
        if self._directory is None and self.worker is None and not self.config.getoption(
                'farm_dir', None):
            return {}  # no farm ran in this session: nothing made, nothing to report
        records = self.records()
        if not records:
            return {}
        from r2d2_sim.farm.report import write_report
        self.written = write_report(records, self.directory,
                                    invocation_dir=str(self.config.invocation_params.dir),
                                    rootdir=str(self.config.rootpath))
        return self.written


def _boxes(scenario: 'Scenario') -> str:
    count = len(scenario.obstacles)
    return f'{count} box' if count == 1 else f'{count} boxes'


def _clear(directory: Path) -> None:
    """Remove an earlier farm's files from ``directory`` (only the files a farm writes)."""
    from r2d2_sim.farm.report import REPORT_JSON, REPORT_MD, TRAJECTORIES_PNG
    for folder, pattern in ((OUTCOMES, '*.jsonl'), (RECORDINGS, '*.mcap'),
                            (SCENARIOS, '*.json')):
        for path in (directory / folder).glob(pattern):
            path.unlink()
    for name in (REPORT_JSON, REPORT_MD, TRAJECTORIES_PNG):
        (directory / name).unlink(missing_ok=True)
    directory.mkdir(parents=True, exist_ok=True)


def _hypothesis_final() -> Optional[bool]:
    """Return None outside a Hypothesis test, else whether this is its final (shrunk) example."""
    import sys
    if 'hypothesis' not in sys.modules:
        return None
    import hypothesis
    from hypothesis.control import current_build_context
    if not hypothesis.currently_in_test_context():
        return None
    return bool(current_build_context().is_final)


def pytest_configure(config: pytest.Config) -> None:
    """Make this process's farm."""
    config.stash[FARM_KEY] = Farm(config)


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node: Any) -> None:
    """Tell an xdist worker the farm directory of the main process (xdist's hook)."""
    node.workerinput[WORKER_INPUT_KEY] = str(node.config.stash[FARM_KEY].directory)


# Outermost (tryfirst), so that it sees the report as pytest's other plugins leave it (xfail).
@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]
                              ) -> Generator[None, pytest.TestReport, pytest.TestReport]:
    """Write the farm's records of a test with its result (in the process that ran it)."""
    report = yield
    farm = item.config.stash.get(FARM_KEY, None)
    if farm is not None:
        farm.test_done(report)
    return report


def pytest_sessionfinish(session: pytest.Session) -> None:
    """Write what waits for a result; in the main process, the report of every worker's."""
    farm = session.config.stash.get(FARM_KEY, None)
    if farm is not None:
        farm.flush()
        if farm.worker is None:
            farm.write_report()


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter,
                            config: pytest.Config) -> None:
    """Name the report files."""
    farm = config.stash.get(FARM_KEY, None)
    if farm is not None and farm.written:
        terminalreporter.write_sep('-', 'r2d2 farm report')
        for path in farm.written.values():
            terminalreporter.write_line(str(path))


@pytest.fixture(scope='session')
def r2d2_farm(request: pytest.FixtureRequest) -> Farm:
    """Provide the farm: ``r2d2_farm.run(scenario, controller, seconds=...)`` -> Outcome."""
    return request.config.stash[FARM_KEY]
