#!/usr/bin/env python3
"""
The scenario farm at scale: docs/farm.md's example farm, 200 variations, against raw physics.

    .venv/bin/python bench/farm.py [--variations 200] [--workers 2] [--raw-sample 20]

- **Farm**: ``pytest -n WORKERS -p r2d2_sim.farm.pytest_plugin`` on the seeded
  test of ``test/examples/farm/test_stopper_farm.py`` (``VARIATIONS`` layouts
  of the room, each up to 20 simulated seconds: a run ends when the robot
  reaches its goal), wall time from the command's start to its exit
  (interpreters, collection, every harness, the report and its picture). From
  the report: runs, verdicts, physics steps.
- **Raw physics of the same worlds**: a sample of the same scenarios (every
  k-th seed), each world built as the farm builds it (room, boxes, the robot
  at its start, driving at 0.3 m/s) and stepped by ``stepSimulation`` alone
  for 2,400 steps: physics steps per wall second on one core, before and
  after the farm (the machine is shared: both are given).
- **Ratio**: the farm's physics steps per second per worker against raw.

Cores kept busy by other processes are measured before the farm (1 s) and
the cores busy during it. Prints, writes ``bench/farm.json`` and keeps the
report (``report.md`` and ``trajectories.png``; the whole farm directory is
``bench/farm_run/``) in ``bench/farm_report/``, which docs/farm.md shows.
Numbers are printed, never asserted.
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time

from common import (
    background_load, BENCH_DIR, LoadMeter, local_date, machine_info, raw_stepper, REPO,
    write_json)

RESULTS_PATH = os.path.join(BENCH_DIR, 'farm.json')
REPORT_DIR = os.path.join(BENCH_DIR, 'farm_report')
EXAMPLE = os.path.join(REPO, 'test', 'examples', 'farm', 'test_stopper_farm.py')
TEST = 'test_the_stopper_never_touches_anything'
RAW_STEPS = 2400
GOAL_S = 240.0  # issue 28: 200 variations in under 4 minutes on our 2 cores


def example_space():
    """Return the example's ScenarioSpace, from the example file."""
    import importlib.util
    spec = importlib.util.spec_from_file_location('farm_example', EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.SPACE, module.PARAMETERS


def measure_raw(seeds):
    """Raw stepSimulation steps per wall second of each seed's world (robot driving)."""
    from r2d2_sim.farm.run import DEFAULT_PARAMETERS
    from r2d2_sim.testing import box_urdf, SimHarness
    space, parameters = example_space()
    rates = []
    for seed in seeds:
        scenario = space.draw(seed)
        settings = dict(DEFAULT_PARAMETERS, **scenario.parameters(), **parameters)
        with SimHarness(**settings) as harness:
            for index, box in enumerate(scenario.obstacles):
                harness.spawn(box_urdf(box.size), name=f'box_{index}',
                              position=(box.x, box.y, box.size[2] / 2.0), yaw=box.yaw)
            harness.send_cmd_vel(linear=0.3)
            harness.advance(steps=24)  # the command reaches the wheel motors
            advance = raw_stepper(harness.sim.world)
            started = time.perf_counter()
            advance(RAW_STEPS)
            rates.append(RAW_STEPS / (time.perf_counter() - started))
    return rates


def run_farm(variations, workers):
    """Run the example farm under pytest; return its wall time, exit status and report."""
    farm_dir = os.path.join(BENCH_DIR, 'farm_run')
    shutil.rmtree(farm_dir, ignore_errors=True)
    env = dict(os.environ, VARIATIONS=str(variations),
               PYTHONPATH=os.pathsep.join(p for p in (REPO, os.environ.get('PYTHONPATH')) if p))
    env.pop('ROS_DOMAIN_ID', None)
    command = [sys.executable, '-m', 'pytest', '-q', '-p', 'r2d2_sim.farm.pytest_plugin',
               '-p', 'no:cacheprovider', '-n', str(workers), '--farm-dir', farm_dir,
               f'{EXAMPLE}::{TEST}']
    meter = LoadMeter().start()
    started = time.perf_counter()
    finished = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True)
    wall_s = time.perf_counter() - started
    load = meter.stop()
    with open(os.path.join(farm_dir, 'report.json'), encoding='utf-8') as source:
        report = json.load(source)
    shutil.rmtree(REPORT_DIR, ignore_errors=True)
    os.makedirs(REPORT_DIR)
    for name in ('report.md', 'trajectories.png'):  # report.json: 3 MB of trajectories
        shutil.copy(os.path.join(farm_dir, name), REPORT_DIR)
    return {'wall_s': wall_s, 'returncode': finished.returncode, 'load': load,
            'summary_line': finished.stdout.strip().splitlines()[-1:],
            'report': report['summary'], 'date': report['date']}


def main(argv=None):
    """Run the farm bench; print and save the results."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--variations', type=int, default=200)
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--raw-sample', type=int, default=20,
                        help='worlds stepped raw (every k-th seed), before and after')
    args = parser.parse_args(argv)
    step = max(1, args.variations // args.raw_sample)
    seeds = list(range(0, args.variations, step))[:args.raw_sample]
    quiet = background_load()
    raw_before = measure_raw(seeds)
    farm = run_farm(args.variations, args.workers)
    raw_after = measure_raw(seeds)
    summary = farm['report']
    steps = summary['physics_steps']
    raw = statistics.median(raw_before + raw_after)
    per_worker = steps / farm['wall_s'] / args.workers
    results = {
        'machine': machine_info(), 'date': local_date(), 'variations': args.variations,
        'workers': args.workers, 'background_load_before': quiet, 'farm': farm,
        'raw_steps_per_s_before': raw_before, 'raw_steps_per_s_after': raw_after,
        'raw_steps_per_s_median': raw, 'farm_steps_per_s_per_worker': per_worker,
        'ratio_to_raw': per_worker / raw, 'goal_s': GOAL_S}
    write_json(RESULTS_PATH, results)
    simulated_s = steps / 240.0
    print(f'\nfarm of {args.variations} variations, pytest -n {args.workers}: '
          f'{farm["wall_s"]:.1f} s wall (goal < {GOAL_S:.0f} s), exit status '
          f'{farm["returncode"]} ({" ".join(farm["summary_line"])})')
    print(f'  {summary["passed"]} passed, {summary["goal_reached"]} reached the goal; '
          f'{steps:,} physics steps = {simulated_s:,.0f} simulated s '
          f'({simulated_s / farm["wall_s"]:.1f} simulated s per wall s over all workers)')
    print(f'  cores busy during the farm {farm["load"]["busy_cores"]:.2f}; other processes '
          f'before it {quiet["busy_cores"]:.2f}')
    print(f'raw physics of the same worlds ({len(seeds)} of them, one core): median '
          f'{statistics.median(raw_before):,.0f} steps/s before, '
          f'{statistics.median(raw_after):,.0f} after')
    print(f'farm: {per_worker:,.0f} physics steps/s per worker = {per_worker / raw:.3f} of raw')
    print(f'\nwritten to {RESULTS_PATH}; the report is in {REPORT_DIR}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
