"""
The farm runner: every variation of a farm as a task on an executor, one report on this machine.

:func:`run_farm` takes a :class:`~r2d2_sim.farm.job.FarmJob` (or its
:class:`~r2d2_sim.farm.job.JobSource`), the variations (a count, or seeds),
an executor (local processes by default; Ray or Dask when asked, see
:func:`~r2d2_sim.farm.executors.choose`) and a report directory, and:

- submits one task per variation (:func:`~r2d2_sim.farm.job.run_variation`),
  each re-deriving its scenario from its seed on whatever host runs it;
- appends each result to ``outcomes/`` as it comes (a line of the same form
  the pytest farm writes), and a failure's recording, which the task sent
  back as bytes, to ``recordings/``: everything lands here, on the machine
  that asked;
- reports a task whose process died as **crashed**, with its seed and how it
  died, and runs it no more (no retries); the Fast DDS segments such tasks
  left are removed on every host (:mod:`r2d2_sim.farm.shm`);
- shows progress (:mod:`r2d2_sim.farm.progress`);
- on Ctrl-C stops the tasks, writes the report of what finished, and says so;
  a later run into the same directory resumes: variations already reported
  are not run again (``fresh`` starts over);
- with ``shard`` runs only the variations of one CI shard
  (:mod:`r2d2_sim.farm.shards`); shards' reports merge with
  ``python -m r2d2_sim.farm report``;
- writes ``report.md``, ``report.json`` and ``trajectories.png``
  (:mod:`r2d2_sim.farm.report`);
- with ``shrink``, shrinks the first failure with Hypothesis on this machine
  (:mod:`r2d2_sim.farm.shrink`): the search is wide, the shrinking local.

Bad input (a shard like ``3/2``, a directory that cannot be written, a farm
that does not pickle, a cluster that does not answer) is a :class:`FarmError`
in one line, raised before anything runs.
"""

from dataclasses import dataclass, field
import json
import os
from pathlib import Path
import re
import shlex
import sys
import time
from typing import Any, Dict, List, Optional, Sequence, TextIO, Union

from r2d2_sim.farm.executors import Crash, ExecutorError, Finished, choose
from r2d2_sim.farm.job import (describe, FarmJob, Item, JobSource, load_failure, RECORD_MODES,
                               TaskResult)
from r2d2_sim.farm.progress import Progress
from r2d2_sim.farm.scenario import ScenarioError
from r2d2_sim.farm.shards import parse_shard, Shard

__all__ = ['run_farm', 'FarmRun', 'FarmError', 'FARM_JSON', 'parse_seeds']

FARM_JSON = 'farm.json'
OUTCOMES = 'outcomes'
RECORDINGS = 'recordings'
# How long the runner waits for results at a time (s): Ctrl-C is noticed between waits.
POLL_S = 0.25


class FarmError(Exception):
    """A farm that cannot run as asked: one line, said before anything runs."""


@dataclass
class FarmRun:
    """
    What a farm run did: the report's directory and records, and what it counted.

    ``records`` are every variation's record in the directory, by key: this
    run's, the resumed ones' and those of this farm's variations that an
    earlier run put there and this one was not asked for (``others`` of them:
    a ``seeds`` or ``shard`` run into a fuller directory). The report is
    written from exactly these, and :meth:`count` and :attr:`exit_status`
    count them: the report, the counts and the exit status always agree.
    ``ran`` is how many this run finished, ``resumed`` how many of those asked
    were there already; ``interrupted`` whether Ctrl-C
    stopped it; ``cleaned`` the Fast DDS segments removed after crashes;
    ``written`` the report's files; ``shrunk`` the shrinking's result, if asked;
    ``start_s`` and ``run_s`` the wall time of starting the executor and of
    running the tasks.
    """

    directory: Path
    records: Dict[int, Dict[str, Any]] = field(default_factory=dict)
    ran: int = 0
    resumed: int = 0
    others: int = 0
    interrupted: bool = False
    cleaned: List[str] = field(default_factory=list)
    written: Dict[str, Path] = field(default_factory=dict)
    shrunk: Optional[Dict[str, Any]] = None
    executor: str = ''
    start_s: float = 0.0  # starting or connecting to the executor (wall)
    run_s: float = 0.0    # from the first task submitted to the last result (wall)
    ready_s: List[float] = field(default_factory=list)  # local workers: spawned to ready

    def count(self, verdict: str) -> int:
        """Return how many variations ``passed``, ``failed`` or ``crashed``."""
        return sum(_verdict(r) == verdict for r in self.records.values())

    @property
    def exit_status(self) -> int:
        """Return 0 when every variation passed, 1 otherwise, 130 when interrupted."""
        if self.interrupted:
            return 130
        return 0 if all(_verdict(r) == 'passed' for r in self.records.values()) else 1


def _verdict(record: Dict[str, Any]) -> str:
    if record.get('crashed'):
        return 'crashed'
    return 'passed' if record['outcome']['passed'] else 'failed'


def parse_seeds(text: str) -> List[int]:
    """Read ``0-199``, ``3,17,42`` or a mix (``0-9,20``); ValueError in one line if not."""
    seeds: List[int] = []
    try:
        for part in text.split(','):
            first, dash, last = part.strip().partition('-')
            low = int(first)
            high = int(last) if dash else low
            if high < low or low < 0:
                raise ValueError
            seeds += range(low, high + 1)
    except ValueError:
        raise ValueError(f'--seeds {text!r}: write seeds as 0-199, 3,17,42 or 0-9,20 '
                         '(whole numbers >= 0)') from None
    return seeds


def _writable(directory: Path) -> None:
    """Make ``directory`` and check a file can be written there; FarmError if not."""
    try:
        directory.mkdir(parents=True, exist_ok=True)
        probe = directory / f'.r2d2_farm_probe-{os.getpid()}'
        probe.write_bytes(b'')
        probe.unlink()
    except OSError as exc:
        raise FarmError(f'the report directory {directory} cannot be written: '
                        f'{exc.strerror or exc}') from None


def _clear(directory: Path) -> None:
    """Remove an earlier farm's files from ``directory`` (only the files a farm writes)."""
    from r2d2_sim.farm.report import REPORT_JSON, REPORT_MD, TRAJECTORIES_PNG
    for folder, pattern in ((OUTCOMES, '*.jsonl'), (RECORDINGS, '*.mcap')):
        for path in (directory / folder).glob(pattern):
            path.unlink()
    for name in (REPORT_JSON, REPORT_MD, TRAJECTORIES_PNG, FARM_JSON):
        (directory / name).unlink(missing_ok=True)


def _slug(text: str) -> str:
    return re.sub(r'[^A-Za-z0-9_.=-]+', '-', text).strip('-')[:100] or 'farm'


def _earlier(directory: Path, identity: Dict[str, Any]) -> Dict[int, Dict[str, Any]]:
    """Return an earlier run's records of this farm in ``directory``; FarmError if another's."""
    from r2d2_sim.farm.rerun import read_records
    found = (directory / OUTCOMES).is_dir() and any((directory / OUTCOMES).glob('*.jsonl'))
    path = directory / FARM_JSON
    if not path.exists():
        if found:
            raise FarmError(f'{directory} holds the outcomes of a pytest farm, not of this '
                            'runner: choose another report directory, or start over in it '
                            '(--fresh)')
        return {}
    try:
        earlier = json.loads(path.read_text(encoding='utf-8'))['farm']
    except (OSError, ValueError, KeyError, TypeError):
        raise FarmError(f'{path} is not a farm runner\'s: remove it, or start over (--fresh)')
    if earlier != identity:
        differ = next(k for k in sorted(set(earlier) | set(identity))
                      if earlier.get(k) != identity.get(k))
        raise FarmError(f'{directory} holds the report of another farm (its {differ} differs): '
                        'resume only the same farm there; choose another directory, or start '
                        'over in it (--fresh)')
    records = [r for r in read_records(directory) if 'farm' in r]
    unloaded = [r for r in records if load_failure(r)]
    if unloaded:
        _drop_load_failures(directory)
        print(f'r2d2_sim.farm: {len(unloaded)} earlier outcome(s) in {directory} were a worker '
              'that could not load the farm, not a verdict: they run again', file=sys.stderr)
    return {int(r['farm']['key']): r for r in records if not load_failure(r)}


def _drop_load_failures(directory: Path) -> None:
    """Rewrite outcomes/ without the records of workers that could not load the farm."""
    for path in sorted((directory / OUTCOMES).glob('*.jsonl')):
        lines = path.read_text(encoding='utf-8').splitlines(keepends=True)
        kept = []
        for line in lines:
            try:
                record = json.loads(line)
            except ValueError:  # a line cut short: read_records said so; kept as it is
                kept.append(line)
                continue
            if not (isinstance(record, dict) and 'farm' in record and load_failure(record)):
                kept.append(line)
        if len(kept) != len(lines):
            scratch = path.with_name(path.name + '.new')
            scratch.write_text(''.join(kept), encoding='utf-8')
            os.replace(scratch, path)


def _command_line(source: Optional[JobSource], key: int, directory: Path) -> str:
    """Return the command that runs variation ``key`` again, recording it."""
    if source is None:
        return (f'run_farm(job, seeds=[{key}], record="all", out="{directory}/rerun-{key}") '
                '(this farm was given as a Python object)')
    return (f'python -m r2d2_sim.farm run {shlex.quote(str(source))} --seeds {key} '
            f'--record all --out {shlex.quote(str(directory / f"rerun-{key}"))}')


def _record(job: FarmJob, source: Optional[JobSource], directory: Path, item: Item,
            result: Union[TaskResult, Crash], executor: str) -> Dict[str, Any]:
    """Turn a task's result into a record (a line of outcomes/); write its recording."""
    farm: Dict[str, Any] = {'key': item.key, 'seed': item.seed, 'executor': executor,
                            'source': None if source is None else str(source),
                            'rerun': _command_line(source, item.key, directory)}
    record: Dict[str, Any] = {'nodeid': job.case_name(item.key), 'rootdir': '', 'run': 0,
                              'property': False, 'farm': farm}
    if isinstance(result, Crash):
        record.update(worker=f'{result.host}:{result.pid}', outcome=None,
                      crashed={'reason': f'crashed: {result.reason}', 'host': result.host,
                               'pid': result.pid})
        return record
    farm.update(host=result.host, pid=result.pid, task_s=result.task_s,
                recording_sha256=result.recording_sha256)
    record['worker'] = f'{result.host}:{result.pid}'
    if result.outcome is None:
        record.update(outcome=None, crashed={'reason': f'raised {result.error}',
                                             'host': result.host, 'pid': result.pid,
                                             'traceback': result.trace})
        return record
    outcome = dict(result.outcome)
    if result.recording is not None:
        folder = directory / RECORDINGS
        folder.mkdir(exist_ok=True)
        path = folder / f'{_slug(job.name)}-{item.key}.mcap'
        path.write_bytes(result.recording)
        outcome['recording'] = str(path)
    record['outcome'] = outcome
    return record


def run_farm(job: Union[FarmJob, JobSource, str], *, variations: Optional[int] = None,
             seeds: Optional[Sequence[int]] = None, executor: Optional[str] = None,
             address: Optional[str] = None, workers: Optional[int] = None,
             out: Union[str, Path] = 'farm_report', shard: Union[str, Shard, None] = None,
             record: str = 'failures', fresh: bool = False, progress: Optional[bool] = None,
             stream: Optional[TextIO] = None, shrink: bool = False,
             picture: bool = True) -> FarmRun:
    """
    Run the farm's variations on an executor; write its report into ``out``; return the run.

    ``job``: a :class:`FarmJob`, or where one is (``FILE.py:NAME``,
    ``MODULE:NAME``, a :class:`JobSource`: the workers import it).
    ``variations`` (seeds 0..n-1; for a list of scenarios, all of them by
    default) or ``seeds`` (explicit keys). ``executor``: ``local``, ``ray``,
    ``dask`` or None to choose (see :func:`~r2d2_sim.farm.executors.choose`);
    ``address`` a cluster's; ``workers`` local processes (default: the cores),
    or for a cluster started here, its workers. ``shard`` ``i/N``.
    ``record``: ``failures`` (a failing run run again, recording: the pytest
    farm's way), ``all`` or ``none``. ``fresh`` clears an earlier run from
    ``out`` instead of resuming it. ``progress``: None on a terminal only.
    ``shrink``: shrink the first failure locally with Hypothesis.
    FarmError (one line) for input that cannot run; KeyboardInterrupt is
    caught: the run stops, the report of what finished is written, and
    :attr:`FarmRun.interrupted` is set.
    """
    if record not in RECORD_MODES:
        raise FarmError(f'--record {record}: one of {", ".join(RECORD_MODES)}')
    try:
        shard = parse_shard(shard) if isinstance(shard, str) else shard
        source = JobSource.parse(job) if isinstance(job, str) else (
            job if isinstance(job, JobSource) else None)
        farm = source.load() if source is not None else job
        if not isinstance(farm, FarmJob):
            raise FarmError(f'run_farm takes a FarmJob or where one is (FILE.py:NAME), got '
                            f'{type(farm).__name__}')
        keys = _keys(farm, variations, seeds)
    except (ValueError, ScenarioError) as exc:
        raise FarmError(str(exc)) from None
    if shard is not None:
        keys = [k for k, item in zip(keys, farm.items(keys)) if shard.holds(
            item.key if farm.listed else item.seed)]
    directory = Path(out).resolve()
    _writable(directory)
    identity = describe(farm)
    try:  # chosen before --fresh clears anything: a bad choice clears nothing
        pool = choose(executor, address, payload=source or farm, record=record,
                      workers=workers)
    except ExecutorError as exc:
        raise FarmError(str(exc)) from None

    def start() -> float:
        began = time.perf_counter()
        try:
            pool.start()
        except ExecutorError as exc:
            pool.close()
            raise FarmError(str(exc)) from None
        return time.perf_counter() - began
    # The executor starts (a cluster is reached) before the directory changes: --fresh
    # clears nothing, and a run writes no farm.json, for an address that does not answer.
    started_s = None
    if fresh:
        started_s = start()
        _clear(directory)
    try:
        earlier = _earlier(directory, identity)
        todo = farm.items([k for k in keys if k not in earlier])
        if todo and started_s is None:
            started_s = start()
        try:
            (directory / OUTCOMES).mkdir(exist_ok=True)
            (directory / FARM_JSON).write_text(json.dumps(
                {'farm': identity, 'source': None if source is None else str(source),
                 'shard': None if shard is None else str(shard)}, indent=1,
                sort_keys=True) + '\n', encoding='utf-8')
        except OSError as exc:  # outcomes/ a file, farm.json a folder, a full disk...
            raise FarmError(f'the report directory {directory} cannot hold a farm\'s report: '
                            f'{exc.strerror or exc}: {exc.filename}') from None
    except BaseException:
        if started_s is not None:  # started: let its workers go
            pool.close()
        raise
    asked = set(keys)
    run = FarmRun(directory, records=dict(earlier), resumed=len(asked & set(earlier)),
                  others=len(set(earlier) - asked), executor=pool.name)
    if started_s is not None:
        run.start_s = started_s
    shown = Progress(len(keys), run.resumed, stream=stream,
                     enabled=progress if progress is not None else (stream or sys.stderr)
                     .isatty())
    if run.resumed and shown.enabled:
        print(f'resuming: {run.resumed} of {len(keys)} variations are in {directory} already',
              file=shown.stream)
    outcomes = directory / OUTCOMES / f'runner-{os.getpid()}-{int(time.time())}.jsonl'
    try:
        _drive(pool, todo, farm, source, directory, outcomes, run, shown)
    except ExecutorError as exc:
        raise FarmError(str(exc)) from None
    finally:
        shown.finish()
    if run.records:
        from r2d2_sim.farm.report import write_report
        run.written = write_report(list(run.records.values()), directory, picture=picture)
    if shrink and not run.interrupted:
        failed = sorted(k for k, r in run.records.items() if _verdict(r) == 'failed')
        if failed:
            from r2d2_sim.farm.shrink import shrink_failure
            try:
                run.shrunk = shrink_failure(farm, farm.items([failed[0]])[0], directory)
            except KeyboardInterrupt:  # the report is written: the run is what it was
                run.interrupted = True
            if run.shrunk is not None and 'report.md' in run.written:
                _add_shrunk(run.written['report.md'], run.shrunk)
    return run


def _add_shrunk(report: Path, shrunk: Dict[str, Any]) -> None:
    """Append the shrinking's result to report.md."""
    lines = ['', '## Shrunk by Hypothesis, on the machine that ran the farm', '',
             f'- {shrunk["summary"]}', f'- the first failing scenario: `{shrunk["first"]}`']
    if shrunk.get('shrunk'):
        lines.append(f'- shrunk to: `{shrunk["shrunk"]}`')
    with open(report, 'a', encoding='utf-8') as out:
        out.write('\n'.join(lines) + '\n')


def _keys(job: FarmJob, variations: Optional[int], seeds: Optional[Sequence[int]]) -> List[int]:
    if variations is not None and seeds is not None:
        raise ValueError('give variations or seeds, not both')
    if seeds is not None:
        keys = list(dict.fromkeys(int(s) for s in seeds))
        job.items(keys)  # a list's indices are checked
        return keys
    if variations is None:
        if job.listed:
            return list(range(len(job.space)))  # type: ignore[arg-type]
        raise ValueError('say how many variations (--variations N) or which seeds (--seeds)')
    if variations < 1:
        raise ValueError(f'--variations {variations}: at least 1')
    listed = len(job.space) if job.listed else None  # type: ignore[arg-type]
    if listed is not None and variations > listed:
        raise ValueError(f'--variations {variations}: the farm lists {listed} scenarios')
    return list(range(variations))


def _drive(pool: Any, todo: List[Item], job: FarmJob, source: Optional[JobSource],
           directory: Path, outcomes: Path, run: FarmRun, shown: Progress) -> None:
    """
    Run ``todo`` on the executor, keep every result as it comes; stop on Ctrl-C.

    The executor was started already when there is anything to run
    (:func:`run_farm` starts it before the report directory changes).
    """
    if not todo:
        pool.close()
        return
    submitted = time.perf_counter()
    try:
        pool.submit(todo)
        with open(outcomes, 'a', encoding='utf-8') as lines:
            while pool.pending():
                finished: List[Finished] = pool.wait(POLL_S)
                for item, result in finished:
                    if isinstance(result, TaskResult) and result.setup_error:
                        raise ExecutorError(result.setup_error)  # as the local pool says it
                    try:
                        line = json.dumps(_record(job, source, directory, item, result,
                                                  pool.name), sort_keys=True)
                        lines.write(line + '\n')
                        lines.flush()
                    except OSError as exc:  # a full disk, recordings/ not a folder...
                        raise FarmError(f'cannot write the outcome of variation {item.key} '
                                        f'into {directory}: {exc.strerror or exc}') from None
                    entry = json.loads(line)  # as a resume reads it back
                    run.records[item.key] = entry
                    run.ran += 1
                    shown.add(_verdict(entry))
    except KeyboardInterrupt:
        run.interrupted = True
        pool.stop()
    except BaseException:  # whatever else ends the run: nothing of it goes on running
        pool.stop()
        raise
    finally:
        run.run_s = time.perf_counter() - submitted
        run.ready_s = list(getattr(pool, 'ready_s', []))
        _let_go(pool, run)


def _let_go(pool: Any, run: FarmRun) -> None:
    """
    Sweep the hosts and let go of the executor, whatever state its workers are in.

    After Ctrl-C a terminal's SIGINT reaches a local cluster's workers too, and
    the cluster's client then fails on a worker going away (Dask's
    CommClosedError, a Ray node gone): the clean-up is best effort, said in a
    warning, and never keeps the report of what finished from being written.
    """
    try:
        run.cleaned = pool.clean_hosts()
    except Exception as exc:
        _warn(f'the Fast DDS files of crashed tasks were not swept on every host '
              f'({_one_line(exc)})')
    try:
        pool.close()
    except Exception as exc:
        _warn(f'letting go of the {pool.name} executor failed ({_one_line(exc)})')


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return f'{type(exc).__name__}: {text.splitlines()[0]}' if text else type(exc).__name__


def _warn(text: str) -> None:
    print(f'r2d2_sim.farm: warning: {text}', file=sys.stderr)
