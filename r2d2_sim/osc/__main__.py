"""
``python -m r2d2_sim.osc``: run an OpenSCENARIO scenario's variations on the farm's executors.

    python -m r2d2_sim.osc SCENARIO.osc [--parameters FILE] [-o DIR] [--jobs N]
                           [--executor local|ray|dask] [--address ADDRESS] [--ros]

Each document of the ``--parameters`` file (scenario_execution's
``--scenario-parameter-file``) is one variation, one task of the farm's
executor (local processes by default, ``--jobs`` of them, one per core; a
Ray or Dask cluster as ``python -m r2d2_sim.farm`` chooses one: the
executor named, the address's kind, ``RAY_ADDRESS``, ``DASK_SCHEDULER_ADDRESS``),
run in lockstep, each scenario of the file a task of its own; one line per
scenario and variation, its verdict and reason, named as scenario_execution
names its test cases, then ``DIR/test.xml`` (JUnit, the same cases) and the
farm's report in ``DIR/farm``. ``--ros`` runs them one after
another against a running simulator instead (the scenario's
``simulator_namespace``, on ``ROS_DOMAIN_ID``). Exit status 0 when every
variation passed, 1 when one failed, 2 for a file that cannot be read.
Works from a source checkout too: osc.r2d2's entry points are registered
for the run.
"""

import argparse
import os
import sys
from typing import Optional, Sequence

from r2d2_sim.errors import ScenarioError

__all__ = ['main']


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run the command line; return the exit status."""
    parser = argparse.ArgumentParser(prog='python -m r2d2_sim.osc',
                                     description=__doc__.split('\n\n')[0].strip())
    parser.add_argument('scenario', help='the OpenSCENARIO 2 file (.osc)')
    parser.add_argument('--parameters', default=None, metavar='FILE',
                        help='a scenario parameter file; each YAML document one variation')
    parser.add_argument('-o', '--output-dir', default='osc_results', metavar='DIR',
                        help='where test.xml and the farm report go (default: osc_results)')
    parser.add_argument('--jobs', type=int, default=None,
                        help='worker processes (default: one per core; a cluster: its own)')
    parser.add_argument('--executor', choices=('local', 'ray', 'dask'), default=None,
                        help='where the variations run (default: local, or the cluster '
                             'RAY_ADDRESS or DASK_SCHEDULER_ADDRESS names)')
    parser.add_argument('--address', default=None,
                        help="the cluster's address (ray://HOST:PORT, auto, tcp://HOST:PORT)")
    parser.add_argument('--ros', action='store_true',
                        help='run against a running simulator over ROS, one at a time')
    args = parser.parse_args(argv)
    if not os.path.isfile(args.scenario):
        print(f'r2d2_sim.osc: error: no scenario file {args.scenario}', file=sys.stderr)
        return 2
    if os.path.exists(args.output_dir) and not os.path.isdir(args.output_dir):
        print(f'r2d2_sim.osc: error: -o {args.output_dir} is a file, not a directory',
              file=sys.stderr)
        return 2
    try:
        import scenario_execution  # noqa: F401
    except ImportError:
        print("r2d2_sim.osc: error: needs scenario_execution: pip install 'r2d2_sim[scenarios]' "
              '(or scenario_execution==1.8.0)', file=sys.stderr)
        return 2
    from r2d2_sim.osc.entry_points import ensure_registered
    ensure_registered()
    from r2d2_sim.farm.executors import ExecutorError
    from r2d2_sim.osc.variations import check_parses, executor_map, IN_PROCESS, run_variations
    simulation = 'r2d2_sim.osc:StandardSimulation' if args.ros else IN_PROCESS
    if args.jobs is not None and args.jobs < 1:
        print(f'r2d2_sim.osc: error: --jobs {args.jobs}: at least 1', file=sys.stderr)
        return 2
    if args.ros or args.jobs == 1:
        # Over ROS the variations share the one running simulator: one after another.
        mapper = None
    else:
        mapper = executor_map(args.executor, args.address, args.jobs)
    try:
        check_parses(args.scenario)
        verdicts = run_variations(args.scenario, args.parameters, args.output_dir,
                                  jobs=1, map_tasks=mapper, simulation=simulation)
    except (ScenarioError, ExecutorError) as exc:
        print(f'r2d2_sim.osc: error: {exc}', file=sys.stderr)
        return 2
    except OSError as exc:  # the results cannot be written there
        print(f'r2d2_sim.osc: error: cannot write into {args.output_dir}: '
              f'{exc.strerror or exc}', file=sys.stderr)
        return 2
    for verdict in verdicts:
        said = 'passed' if verdict.passed else f'FAILED: {verdict.reason}'
        print(f'{verdict.name}: {said}')
    failed = sum(not v.passed for v in verdicts)
    print(f'{len(verdicts) - failed} passed, {failed} failed; {args.output_dir}/test.xml')
    return 1 if failed else 0


if __name__ == '__main__':
    raise SystemExit(main())
