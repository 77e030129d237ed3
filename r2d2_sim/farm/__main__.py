"""
``python -m r2d2_sim.farm``: run a farm; rerun a case from its report, recording it; merge reports.

    python -m r2d2_sim.farm run FILE.py:NAME --variations 200 [--executor local|ray|dask]
                                [--address ADDR] [--workers N] [--out DIR] [--shard i/N]
                                [--seeds 0-9,17] [--record failures|all|none] [--fresh]
                                [--shrink] [--progress | --no-progress]
    python -m r2d2_sim.farm rerun farm_report/report.json --case 3 [--record DIR]
                                  [--project DIR]
    python -m r2d2_sim.farm report DIR [--out DIR]

``run`` runs every variation of the farm named (a ``FarmJob`` in a file or a
module) as a task of an executor (:mod:`r2d2_sim.farm.runner`): local
processes by default, Ray or Dask when asked or when ``RAY_ADDRESS`` or
``DASK_SCHEDULER_ADDRESS`` says so. Exit status 0 when every variation
passed, 1 when one failed or crashed, 2 for bad input, 130 after Ctrl-C
(the report of what finished is written; the same command resumes).

``rerun`` runs the case's test again, the project's own file of it
(``--project``, default the current directory; a report does not choose the
code that runs: :mod:`r2d2_sim.farm.rerun`), with its scenario replayed and
every run recorded into ``--record`` (default: ``rerun-<case>`` beside the
report), then checks the rerun's outcome is the report's, measure for
measure. Exit status 0 when it is, 1 when it is not (a determinism bug, said
in one line) or the test could not run, 2 for a bad report, case or project.
``report`` writes the report again from the outcomes of one or more farm
directories (CI shards' together).
"""

import argparse
import json
from pathlib import Path
import signal
import sys
from typing import Any, Dict, List, Optional, Sequence, Set, Tuple

from r2d2_sim.farm.rerun import read_records, ReportError, rerun
from r2d2_sim.farm.runner import FarmError

EXIT_INTERRUPTED = 130  # as a shell reports a process Ctrl-C ended
SHOWN_FILES = 3         # shared-memory files named in the summary line (then "...")

__all__ = ['main']


def rebuild(directories: Sequence[Path], out: Path) -> int:
    """Write one report of the outcomes in ``directories`` into ``out``."""
    from r2d2_sim.farm.report import write_report
    from r2d2_sim.farm.runner import FARM_JSON
    records: List[Dict[str, Any]] = []
    seen: Set[Tuple[Any, ...]] = set()
    repeated = 0
    for directory in directories:
        found = read_records(directory)
        if not found:
            if (directory / FARM_JSON).is_file():
                continue  # a runner's shard that held no seed: nothing to add
            raise ReportError(f'{directory}: no farm outcomes (outcomes/*.jsonl)')
        # A run a directory given before holds too (a farm and a part of it, given
        # together) is counted once: reports of shards never share one.
        farm = _farm_identity(directory)
        keys = [(farm,) + _identity(record) for record in found]
        records += [record for record, key in zip(found, keys) if key not in seen]
        repeated += sum(key in seen for key in keys)
        seen.update(keys)
    if not records:
        raise ReportError(f'no farm outcomes in {", ".join(map(str, directories))}')
    if repeated:
        print(f'r2d2_sim.farm: {repeated} outcome(s) were in more than one of the directories '
              '(the same farm, test, run and seed): counted once', file=sys.stderr)
    for path in write_report(records, out).values():
        print(path)
    return 0


def _farm_identity(directory: Path) -> str:
    """Return what identifies the farm run in ``directory`` (its farm.json), '' if unsaid."""
    from r2d2_sim.farm.runner import FARM_JSON
    try:
        saved = json.loads((directory / FARM_JSON).read_text(encoding='utf-8'))
    except (OSError, ValueError):
        return ''  # a pytest farm's directory: its records name their tests
    return json.dumps(saved.get('farm'), sort_keys=True)


def _identity(record: Dict[str, Any]) -> Tuple[Any, ...]:
    """Return what makes a farm outcome one run: its test, its run number, its seed."""
    outcome, farm = record.get('outcome'), record.get('farm') or {}
    seed = outcome['scenario']['seed'] if outcome else farm.get('seed')
    return (record.get('rootdir'), record['nodeid'], record.get('run', 0),
            bool(record.get('property')), seed)


def run(args: argparse.Namespace) -> int:
    """Run a farm from the command line; print where its report is."""
    from r2d2_sim.farm.runner import parse_seeds, run_farm
    try:
        seeds = None if args.seeds is None else parse_seeds(args.seeds)
    except ValueError as exc:
        raise FarmError(str(exc)) from None
    terminated: List[int] = []

    def on_term(number: int, frame: Any) -> None:
        # SIGTERM (a CI job cancelled, `kill`) stops the run as Ctrl-C does: what finished
        # is reported and the run resumes from it. Once: the report is being written.
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        terminated.append(number)
        raise KeyboardInterrupt
    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        done = run_farm(args.farm, variations=args.variations, seeds=seeds,
                        executor=args.executor, address=args.address, workers=args.workers,
                        out=args.out, shard=args.shard, record=args.record,
                        fresh=args.fresh, progress=args.progress, shrink=args.shrink)
    except KeyboardInterrupt:  # outside the variations' run: starting a Ray, writing the report
        print('r2d2_sim.farm: interrupted; run the same command again to resume',
              file=sys.stderr)
        return 128 + terminated[0] if terminated else EXIT_INTERRUPTED
    finally:
        signal.signal(signal.SIGTERM, previous)
    passed, failed, crashed = (done.count(v) for v in ('passed', 'failed', 'crashed'))
    total = len(done.records)
    state = 'interrupted: ' if done.interrupted else ''
    others = f', {done.others} run before and not asked now' if done.others else ''
    print(f'{state}{total} variations reported ({done.ran} run now on {done.executor}, '
          f'{done.resumed} resumed{others}): {passed} passed, {failed} failed, '
          f'{crashed} crashed')
    if done.cleaned:
        names = ' '.join(done.cleaned[:SHOWN_FILES]) + (
            ' ...' if len(done.cleaned) > SHOWN_FILES else '')
        print(f'removed {len(done.cleaned)} shared-memory file(s) that stopped or crashed '
              f'tasks left: {names}')
    for path in done.written.values():
        print(path)
    if done.shrunk is not None:
        print(done.shrunk['summary'])
    if done.interrupted:
        print('the report holds what finished; run the same command again to resume',
              file=sys.stderr)
        if terminated:
            return 128 + terminated[0]  # as a shell reports a process SIGTERM ended
    return done.exit_status


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the command line; return the exit status."""
    parser = argparse.ArgumentParser(prog='python -m r2d2_sim.farm', description=__doc__.split(
        '\n\n')[0])
    commands = parser.add_subparsers(dest='command', required=True)
    farm = commands.add_parser('run', help='run a farm\'s variations on an executor')
    farm.add_argument('farm', help='the farm: FILE.py:NAME or MODULE:NAME, NAME a FarmJob')
    which = farm.add_mutually_exclusive_group()
    which.add_argument('--variations', type=int, default=None, metavar='N',
                       help='seeds 0..N-1 (a list of scenarios: all of them by default)')
    which.add_argument('--seeds', default=None, help='these seeds: 0-199, 3,17,42, 0-9,20')
    farm.add_argument('--executor', choices=('local', 'ray', 'dask'), default=None,
                      help='where tasks run (default: local, or the cluster RAY_ADDRESS or '
                      'DASK_SCHEDULER_ADDRESS names)')
    farm.add_argument('--address', default=None,
                      help='the cluster: ray://HOST:10001, HOST:6379 (with --executor ray), '
                      'auto, tcp://HOST:8786')
    farm.add_argument('--workers', type=int, default=None,
                      help='worker processes (local, or a cluster started here; default: cores)')
    farm.add_argument('--out', type=Path, default=Path('farm_report'),
                      help='the report directory (default farm_report); a run resumes there')
    farm.add_argument('--shard', default=None, metavar='i/N',
                      help='run only the seeds of CI shard i of N (by the hash of the seed)')
    farm.add_argument('--record', choices=('failures', 'all', 'none'), default='failures',
                      help='what is recorded to MCAP (default: failures)')
    farm.add_argument('--fresh', action='store_true',
                      help='clear an earlier run from --out instead of resuming it')
    farm.add_argument('--shrink', action='store_true',
                      help='shrink the first failure with Hypothesis, on this machine')
    farm.add_argument('--progress', action=argparse.BooleanOptionalAction, default=None,
                      help='the progress line (default: on a terminal)')
    again = commands.add_parser('rerun', help='rerun a case of a report, recording it')
    again.add_argument('report', type=Path, help='the report.json of a farm')
    again.add_argument('--case', type=int, required=True, help='the case number')
    again.add_argument('--record', type=Path, default=None, metavar='DIR',
                       help='where the recording goes (default: rerun-CASE beside the report)')
    again.add_argument('--project', type=Path, default=None, metavar='DIR',
                       help='the project whose test runs (default: the current directory); '
                       'a case whose test is not a file of it is refused')
    build = commands.add_parser('report', help='write a report from farm directories')
    build.add_argument('directories', type=Path, nargs='+', help='farm directories (--farm-dir)')
    build.add_argument('--out', type=Path, default=Path('farm_report'), help='where it goes')
    args = parser.parse_args(argv)
    try:
        if args.command == 'run':
            return run(args)
        if args.command == 'rerun':
            return rerun(args.report, args.case, args.record, args.project)
        return rebuild(args.directories, args.out)
    except (ReportError, FarmError) as exc:
        print(f'r2d2_sim.farm: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM outside the variations' run
        print('r2d2_sim.farm: interrupted', file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == '__main__':
    raise SystemExit(main())
