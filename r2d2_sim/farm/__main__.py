"""
``python -m r2d2_sim.farm``: rerun a farm's case from its report, recording it; rebuild a report.

    python -m r2d2_sim.farm rerun farm_report/report.json --case 3 [--record DIR]
                                  [--project DIR]
    python -m r2d2_sim.farm report DIR [--out DIR]

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
from pathlib import Path
import sys
from typing import Optional, Sequence

from r2d2_sim.farm.rerun import read_records, ReportError, rerun

__all__ = ['main']


def rebuild(directories: Sequence[Path], out: Path) -> int:
    """Write one report of the outcomes in ``directories`` into ``out``."""
    from r2d2_sim.farm.report import write_report
    records = []
    for directory in directories:
        found = read_records(directory)
        if not found:
            raise ReportError(f'{directory}: no farm outcomes (outcomes/*.jsonl)')
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
    again.add_argument('--project', type=Path, default=None, metavar='DIR',
                       help='the project whose test runs (default: the current directory); '
                       'a case whose test is not a file of it is refused')
    build = commands.add_parser('report', help='write a report from farm directories')
    build.add_argument('directories', type=Path, nargs='+', help='farm directories (--farm-dir)')
    build.add_argument('--out', type=Path, default=Path('farm_report'), help='where it goes')
    args = parser.parse_args(argv)
    try:
        if args.command == 'rerun':
            return rerun(args.report, args.case, args.record, args.project)
        return rebuild(args.directories, args.out)
    except ReportError as exc:
        print(f'r2d2_sim.farm: error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    raise SystemExit(main())
