#!/usr/bin/env python3
"""
OpenSCENARIO variations at scale: a 200-document parameter file, in a pool and one by one.

    .venv/bin/python bench/osc_variations.py [--documents 200] [--jobs 2] [--one-by-one 20]

``bench/osc/stopper.osc`` is the farm's example (docs/farm.md) as a scenario; the
parameter file has one document per seed of the farm's space (its boxes, start,
goal and seed), written to ``bench/osc_run/documents.yaml``.

- **Pool**: ``run_variations`` (what ``python -m r2d2_sim.osc`` runs) with ``--jobs``
  processes, twice; every verdict of the second run must equal the first's (verdict,
  reason and measures).
- **One by one**: the same documents as scenario_execution runs a batch
  (scenario_execution_coverage's ``scenario_batch_execution``: a process per
  document, one after another): ``scenario_execution --simulation
  r2d2_sim.osc:R2D2Simulation --scenario-parameter-file <one document>``, for the
  first ``--one-by-one`` documents; their verdicts must be the pool's. Its time for
  all the documents is that sample's mean per document times their number.
- **Ratio**: one by one over the pool (the pool's first run).

Prints, writes ``bench/osc_variations.json``. Numbers are printed, never asserted,
apart from the verdicts' agreement.
"""

import argparse
import json
import os
from pathlib import Path
import shutil
import subprocess
import sys
import time
import xml.etree.ElementTree as ElementTree

from common import background_load, BENCH_DIR, LoadMeter, local_date, machine_info, REPO, \
    write_json

sys.path.insert(0, REPO)

RESULTS_PATH = os.path.join(BENCH_DIR, 'osc_variations.json')
RUN_DIR = Path(BENCH_DIR) / 'osc_run'
SCENARIO = Path(BENCH_DIR) / 'osc' / 'stopper.osc'
EXAMPLE = Path(REPO) / 'test' / 'examples' / 'farm' / 'test_stopper_farm.py'


def farm_space():
    """Return the farm example's ScenarioSpace, from its file."""
    import importlib.util
    spec = importlib.util.spec_from_file_location('farm_example', EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.SPACE


def write_documents(path, count):
    """Write ``count`` documents, one per seed of the farm's space; return the path."""
    import yaml
    space = farm_space()
    documents = []
    for seed in range(count):
        scenario = space.draw(seed)
        x, y = scenario.goal_point
        documents.append({'stopper': {
            'start_x': scenario.start.x, 'start_y': scenario.start.y,
            'start_yaw': scenario.start.yaw, 'goal_x': x, 'goal_y': y,
            'goal_tolerance': scenario.goal.values[2], 'seed': seed,
            'obstacles': json.dumps([[b.x, b.y, b.yaw, *b.size] for b in scenario.obstacles])}})
    path.write_text(yaml.safe_dump_all(documents, sort_keys=True), encoding='utf-8')
    return path


def pool(documents, jobs, out):
    """Run every document in a pool; return (wall s, verdicts)."""
    from r2d2_sim.osc.variations import run_variations
    started = time.perf_counter()
    verdicts = run_variations(str(SCENARIO), str(documents), str(out), jobs=jobs)
    return time.perf_counter() - started, verdicts


def one_by_one(documents, count, env):
    """Run the first ``count`` documents a process each; return (wall s each, verdicts)."""
    texts = documents.read_text(encoding='utf-8').split('\n---\n')
    command = os.path.join(os.path.dirname(sys.executable), 'scenario_execution')
    walls, verdicts = [], []
    for number in range(count):
        single = RUN_DIR / 'single.yaml'
        single.write_text(texts[number], encoding='utf-8')
        out = RUN_DIR / 'single_out'
        shutil.rmtree(out, ignore_errors=True)
        started = time.perf_counter()
        subprocess.run([command, '--simulation', 'r2d2_sim.osc:R2D2Simulation',
                        '--scenario-parameter-file', str(single), '-o', str(out),
                        str(SCENARIO)], env=env, capture_output=True, text=True, timeout=600)
        walls.append(time.perf_counter() - started)
        case = ElementTree.parse(out / 'test.xml').getroot().find('testcase')
        verdicts.append(case.find('failure') is None)
    return walls, verdicts


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--documents', type=int, default=200)
    parser.add_argument('--jobs', type=int, default=2)
    parser.add_argument('--one-by-one', type=int, default=20,
                        help='documents run a process each (the sample of the baseline)')
    args = parser.parse_args()
    from r2d2_sim.osc.entry_points import ensure_registered
    ensure_registered()  # a source checkout: the children find osc.r2d2 through PYTHONPATH
    shutil.rmtree(RUN_DIR, ignore_errors=True)
    RUN_DIR.mkdir(parents=True)
    documents = write_documents(RUN_DIR / 'documents.yaml', args.documents)
    idle = background_load()
    meter = LoadMeter().start()
    first_s, first = pool(documents, args.jobs, RUN_DIR / 'pool')
    second_s, second = pool(documents, args.jobs, RUN_DIR / 'pool_again')
    load = meter.stop()
    same = all(a.same_as(b) for a, b in zip(first, second)) and len(first) == len(second)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (os.environ.get('PYTHONPATH'), REPO) if p))
    sample = min(args.one_by_one, args.documents)
    walls, serial = one_by_one(documents, sample, env)
    agree = serial == [v.passed for v in first[:sample]]
    per_document_s = sum(walls) / len(walls) if walls else float('nan')
    serial_s = per_document_s * args.documents
    passed = sum(v.passed for v in first)
    simulated_s = sum(v.outcome['seconds'] for v in first if v.outcome)
    results = {
        'date': local_date(), 'machine': machine_info(), 'documents': args.documents,
        'jobs': args.jobs, 'cores_busy_before': idle['busy_cores'],
        'cores_busy_during_pools': load['busy_cores'],
        'pool_s': first_s, 'pool_again_s': second_s, 'identical_on_rerun': same,
        'passed': passed, 'failed': args.documents - passed,
        'simulated_s': simulated_s, 'one_by_one_sample': sample,
        'one_by_one_per_document_s': per_document_s, 'one_by_one_s': serial_s,
        'one_by_one_agrees': agree, 'speedup': serial_s / first_s,
        'pool_per_document_s': first_s / args.documents}
    write_json(RESULTS_PATH, results)
    print(f'{args.documents} documents, {args.jobs} processes: {first_s:.1f} s, then '
          f'{second_s:.1f} s; identical on the rerun: {same}; {passed} passed')
    print(f'simulated {simulated_s:.0f} s in all ({simulated_s / first_s:.1f} simulated s per '
          f'wall s); one by one ({sample} sampled, a process each): {per_document_s:.2f} s a '
          f'document, {serial_s:.0f} s for {args.documents}; verdicts agree: {agree}')
    print(f'ratio one by one / pool: {serial_s / first_s:.2f}; other load: '
          f'{idle["busy_cores"]:.2f} cores before, {load["busy_cores"]:.2f} during the pools')


if __name__ == '__main__':
    main()
