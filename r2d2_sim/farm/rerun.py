"""
Rerunning a farm's case from its report: the project's own test, recorded, checked against it.

``python -m r2d2_sim.farm rerun report.json --case N`` (:func:`rerun`) runs
the case's test again with its scenario replayed (``R2D2_FARM_REPLAY``: a
Hypothesis property draws just that scenario; a seeded test draws it from its
seed anyway), records every run and checks the run that is the case's comes
out as the report says, measure for measure. A case whose run raised (crashed)
has no outcome to compare with: its scenario runs again and what it does is
printed.

**What runs is the project's, never the report's.** A report may come from a
colleague or from CI; the code it names is not trusted. The rerun runs a test
file of the project it is started in (``--project DIR``, default the current
directory) and nothing above it: the case's file where the report says when
that lies inside the project, else the longest tail of its path that is a
file of the project (a report from another checkout finds its test here);
else it refuses, in one line, before anything runs. pytest runs in the
project with ``--rootdir`` and ``--confcutdir`` the project, so neither the
report's directories nor a ``conftest.py`` above the project is imported; the
rerun names the test and the ``conftest.py`` files it will run first.

**A case of the farm runner** (``python -m r2d2_sim.farm run``: its record
names the farm, ``FILE.py:NAME`` or ``MODULE:NAME``, and the variation's
seed) runs again in this process (:func:`rerun_farm_case`), recorded; the
farm's file must be a file of the project, as a test's must. A crashed
case has no outcome to compare with: its new outcome is printed.

**Which run is the case's.** A node id is relative to the rootdir of the
pytest process that ran it, which each record keeps: pytest chooses it from
the command line before the farm plugin's options are known, so a separate
value (``--farm-dir ../shard1``) counts as a path, and xdist's workers (which
find that directory made) may choose another than their main process. Runs
are compared by the test file and name they resolve to, not by node id. A
seeded test's case is the run of the same number; a property's, the run of
the same rank in its final (shrunk) example.
"""

import json
import os
from pathlib import Path, PurePosixPath
import shutil
import subprocess
import sys
import tempfile
from typing import Any, Dict, List, Optional, Sequence, Tuple

__all__ = ['ReportError', 'rerun', 'load_case', 'locate', 'same_run', 'read_records',
           'conftests', 'rerun_farm_case']

PLUGIN = 'r2d2_sim.farm.pytest_plugin'
# A test: its file (resolved) and its name in the file, as after '::' in a node id.
Where = Tuple[Path, str]


class ReportError(Exception):
    """A report, case or farm directory that cannot be used: one line, exit status 2."""


def load_case(report: Path, number: int) -> Dict[str, Any]:
    """
    Return case ``number`` of ``report``, with its ``rootdir`` and its ``ordinal``.

    ``rootdir``: the one its node id is relative to (the record's, else the
    report's, for reports written before records kept theirs). ``ordinal``:
    for a property's case, its rank among its test's cases (the final
    example's runs, in order); 0 otherwise.
    """
    try:
        data = json.loads(report.read_text(encoding='utf-8'))
        cases = data['cases']
        case = dict(cases[number]) if 0 <= number < len(cases) else None
        if case is not None:
            nodeid, prop, run = case['nodeid'], bool(case['property']), int(case['run'])
            ranks = sorted(int(c['run']) for c in cases
                           if c['nodeid'] == nodeid and bool(c['property']) == prop)
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ReportError(f'{report}: not a farm report ({type(exc).__name__}: {exc})')
    if case is None:
        raise ReportError(f'{report} has cases 0..{len(cases) - 1}, not {number}')
    case['rootdir'] = case.get('rootdir') or data.get('rootdir')
    case['ordinal'] = ranks.index(run) if prop else 0
    return case


def locate(case: Dict[str, Any], project: Path) -> Where:
    """
    Return the project's file of ``case``'s test and the test's name in it.

    ``project`` is resolved. The report's own path first (its rootdir and
    node id), then the tails of the node id's path under the project, longest
    first: the first that is a file inside the project (symbolic links
    followed). ReportError (one line) when none is.
    """
    path, _, name = str(case['nodeid']).partition('::')
    if path.endswith('.osc'):
        again = case.get('rerun') or 'python -m r2d2_sim.osc'
        raise ReportError(f'case {case.get("case")} is the OpenSCENARIO variation {name}, not '
                          f'a pytest test: run it again with {again}')
    parts = [part for part in PurePosixPath(path).parts if part != '/']
    candidates = [Path(case['rootdir'], path)] if case.get('rootdir') else []
    candidates += [project.joinpath(*parts[first:]) for first in range(len(parts))]
    for candidate in candidates:
        try:
            found = candidate.resolve()
        except (OSError, RuntimeError):  # a loop of links: not a file of the project
            continue
        if found.is_relative_to(project) and found.suffix == '.py' and found.is_file():
            return found, name
    where = f' (in {case["rootdir"]})' if case.get('rootdir') else ''
    raise ReportError(f'case {case.get("case")}\'s test {path}{where} is not a file of this '
                      f'project ({project}): rerun from the project\'s directory, or name it '
                      'with --project DIR')


def conftests(project: Path, test_file: Path) -> List[Path]:
    """Return the conftest.py files pytest loads for ``test_file`` (``--confcutdir`` project)."""
    folders = [test_file.parent, *test_file.parent.parents]
    found = [folder / 'conftest.py' for folder in folders[:folders.index(project) + 1]]
    return [path for path in reversed(found) if path.is_file()]


def read_records(directory: Path) -> List[Dict[str, Any]]:
    """
    Return the outcome records of a farm directory (outcomes/*.jsonl), file by file.

    A file's last line cut short (a run killed, or a disk full, while it was
    written) is left out, said once on stderr: that variation runs again on
    a resume. Any other line that is not a record is a ReportError (one line).
    """
    records = []
    for path in sorted((directory / 'outcomes').glob('*.jsonl')):
        try:
            lines = [line for line in path.read_text(encoding='utf-8').splitlines()
                     if line.strip()]
        except (OSError, UnicodeDecodeError) as exc:
            raise ReportError(f'{path}: cannot be read: {exc}') from None
        for number, line in enumerate(lines, 1):
            try:
                record = json.loads(line)
            except ValueError:
                if number == len(lines):
                    print(f'r2d2_sim.farm: {path}: its last line is cut short; left out',
                          file=sys.stderr)
                    continue
                raise ReportError(f'{path}: line {number} is not a farm outcome') from None
            if not isinstance(record, dict):
                raise ReportError(f'{path}: line {number} is not a farm outcome')
            records.append(record)
    return records


def _where(record: Dict[str, Any]) -> Optional[Where]:
    """Return the test a record is of, or None for a record that keeps no rootdir."""
    if not record.get('rootdir'):
        return None
    path, _, name = record['nodeid'].partition('::')
    return Path(record['rootdir'], path).resolve(), name


def same_run(records: Sequence[Dict[str, Any]], case: Dict[str, Any],
             where: Where) -> Optional[Dict[str, Any]]:
    """
    Return the record among a rerun's ``records`` that is ``case`` again, or None.

    The same test (``where``, from :func:`locate`); of a seeded test the run
    of the same number, of a property the final example's run of the same
    rank (``case['ordinal']``, from :func:`load_case`).
    """
    prop = bool(case['property'])
    mine = sorted((r for r in records if bool(r['property']) == prop and _where(r) == where),
                  key=lambda r: r['run'])
    if prop:
        return mine[case['ordinal']] if case['ordinal'] < len(mine) else None
    return next((r for r in mine if r['run'] == case['run']), None)


def rerun(report: Path, number: int, record: Optional[Path],
          project: Optional[Path] = None) -> int:
    """
    Rerun case ``number`` of ``report`` in ``project`` (default: here), recording it.

    Return the exit status: 0 the same outcome, 1 another (a determinism bug,
    said in one line) or the case did not run. ReportError before anything
    runs for a report, case or test that cannot be used.
    """
    from r2d2_sim.farm.run import check_same, DeterminismError, Outcome
    from r2d2_sim.farm.scenario import Scenario, ScenarioError
    from r2d2_sim.farm.strategies import REPLAY_ENV
    case = load_case(report, number)
    if case.get('farm'):
        return rerun_farm_case(report, case, record, project)
    expected: Optional[Outcome] = None
    try:
        if case.get('crashed') and case.get('outcome') is None:  # a run that raised
            scenario = Scenario.from_dict(case.get('scenario') or {})
        else:
            expected = Outcome.from_dict(case['outcome'])
            scenario = expected.scenario
    except ScenarioError as exc:
        raise ReportError(f'{report}: case {number}: {exc}') from None
    project = (project or Path.cwd()).resolve()
    if not project.is_dir():
        raise ReportError(f'--project {project}: not a directory')
    test_file, name = locate(case, project)
    record = (record or report.parent / f'rerun-{number}').resolve()
    record.mkdir(parents=True, exist_ok=True)
    for old in record.glob('*.mcap'):
        old.unlink()
    # The rerun's own farm report goes beside its recording: the pytest run prints
    # where it is, and a report in a scratch directory was gone by then. Made afresh,
    # but only ever over a rerun's own (--record may name any directory).
    farm = record / 'rerun_farm'
    if farm.exists():
        if not (farm / 'outcomes').is_dir():
            raise ReportError(f'{farm} exists and is no farm directory: give another --record')
        shutil.rmtree(farm)
    with tempfile.TemporaryDirectory(prefix='r2d2_farm_rerun_') as scratch:
        replayed = Path(scratch) / 'scenario.json'
        replayed.write_text(scenario.to_json(), encoding='utf-8')
        env = dict(os.environ, **{REPLAY_ENV: str(replayed)})
        # Options as one argument each: pytest chooses its rootdir before it knows them.
        command = [sys.executable, '-m', 'pytest', '-q', '-p', PLUGIN, '-p', 'no:cacheprovider',
                   f'--rootdir={project}', f'--confcutdir={project}', f'--farm-dir={farm}',
                   f'--farm-record={record}', f'{test_file}::{name}']
        loaded = ', '.join(map(str, conftests(project, test_file))) or 'none'
        print(f'rerunning case {number} ({case["nodeid"]}, seed {scenario.seed}) in '
              f'{project}:\n  the test: {test_file}::{name}\n  conftest.py: {loaded}\n  '
              + ' '.join(command), flush=True)
        finished = subprocess.run(command, cwd=project, env=env)
        runs = read_records(farm)
    mine = same_run(runs, case, (test_file, name))
    if mine is None:
        print(f'r2d2_sim.farm: the rerun did not run case {number} again ({case["nodeid"]}; '
              f'pytest exit status {finished.returncode})', file=sys.stderr)
        return 1
    if mine['outcome'] is None or expected is None:
        now = (mine['crashed']['reason'] if mine['outcome'] is None
               else 'passed' if mine['outcome']['passed']
               else f'failed: {mine["outcome"]["reason"]}')
        if expected is None:
            print(f'the report has it crashed ({case["reason"]}); this time it {now}')
            return 0
        print(f'r2d2_sim.farm: case {number} {now} this time, not as in the report',
              file=sys.stderr)
        return 1
    again = Outcome.from_dict(mine['outcome'])
    try:
        check_same(expected, again)
    except DeterminismError as exc:
        print(str(exc), file=sys.stderr)
        return 1
    verdict = 'passed' if again.passed else f'failed: {again.reason}'
    print(f'the same outcome as in the report ({verdict}); recording: {again.recording}\n'
          f'replay it into ROS: replay {again.recording} (python -m r2d2_sim.apps.replay), '
          'or open it in Foxglove')
    return 0


def rerun_farm_case(report: Path, case: Dict[str, Any], record: Optional[Path],
                    project: Optional[Path] = None) -> int:
    """
    Run a farm runner's case again in this process, recording it; compare with the report.

    Returns 0 for the report's outcome (or, for a crashed case, any outcome),
    1 for another outcome or a run that raised. ReportError (one line) for a
    farm given as a Python object (nothing to import) or a file outside the
    project.
    """
    from r2d2_sim.farm.job import Item, JobSource, run_variation
    from r2d2_sim.farm.run import check_same, DeterminismError, Outcome
    farm = case['farm']
    number, key, seed = case['case'], int(farm['key']), int(farm['seed'])
    source = farm.get('source')
    if not source:
        raise ReportError(f'case {number} came from run_farm() given a FarmJob object, not a '
                          f'file or module: run it again with run_farm(job, seeds=[{key}], '
                          'record="all")')
    where, _, name = str(source).rpartition(':')
    project = (project or Path.cwd()).resolve()
    if where.endswith('.py'):
        found, _ = locate({'case': number, 'nodeid': f'{where}::{name}', 'rootdir': ''},
                          project)
        where = str(found)
    record = (record or report.parent / f'rerun-{number}').resolve()
    record.mkdir(parents=True, exist_ok=True)
    print(f'rerunning case {number} (seed {seed}) of the farm {where}:{name} in this process, '
          f'recording into {record}', flush=True)
    result = run_variation(JobSource(where, name), Item(key, seed), record='all')
    if result.outcome is None:
        print(f'r2d2_sim.farm: the rerun raised {result.error}', file=sys.stderr)
        return 1
    path = record / f'case-{number}-seed-{seed}.mcap'
    path.write_bytes(result.recording or b'')
    again = Outcome.from_dict(dict(result.outcome, recording=str(path)))
    verdict = 'passed' if again.passed else f'failed: {again.reason}'
    if case['outcome'] is None:
        print(f'the report has it crashed ({case["reason"]}); this time it {verdict}; '
              f'recording: {path}')
        return 0
    try:
        check_same(Outcome.from_dict(case['outcome']), again)
    except DeterminismError as exc:
        print(str(exc), file=sys.stderr)
        return 1
    print(f'the same outcome as in the report ({verdict}); recording: {path}\n'
          f'replay it into ROS: replay {path} (python -m r2d2_sim.apps.replay), '
          'or open it in Foxglove')
    return 0
