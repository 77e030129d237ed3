#!/usr/bin/env python3
"""
The farm runner in one run: start-up, overhead per task, 200 variations alike everywhere.

    .venv/bin/python bench/farm_runner.py [--variations 200] [--tiny 40] [--skip-clusters]

1. **Local start-up**: the local executor's worker processes, spawned to
   ready for work (rclpy, PyBullet and the farm imported), and the whole
   command (``python -m r2d2_sim.farm run``) for one tiny variation.
2. **Per-task overhead beyond the simulator's own start-up**, on each
   executor (local processes; Ray, a cluster of two nodes built here;
   Dask, a scheduler and two workers started as processes): ``--tiny``
   variations of 0.05 simulated seconds (each task builds and closes its
   simulator, which is the task's own time, ``task_s``, measured inside the
   worker); overhead per task = (wall time of the tasks x workers - sum of
   task_s - the local workers' start-up) / tasks, after a first run that warms
   the cluster's workers (the bench stays connected to Ray, whose workers
   belong to a connection).
3. **200 variations alike on every executor**: docs/farm.md's farm (20
   simulated seconds each), every run recorded, on local, Ray and Dask:
   verdicts, measures (SHA-256 of their JSON) and recording hashes compared
   variation by variation, and the five pinned in
   ``test/farm/data/fingerprints.json`` checked.
4. **The README farm, 200 x 20 simulated seconds, locally**
   (``python -m r2d2_sim.farm run test_stopper_farm.py:FARM``, failures
   recorded, the report and its picture written), wall time from the
   command's start to its exit; physics steps per second per worker against
   raw ``stepSimulation`` of the same worlds (``farm.py``'s measure, before
   and after).

Cores kept busy by other processes are measured before (1 s) and during the
README farm. Writes ``bench/farm_runner.json`` (the README farm's report
stays in ``bench/farm_run/``; docs/farm.md shows ``farm.py``'s, of the
pytest farm); numbers printed, never asserted.
"""

import argparse
import hashlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from common import background_load, BENCH_DIR, LoadMeter, local_date, machine_info, REPO, \
    write_json
from farm import EXAMPLE, measure_raw

RESULTS_PATH = os.path.join(BENCH_DIR, 'farm_runner.json')
JOBS = os.path.join(REPO, 'test', 'system', 'farm_jobs.py')
FINGERPRINTS = os.path.join(REPO, 'test', 'farm', 'data', 'fingerprints.json')
OBJECT_STORE_BYTES = 100 * 1024 * 1024
TINY = '''
from r2d2_sim.farm import FarmJob
import sys
sys.path.insert(0, {folder!r})
import test_stopper_farm as example

TINY = FarmJob(example.SPACE, example.goal_stopper, seconds=0.05, verdict=example.safe,
               parameters=example.PARAMETERS, name='tiny')
'''


def env():
    """Return the environment of a farm command: this checkout first on the path."""
    return dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (REPO, os.environ.get('PYTHONPATH')) if p))


def overhead(run, workers):
    """
    Return the wall time per task beyond its own time in its worker (s), and its parts.

    The workers' time is the tasks' wall time times the workers; what is not a
    task's own time (``task_s``: building, running and closing its simulator,
    inside the worker) nor a local worker's start-up (spawned to ready) is
    overhead: sending the task and its result, scheduling, idle gaps.
    """
    task_s = [r['farm']['task_s'] for r in run.records.values()]
    wall = run.run_s
    start_up = sum(run.ready_s)
    return {'tasks': len(task_s), 'workers': workers, 'run_s': wall, 'start_s': run.start_s,
            'workers_start_up_s': start_up, 'task_s_mean': statistics.mean(task_s),
            'overhead_s_per_task': (wall * workers - start_up - sum(task_s)) / len(task_s)}


def fingerprint(record):
    """Return what must agree between executors: verdict, measures' hash, recording's hash."""
    outcome = record['outcome']
    if outcome is None:
        return ('crashed', record['crashed']['reason'])
    measures = {k: v for k, v in outcome.items() if k not in ('wall_s', 'recording')}
    return (outcome['passed'], outcome['reason'],
            hashlib.sha256(json.dumps(measures, sort_keys=True).encode()).hexdigest(),
            record['farm']['recording_sha256'])


def tiny_job(scratch):
    """Write the tiny farm (0.05 simulated s per variation); return its FILE:NAME."""
    path = os.path.join(scratch, 'tiny_farm.py')
    with open(path, 'w', encoding='utf-8') as out:
        out.write(TINY.format(folder=os.path.dirname(EXAMPLE)))
    return f'{path}:TINY'


class Clusters:
    """A Ray cluster of two nodes and a Dask scheduler with two workers, built here."""

    def __init__(self, scratch):
        self.scratch = scratch
        self.ray = None
        self.dask_address = None
        self.processes = []

    def start_ray(self):
        from ray.cluster_utils import Cluster
        self.ray = Cluster(initialize_head=True, head_node_args={
            'num_cpus': 1, 'object_store_memory': OBJECT_STORE_BYTES,
            'include_dashboard': False})
        self.ray.add_node(num_cpus=1, object_store_memory=OBJECT_STORE_BYTES)
        self.ray.wait_for_nodes()
        return self.ray.address

    def start_dask(self):
        scheduler_file = os.path.join(self.scratch, 'scheduler.json')
        log = open(os.path.join(self.scratch, 'dask.log'), 'wb')
        self.processes.append(subprocess.Popen(
            [sys.executable, '-m', 'distributed.cli.dask_scheduler', '--host', '127.0.0.1',
             '--port', '0', '--no-dashboard', '--scheduler-file', scheduler_file],
            stdout=log, stderr=subprocess.STDOUT, env=env(), start_new_session=True))
        deadline = time.monotonic() + 60
        while not os.path.exists(scheduler_file) and time.monotonic() < deadline:
            time.sleep(0.05)
        with open(scheduler_file, encoding='utf-8') as source:
            self.dask_address = json.load(source)['address']
        for name in ('w1', 'w2'):
            self.processes.append(subprocess.Popen(
                [sys.executable, '-m', 'distributed.cli.dask_worker', '--scheduler-file',
                 scheduler_file, '--nthreads', '1', '--no-dashboard', '--name', name],
                stdout=log, stderr=subprocess.STDOUT, env=env(), start_new_session=True))
        from distributed import Client
        with Client(self.dask_address, timeout='60s') as client:
            client.wait_for_workers(2, timeout=120)
        return self.dask_address

    def stop(self):
        if self.ray is not None:
            self.ray.shutdown()
        for process in reversed(self.processes):
            process.terminate()
        for process in reversed(self.processes):
            try:
                process.wait(20)
            except subprocess.TimeoutExpired:
                process.kill()


def readme_farm(variations, workers):
    """Run the README farm with the runner's command; return wall time, report and load."""
    out = os.path.join(BENCH_DIR, 'farm_run')
    shutil.rmtree(out, ignore_errors=True)
    command = [sys.executable, '-m', 'r2d2_sim.farm', 'run', f'{EXAMPLE}:FARM',
               '--variations', str(variations), '--workers', str(workers), '--out', out,
               '--no-progress']
    meter = LoadMeter().start()
    started = time.perf_counter()
    done = subprocess.run(command, cwd=REPO, env=env(), capture_output=True, text=True)
    wall = time.perf_counter() - started
    load = meter.stop()
    with open(os.path.join(out, 'report.json'), encoding='utf-8') as source:
        report = json.load(source)
    return {'wall_s': wall, 'returncode': done.returncode, 'load': load,
            'stdout': done.stdout.strip().splitlines()[:1], 'summary': report['summary']}


def main(argv=None):
    """Run the runner's bench; print and save the results."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--variations', type=int, default=200)
    parser.add_argument('--tiny', type=int, default=40)
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--raw-sample', type=int, default=20)
    parser.add_argument('--skip-clusters', action='store_true')
    parser.add_argument('--readme-only', action='store_true',
                        help='only part 4, the README farm (the rest of farm_runner.json kept)')
    args = parser.parse_args(argv)
    os.environ['PYTHONPATH'] = env()['PYTHONPATH']  # the clusters' workers import this checkout
    from r2d2_sim.farm.runner import run_farm
    results = {'machine': machine_info(), 'date': local_date(), 'variations': args.variations,
               'workers': args.workers, 'background_load_before': background_load()}
    if args.readme_only:
        with open(RESULTS_PATH, encoding='utf-8') as source:
            earlier = json.load(source)
        results = dict(earlier, readme_date=results['date'],
                       readme_background_load_before=results['background_load_before'])
    else:
        results.update(run_executors(args, run_farm))
    # 4. The README farm.
    step = max(1, args.variations // args.raw_sample)
    seeds = list(range(0, args.variations, step))[:args.raw_sample]
    raw_before = measure_raw(seeds)
    farm = readme_farm(args.variations, args.workers)
    raw_after = measure_raw(seeds)
    raw = statistics.median(raw_before + raw_after)
    steps = farm['summary']['physics_steps']
    per_worker = steps / farm['wall_s'] / args.workers
    results.update(readme_farm=farm, raw_steps_per_s_before=raw_before,
                   raw_steps_per_s_after=raw_after, raw_steps_per_s_median=raw,
                   farm_steps_per_s_per_worker=per_worker, ratio_to_raw=per_worker / raw)
    write_json(RESULTS_PATH, results)
    show(results, args, farm, steps, per_worker, raw)
    return 0


def run_executors(args, run_farm):
    """Parts 1-3: start-up, overhead per task and the 200 compared, on every executor."""
    results = {}
    scratch = tempfile.mkdtemp(prefix='r2d2_farm_bench_')
    tiny = tiny_job(scratch)
    clusters = Clusters(scratch)
    try:
        # 1. Local start-up.
        started = time.perf_counter()
        one = subprocess.run([sys.executable, '-m', 'r2d2_sim.farm', 'run', tiny, '--seeds', '0',
                              '--workers', '1', '--out', os.path.join(scratch, 'one'),
                              '--no-progress', '--record', 'none'],
                             cwd=REPO, env=env(), capture_output=True, text=True)
        results['one_tiny_variation_command_s'] = time.perf_counter() - started
        results['one_tiny_variation_returncode'] = one.returncode
        # 2. Per-task overhead, and 3. the same 200 everywhere.
        executors = [('local', None)]
        if not args.skip_clusters:
            executors += [('ray', clusters.start_ray()), ('dask', clusters.start_dask())]
        results['overhead'], results['alike'] = {}, {}
        prints = {}
        for name, address in executors:
            if name == 'ray':  # connected here, so its workers stay warm between runs
                import ray
                ray.init(address=address, log_to_driver=False, configure_logging=False)
            for attempt in ('warm-up', 'measured'):
                run = run_farm(tiny, variations=args.tiny, executor=name, address=address,
                               workers=args.workers, out=os.path.join(scratch, f'{name}-tiny'),
                               fresh=True, record='none', progress=False, picture=False)
            results['overhead'][name] = overhead(run, args.workers)
            if name == 'local':
                results['local_workers_ready_s'] = run.ready_s
            run = run_farm(f'{JOBS}:FARM', variations=args.variations, executor=name,
                           address=address, workers=args.workers,
                           out=os.path.join(scratch, f'{name}-200'), fresh=True, record='all',
                           progress=False, picture=False)
            prints[name] = {key: fingerprint(r) for key, r in run.records.items()}
            results['alike'][name] = {'ran': run.ran, 'run_s': run.run_s,
                                      'failed': run.count('failed'),
                                      'crashed': run.count('crashed')}
            print(f'{name}: overhead {results["overhead"][name]["overhead_s_per_task"] * 1e3:.1f}'
                  f' ms per task; {run.ran} variations in {run.run_s:.1f} s', flush=True)
            if name == 'ray':
                ray.shutdown()
        reference = prints['local']
        with open(FINGERPRINTS, encoding='utf-8') as source:
            pinned = json.load(source)
        results['pinned_match'] = all(
            reference[s][0] == pinned[f'stopper-{s}']['passed']
            and reference[s][2] == pinned[f'stopper-{s}']['measures_sha256']
            and reference[s][3] == pinned[f'stopper-{s}']['recording_sha256']
            for s in range(min(5, args.variations)))
        for name in prints:
            differ = sorted(k for k in reference if prints[name].get(k) != reference[k])
            results['alike'][name]['differ_from_local'] = differ
            results['alike'][name]['identical'] = not differ and len(prints[name]) == len(
                reference)
    finally:
        clusters.stop()
        shutil.rmtree(scratch, ignore_errors=True)
    return results


def show(results, args, farm, steps, per_worker, raw):
    """Print the numbers."""
    before = results.get('readme_background_load_before', results['background_load_before'])
    print(f'\nlocal workers ready in {max(results["local_workers_ready_s"] or [0]):.2f} s; one '
          f'tiny variation, whole command: {results["one_tiny_variation_command_s"]:.2f} s')
    for name, numbers in results['overhead'].items():
        alike = results['alike'][name]
        print(f'{name}: per-task overhead {numbers["overhead_s_per_task"] * 1e3:.1f} ms '
              f'(tasks {numbers["task_s_mean"] * 1e3:.0f} ms each); {alike["ran"]} x 20 s '
              f'identical to local: {alike["identical"]}')
    print(f'the five pinned seeds match test/farm/data/fingerprints.json: '
          f'{results["pinned_match"]}')
    print(f'README farm, {args.variations} x 20 simulated s, local: {farm["wall_s"]:.1f} s '
          f'(exit {farm["returncode"]}; cores busy {farm["load"]["busy_cores"]:.2f}, other '
          f'processes before {before["busy_cores"]:.2f}); '
          f'{steps:,} steps, {per_worker:,.0f} steps/s per worker = {per_worker / raw:.2f} of '
          f'raw ({raw:,.0f})')


if __name__ == '__main__':
    raise SystemExit(main())
