"""
The farm runner on clusters built here: Ray with two nodes, Dask with a scheduler and workers.

Each cluster runs docs/farm.md's farm, five seeds recording every run, and a
sixth variation whose worker is killed (SIGKILL) mid-run:

- the five give the verdicts, measures and recording hashes pinned in
  ``test/farm/data/fingerprints.json`` (the same runs made in one process),
  with their recordings written here, on the machine that asked;
- the killed one is reported crashed with its seed, not run again (Ray's
  retries are off; Dask's scheduler starts it again on another worker, and
  that start reports the crash instead of running it); its process is gone
  and so are the Fast DDS segments it held.

Dask's worker is killed on the first variation and the five run after it, on
the worker Dask starts again: none of them may be taken for a crash.
The OpenSCENARIO variations run on the same executors: the crossing's two
documents on a Dask cluster give the verdicts of a local run.

Ray takes about 5 s and 600 MiB per node to start: one cluster of each, and
few variations here. ``bench/farm_clusters.py`` runs the 200 variations of
the done-when on each executor.
"""

import contextlib
import os
from pathlib import Path
import signal
import socket
import subprocess
import sys
import time

import pytest

from helpers import REPO
from r2d2_sim.farm.runner import run_farm
from test_farm_runner import (
    alive, check_against_fingerprints, DEADLINE_S, FARM, Killer, REFERENCE_SEEDS)

VICTIM = 5
# A Ray node's object store: small, it holds one job and small results.
OBJECT_STORE_BYTES = 100 * 1024 * 1024


@pytest.fixture
def victim_env(tmp_path):
    """Point the victim at a pid file; set before any worker process starts (they inherit it)."""
    pid_file = tmp_path / 'victim.pid'
    saved = {k: os.environ.get(k) for k in ('R2D2_FARM_VICTIM', 'PYTHONPATH')}
    os.environ['R2D2_FARM_VICTIM'] = f'{VICTIM}:{pid_file}'
    os.environ['PYTHONPATH'] = os.pathsep.join(
        p for p in (REPO, saved['PYTHONPATH']) if p)
    try:
        yield pid_file
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def check_run(run, killer: Killer, tmp_path: Path, executor: str, workers: int = 2) -> None:
    """Check the pinned five, the victim crashed where it ran, nothing left, all written here."""
    assert run.executor == executor and run.ran == len(REFERENCE_SEEDS) + 1
    check_against_fingerprints(run.records)
    for seed in REFERENCE_SEEDS:
        assert Path(run.records[seed]['outcome']['recording']).parent == \
            tmp_path / 'report' / 'recordings'
    # Ray's two nodes both ran some (Dask's one worker ran them all after it was restarted).
    assert len({run.records[s]['worker'] for s in REFERENCE_SEEDS}) >= workers
    killer.thread.join(DEADLINE_S)
    assert killer.pid is not None, 'the victim never said where it runs'
    crashed = run.records[VICTIM]['crashed']
    assert crashed['reason'].startswith('crashed: its ') and 'died' in crashed['reason']
    # Where it died, as the report's "on:" line says it: the host and the killed process.
    assert (crashed['host'], crashed['pid']) == (socket.gethostname(), killer.pid), crashed
    assert run.records[VICTIM]['worker'] == f'{socket.gethostname()}:{killer.pid}'
    assert run.count('crashed') == 1
    assert f'seed {VICTIM}' in (tmp_path / 'report' / 'report.md').read_text()
    assert not alive(killer.pid)
    assert killer.segments, 'the victim held no Fast DDS segment: nothing was checked'
    assert killer.left() == [], 'segments of the killed worker left in /dev/shm'


def test_a_ray_cluster_of_two_nodes_gives_the_pinned_runs_and_names_a_crash(tmp_path,
                                                                            victim_env):
    import ray
    from ray.cluster_utils import Cluster
    cluster = Cluster(initialize_head=True, head_node_args={
        'num_cpus': 1, 'object_store_memory': OBJECT_STORE_BYTES, 'include_dashboard': False})
    try:
        cluster.add_node(num_cpus=1, object_store_memory=OBJECT_STORE_BYTES)
        cluster.wait_for_nodes()
        killer = Killer(victim_env)
        term = signal.getsignal(signal.SIGTERM)
        run = run_farm(FARM, seeds=REFERENCE_SEEDS + [VICTIM], executor='ray',
                       address=cluster.address, out=tmp_path / 'report', record='all',
                       progress=False)
        assert not ray.is_initialized()  # the runner connected, so it let go
        # ray.init's own SIGTERM handler (sys.exit) would have ended a run with no report.
        assert signal.getsignal(signal.SIGTERM) is term
        check_run(run, killer, tmp_path, 'ray')
        assert 'Ray worker died' in run.records[VICTIM]['crashed']['reason']
    finally:
        cluster.shutdown()


def start(command: list, log: Path) -> subprocess.Popen:
    """Start a cluster process, its output in ``log``."""
    with open(log, 'wb') as out:
        return subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True)


@contextlib.contextmanager
def dask_cluster(tmp_path: Path, workers: int = 2):
    """Run a Dask scheduler and ``workers`` one-thread workers here; yield its address."""
    scheduler_file = tmp_path / 'scheduler.json'
    processes = [start([sys.executable, '-m', 'distributed.cli.dask_scheduler', '--host',
                        '127.0.0.1', '--port', '0', '--no-dashboard', '--scheduler-file',
                        str(scheduler_file)], tmp_path / 'scheduler.log')]
    try:
        deadline = time.monotonic() + DEADLINE_S
        import json
        address = None
        while address is None and time.monotonic() < deadline:
            try:  # the scheduler writes the file: it may exist before its text does
                address = json.loads(scheduler_file.read_text())['address']
            except (OSError, ValueError, KeyError):
                time.sleep(0.05)
        assert address is not None, 'the Dask scheduler never wrote its address'
        for number in range(1, workers + 1):
            processes.append(start([sys.executable, '-m', 'distributed.cli.dask_worker',
                                    '--scheduler-file', str(scheduler_file), '--nthreads', '1',
                                    '--no-dashboard', '--name', f'w{number}'],
                                   tmp_path / f'w{number}.log'))
        from distributed import Client
        with Client(address, timeout='60s') as client:
            client.wait_for_workers(workers, timeout=DEADLINE_S)
        yield address
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in reversed(processes):
            try:
                process.wait(20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


def test_a_dask_scheduler_whose_one_worker_dies_gives_the_pinned_runs_and_names_a_crash(
        tmp_path, victim_env):
    """
    One worker, killed on the first variation: the five after it run on the one Dask starts again.

    (A job scattered to the workers once died with the only worker holding
    it, and every variation still waiting was reported crashed.)
    """
    with dask_cluster(tmp_path, workers=1) as address:
        killer = Killer(victim_env)
        run = run_farm(FARM, seeds=[VICTIM] + REFERENCE_SEEDS, executor='dask',
                       address=address, out=tmp_path / 'report', record='all', progress=False)
        check_run(run, killer, tmp_path, 'dask', workers=1)
        assert 'Dask' in run.records[VICTIM]['crashed']['reason']


def test_openscenario_documents_on_a_dask_cluster_give_the_local_verdicts(tmp_path, victim_env):
    """The crossing's two documents as Dask tasks: the verdicts and measures of a local run."""
    from common import OSC_EXAMPLES
    from r2d2_sim.osc.entry_points import ensure_registered
    from r2d2_sim.osc.variations import executor_map, run_document, tasks_of
    ensure_registered()
    tasks = tasks_of(str(OSC_EXAMPLES / 'crossing.osc'),
                     str(OSC_EXAMPLES / 'crossing_speeds.yaml'))
    with dask_cluster(tmp_path, workers=1) as address:
        verdicts = sorted(executor_map('dask', address)(run_document, tasks),
                          key=lambda v: v.number)
    assert [(v.name, v.passed) for v in verdicts] == [('crossing-0', True),
                                                      ('crossing-1', False)]
    assert all(v.same_as(run_document(t)) for v, t in zip(verdicts, tasks))


WORKER_FAILS = '''
"""A farm that imports everywhere but in a Dask worker (a module not installed there)."""
import multiprocessing
from r2d2_sim.farm import FarmJob, ScenarioSpace, safe
if 'Dask' in multiprocessing.current_process().name:
    raise ImportError('only on the workers')


def idle(harness, scenario):
    """Add nothing."""


FARM = FarmJob(ScenarioSpace(), idle, seconds=0.2, verdict=safe, name='idle')
'''


def test_a_farm_the_dask_workers_cannot_load_stops_in_one_line_as_locally(tmp_path):
    """No variation is reported crashed for it: nothing ran, and nothing is resumed later."""
    from test_farm_runner import farm_env
    farm = tmp_path / 'worker_fails.py'
    farm.write_text(WORKER_FAILS)
    done = subprocess.run(
        [sys.executable, '-m', 'r2d2_sim.farm', 'run', f'{farm}:FARM', '--variations', '3',
         '--executor', 'dask', '--workers', '1', '--out', str(tmp_path / 'report'),
         '--no-progress'], cwd=tmp_path, env=farm_env(), capture_output=True, text=True,
        timeout=DEADLINE_S)
    said = [line for line in done.stderr.splitlines() if line.startswith('r2d2_sim.farm')]
    assert done.returncode == 2, done.stderr
    assert len(said) == 1 and said[0].startswith(
        'r2d2_sim.farm: error: a worker could not load the farm on '), done.stderr
    assert 'importing it raised ImportError: only on the workers' in said[0]
    assert 'crashed' not in done.stdout
    outcomes = list((tmp_path / 'report' / 'outcomes').glob('*.jsonl'))
    assert all(path.read_text() == '' for path in outcomes)
