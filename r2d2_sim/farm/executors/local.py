"""
The local executor: processes of this machine, started with ``spawn``, a variation at a time.

Why not :class:`concurrent.futures.ProcessPoolExecutor`: when one of its
workers dies, it breaks the whole pool and fails every pending future, so
a single killed variation would take the others' verdicts with it, and it
cannot say which variation the dead worker ran. Here each worker has a pipe
of its own and runs one variation at a time, so a dead worker names exactly
the variation it ran (a :class:`~r2d2_sim.farm.executors.Crash`, never run
again), is replaced, and the Fast DDS segments it left are removed
(:func:`r2d2_sim.farm.shm.clean_dead`). The simulator runs inside the worker,
so it dies with it.

Workers start with ``spawn``: a fresh interpreter, never a ``fork`` of a
process whose DDS threads run (rclpy #328). Each imports the farm's run
(rclpy, PyBullet) and the job once, then takes variation after variation;
it ignores Ctrl-C (the runner stops it) and ends when the runner's process
ends (:func:`r2d2_sim.client.end_with_parent`: SIGTERM, then SIGKILL).
"""

import multiprocessing
from multiprocessing.connection import Connection, wait as wait_for_any
import os
import pickle
import signal
import socket
import time
from typing import Any, Dict, List, Optional, Sequence

from r2d2_sim.farm.executors.base import Crash, ExecutorError, Finished
from r2d2_sim.farm.job import Item, prepare, run_variation

__all__ = ['LocalPool', 'payload_bytes']

# A worker that does not answer the runner's stop within this is killed (s).
STOP_GRACE_S = 2.0


def payload_bytes(payload: Any) -> bytes:
    """Pickle the job as the workers get it; ExecutorError (one line) if it does not pickle."""
    try:
        return pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception as exc:  # pickle raises PicklingError, AttributeError, TypeError...
        raise ExecutorError(
            f'the farm does not pickle, so it cannot reach the worker processes '
            f'({type(exc).__name__}: {exc}): define its space, controller and verdict at the '
            'top level of a module (no lambdas, no functions inside functions), or name it '
            'as FILE.py:NAME') from None


class _Worker:
    """One worker process, its end of the pipe and the variation it runs now."""

    def __init__(self, process: Any, connection: Connection) -> None:
        self.process = process
        self.connection = connection
        self.item: Optional[Item] = None
        self.dead = False


class LocalPool:
    """
    ``workers`` processes of this machine running variations of ``payload``.

    ``payload`` is a :class:`~r2d2_sim.farm.job.FarmJob` or a
    :class:`~r2d2_sim.farm.job.JobSource`; ``record`` what each task records
    (:data:`~r2d2_sim.farm.job.RECORD_MODES`).
    """

    name = 'local'

    def __init__(self, payload: Any, record: str, workers: int) -> None:
        if workers < 1:
            raise ExecutorError(f'--workers {workers}: at least 1')
        self._payload = payload_bytes(payload)
        self._record = record
        self._count = workers
        self._context = multiprocessing.get_context('spawn')
        self._workers: List[_Worker] = []
        self._queue: List[Item] = []
        self._finished: List[Finished] = []
        self._started = 0
        self.errors: List[str] = []  # a worker that could not load the job says why
        self.cleaned: List[str] = []  # Fast DDS segments dead workers left, removed
        self.started_at = 0.0
        self.ready_s: List[float] = []  # each worker's start-up: spawned to ready for work (s)

    def start(self) -> None:
        """Start the workers (they import the run and the job while the first tasks wait)."""
        self.started_at = time.perf_counter()
        for _ in range(self._count):
            self._spawn()

    def _spawn(self) -> None:
        mine, theirs = self._context.Pipe()
        self._started += 1
        process = self._context.Process(
            target=_serve, args=(theirs, os.getpid(), self._payload, self._record),
            name=f'r2d2_farm-{self._started}', daemon=True)
        process.start()
        theirs.close()
        self._workers.append(_Worker(process, mine))

    def submit(self, items: Sequence[Item]) -> None:
        """Queue ``items``; idle workers take them at once."""
        self._queue.extend(items)
        self._dispatch()

    def pending(self) -> int:
        """Return the variations queued or running."""
        return len(self._queue) + sum(w.item is not None for w in self._workers)

    def _dispatch(self) -> None:
        for worker in self._workers:
            if worker.item is None and not worker.dead and self._queue:
                worker.item = self._queue.pop(0)
                try:
                    worker.connection.send(worker.item)
                except OSError:
                    worker.dead = True  # found by wait(), its variation reported crashed

    def wait(self, timeout_s: float) -> List[Finished]:
        """Return what finished, waiting up to ``timeout_s`` for something to."""
        if not self._finished:
            watched: Dict[Any, _Worker] = {}
            for worker in self._workers:
                watched[worker.connection] = worker
                watched[worker.process.sentinel] = worker
            for ready in wait_for_any(list(watched), timeout_s):
                worker = watched[ready]
                if ready is worker.connection:
                    self._receive(worker)
            self._bury()
        self._dispatch()
        finished, self._finished = self._finished, []
        return finished

    def _receive(self, worker: _Worker) -> None:
        try:
            while worker.connection.poll():
                kind, body = worker.connection.recv()
                if kind == 'done' and worker.item is not None:
                    self._finished.append((worker.item, body))
                    worker.item = None
                elif kind == 'ready':
                    self.ready_s.append(time.perf_counter() - self.started_at)
                elif kind == 'error':
                    self.errors.append(body)
        except (EOFError, OSError):
            worker.dead = True

    def _bury(self) -> None:
        """Report the variation of each dead worker as crashed; replace it if work remains."""
        dead = [w for w in self._workers if w.dead or not w.process.is_alive()]
        if not dead:
            return
        from r2d2_sim.farm.shm import clean_dead
        for worker in dead:
            worker.process.join(STOP_GRACE_S)
            self._receive(worker)  # a result sent just before it died still counts
            if worker.item is not None:
                self._finished.append((worker.item, Crash(
                    worker.item.key, worker.item.seed, _how_it_died(worker.process),
                    socket.gethostname(), worker.process.pid)))
                worker.item = None
            worker.connection.close()
            self._workers.remove(worker)
        self.cleaned += clean_dead()
        if self.errors:
            raise ExecutorError(self.errors[0])
        missing = self._count - len(self._workers)
        for _ in range(min(missing, len(self._queue))):
            self._spawn()

    def stop(self) -> None:
        """Kill every worker now (what runs is not finished: the report leaves it out)."""
        for worker in self._workers:
            if worker.process.is_alive():
                worker.process.kill()
        for worker in self._workers:
            worker.process.join(STOP_GRACE_S)
            worker.connection.close()
        self._workers.clear()
        self._queue.clear()

    def close(self) -> None:
        """Ask idle workers to end, and end the rest."""
        for worker in self._workers:
            try:
                worker.connection.send(None)
            except OSError:
                pass
        for worker in self._workers:
            worker.process.join(STOP_GRACE_S)
        self.stop()

    def clean_hosts(self) -> List[str]:
        """Remove the segments dead workers left on this host."""
        from r2d2_sim.farm.shm import clean_dead
        self.cleaned += clean_dead()
        return self.cleaned


def _how_it_died(process: Any) -> str:
    code = process.exitcode
    if code is None:
        return f'its worker process {process.pid} stopped answering'
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f'signal {-code}'
        return f'its worker process {process.pid} died, killed by {name}'
    return f'its worker process {process.pid} exited with status {code} while running it'


def _serve(connection: Connection, parent: int, payload: bytes, record: str) -> None:
    """Serve as a worker: load the run and the job, then run what the pipe brings."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the runner's to handle
    from r2d2_sim.client import end_with_parent, PARENT_PID_ENV
    os.environ[PARENT_PID_ENV] = str(parent)
    try:
        end_with_parent()
        job = prepare(pickle.loads(payload))
    except Exception as exc:
        connection.send(('error', f'a worker could not load the farm: {exc}'))
        return
    connection.send(('ready', os.getpid()))
    while True:
        try:
            item = connection.recv()
        except (EOFError, OSError):
            return
        if item is None:
            return
        connection.send(('done', run_variation(job, item, record)))
