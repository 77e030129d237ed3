"""
``python -m r2d2_sim.farm``: rerun a farm's case from its report, recording it; rebuild a report.

    python -m r2d2_sim.farm rerun farm_report/report.json --case 3 [--record DIR]
    python -m r2d2_sim.farm report DIR [--out DIR]

``rerun`` runs the case's test again where the farm ran (its pytest node id,
from the directory pytest was started in) with its scenario replayed
(``R2D2_FARM_REPLAY``: a Hypothesis property draws just that scenario; a
seeded test draws it from its seed anyway) and every run recorded into
``--record`` (default: ``rerun-<case>`` beside the report), then checks the
rerun's outcome is the report's, measure for measure. Exit status 0 when it
is, 1 when it is not (a determinism bug, said in one line) or the test could
not run, 2 for a bad report or case. ``report`` writes the report again from
the outcomes of one or more farm directories (CI shards' together).
"""

import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile
from typing import List, Optional, Sequence

__all__ = ['main']


class FarmCliError(Exception):
    """A report or case that cannot be used: one line, exit status 2."""


def _load_case(report: Path, number: int) -> dict:
    try:
        data = json.loads(report.read_text(encoding='utf-8'))
        cases = data['cases']
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise FarmCliError(f'{report}: not a farm report ({type(exc).__name__}: {exc})')
    if not 0 <= number < len(cases):
        raise FarmCliError(f'{report} has cases 0..{len(cases) - 1}, not {number}')
    return dict(cases[number], invocation_dir=data.get('invocation_dir'),
                rootdir=data.get('rootdir'))


def rerun(report: Path, number: int, record: Optional[Path]) -> int:
    """Rerun case ``number`` of ``report`` recording it; return the exit status."""
    from r2d2_sim.farm.run import check_same, DeterminismError, Outcome
    from r2d2_sim.farm.strategies import REPLAY_ENV
    case = _load_case(report, number)
    expected = Outcome.from_dict(case['outcome'])
    record = (record or report.parent / f'rerun-{number}').resolve()
    record.mkdir(parents=True, exist_ok=True)
    for old in record.glob('*.mcap'):
        old.unlink()
    with tempfile.TemporaryDirectory(prefix='r2d2_farm_rerun_') as scratch:
        scenario = Path(scratch) / 'scenario.json'
        scenario.write_text(expected.scenario.to_json(), encoding='utf-8')
        env = dict(os.environ, **{REPLAY_ENV: str(scenario)})
        rootdir = case.get('rootdir') or '.'
        command = [sys.executable, '-m', 'pytest', '-q', '-p', 'r2d2_sim.farm.pytest_plugin',
                   '-p', 'no:cacheprovider', '--farm-dir', str(Path(scratch) / 'farm'),
                   '--farm-record', str(record), str(Path(rootdir) / case['nodeid'])]
        print(f'rerunning case {number} ({case["nodeid"]}, seed {expected.scenario.seed}):\n  '
              + ' '.join(command), flush=True)
        finished = subprocess.run(command, cwd=case.get('invocation_dir') or rootdir, env=env)
        runs = _records(Path(scratch) / 'farm')
    # A seeded case is the same run of its test; a property's, its final (shrunk) example.
    mine = [r for r in runs if r['nodeid'] == case['nodeid'] and (
        r['property'] if case['property'] else r['run'] == case['run'])]
    if not mine:
        print(f'r2d2_sim.farm: the rerun did not run case {number} again ({case["nodeid"]}; '
              f'pytest exit status {finished.returncode})', file=sys.stderr)
        return 1
    again = Outcome.from_dict(mine[-1]['outcome'])
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


def _records(directory: Path) -> List[dict]:
    records = []
    for path in sorted((directory / 'outcomes').glob('*.jsonl')):
        records += [json.loads(line) for line in path.read_text(encoding='utf-8').splitlines()
                    if line.strip()]
    return records


def rebuild(directories: Sequence[Path], out: Path) -> int:
    """Write one report of the outcomes in ``directories`` into ``out``."""
    from r2d2_sim.farm.report import write_report
    records = []
    for directory in directories:
        found = _records(directory)
        if not found:
            raise FarmCliError(f'{directory}: no farm outcomes (outcomes/*.jsonl)')
        records += found
    for path in write_report(records, out).values():
        print(path)
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the command line; return the exit status."""
    parser = argparse.ArgumentParser(prog='python -m r2d2_sim.farm', description=__doc__.split(
        '\n\n')[0])
    commands = parser.add_subparsers(dest='command', required=True)
    again = commands.add_parser('rerun', help='rerun a case of a report, recording it')
    again.add_argument('report', type=Path, help='the report.json of a farm')
    again.add_argument('--case', type=int, required=True, help='the case number')
    again.add_argument('--record', type=Path, default=None, metavar='DIR',
                       help='where the recording goes (default: rerun-CASE beside the report)')
    build = commands.add_parser('report', help='write a report from farm directories')
    build.add_argument('directories', type=Path, nargs='+', help='farm directories (--farm-dir)')
    build.add_argument('--out', type=Path, default=Path('farm_report'), help='where it goes')
    args = parser.parse_args(argv)
    try:
        if args.command == 'rerun':
            return rerun(args.report, args.case, args.record)
        return rebuild(args.directories, args.out)
    except FarmCliError as exc:
        print(f'r2d2_sim.farm: error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    raise SystemExit(main())
