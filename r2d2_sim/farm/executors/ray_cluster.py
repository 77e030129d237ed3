"""
The Ray executor: each variation a Ray task, never retried.

Ray retries a task whose worker died three times by default (``max_retries``);
here it is 0, so a killed worker's variation comes back as a
:class:`~r2d2_sim.farm.executors.Crash`. The job is put in the object store
once and every task reads it from there. Ray reuses its worker processes:
each task's simulator has a context of its own and closes it, and leases its
domain on the host it runs on.

Where Ray runs: ``address`` (``ray://HOST:10001``, ``HOST:6379``, ``auto``),
else ``RAY_ADDRESS``, else a Ray instance started here with ``workers`` CPUs
(about 5 s and 600 MiB: say ``--executor ray`` only for a cluster). A process
that is connected to Ray already (``ray.init`` called) is used as it is and
left connected. The package (and the farm's module, unless it is named by a
file path that exists on every node) must be installed on every node.
"""

import os
import signal
import socket
import threading
from typing import Any, Dict, List, Optional, Sequence, Tuple
import uuid

from r2d2_sim.farm.executors.base import (
    check_pickles, check_reachable, connect_within, Crash, ExecutorError, Finished,
    ship_by_value)
from r2d2_sim.farm.job import Item, LOAD_FAILED, run_variation, TaskResult

__all__ = ['RayPool', 'run_noted']

# Ray's ports when an address names none: GCS for HOST, the client server for ray://.
GCS_PORT, CLIENT_PORT = 6379, 10001


class RayPool:
    """Variations of ``payload`` as Ray tasks (see the module)."""

    name = 'ray'

    def __init__(self, payload: Any, record: str, address: Optional[str],
                 workers: Optional[int]) -> None:
        try:
            import ray
            from ray import cloudpickle
        except ImportError:
            raise ExecutorError('the ray executor needs Ray: pip install "r2d2_sim[ray]" '
                                '(or pip install ray)') from None
        self._ray = ray
        ship_by_value(cloudpickle, payload)
        check_pickles(cloudpickle.dumps, payload)
        self._payload = payload
        self._record = record
        self._address = address or os.environ.get('RAY_ADDRESS') or None
        self._workers = workers
        self._ours = False  # did we connect (and so disconnect)?
        self._run = uuid.uuid4().hex[:12]
        self._pending: Dict[Any, Item] = {}
        self._task: Any = None
        self._job: Any = None

    def start(self) -> None:
        """Connect to the cluster (or start Ray here); ExecutorError (one line) if it fails."""
        ray, address = self._ray, self._address
        if not ray.is_initialized():
            if address and address not in ('auto', 'local'):
                client = address.startswith('ray://')
                check_reachable(address, 'Ray cluster', CLIENT_PORT if client else GCS_PORT)
            options: Dict[str, Any] = dict(log_to_driver=False, configure_logging=False)
            if not address or address == 'local':
                options.update(include_dashboard=False, num_cpus=self._workers)
            # ray.init puts a SIGTERM handler of its own (sys.exit) in place of the caller's,
            # which would end a farm run with no report and its tasks still queued.
            term = signal.getsignal(signal.SIGTERM)
            try:
                if address and address not in ('auto', 'local'):
                    connect_within(lambda: ray.init(address=address, **options),
                                   'Ray cluster', address)
                else:
                    ray.init(address=address, **options)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                text = str(exc).strip().splitlines()[0] if str(exc).strip() else repr(exc)
                where = address or 'a new local instance'
                raise ExecutorError(f'cannot connect to Ray at {where}: {text}') from None
            finally:
                if term is not None and threading.current_thread() is threading.main_thread():
                    signal.signal(signal.SIGTERM, term)
            self._ours = True
        self._task = ray.remote(max_retries=0, retry_exceptions=False, num_cpus=1)(
            run_noted)
        self._job = ray.put(self._payload)

    def submit(self, items: Sequence[Item]) -> None:
        """Submit one task per variation."""
        for item in items:
            self._pending[self._task.remote(self._job, item, self._record, self._run)] = item

    def pending(self) -> int:
        """Return the tasks not finished."""
        return len(self._pending)

    def wait(self, timeout_s: float) -> List[Finished]:
        """Return the tasks finished, waiting up to ``timeout_s`` for one."""
        ray = self._ray
        refs = list(self._pending)
        if not refs:
            return []
        ready, _ = ray.wait(refs, num_returns=1, timeout=timeout_s)
        if ready:
            ready, _ = ray.wait(refs, num_returns=len(refs), timeout=0)
        finished: List[Finished] = []
        for ref in ready:
            item = self._pending.pop(ref)
            try:
                finished.append((item, ray.get(ref)))
            except ray.exceptions.RayTaskError as exc:
                # run_variation returns every error of its own: what a task raises is its
                # worker failing to take the job in (unpickling it: a module not installed).
                raise ExecutorError(f'{LOAD_FAILED}: {_reason(exc)}') from None
            except ray.exceptions.RayError as exc:
                host, pid = _noted(_note_key(self._run, item))
                finished.append((item, Crash(item.key, item.seed, _reason(exc), host, pid)))
        return finished

    def stop(self) -> None:
        """Cancel the tasks not finished, killing the workers that run them."""
        for ref in self._pending:
            try:
                self._ray.cancel(ref, force=True)
            except Exception:  # finished meanwhile, or its worker gone already
                pass
        self._pending.clear()

    def close(self) -> None:
        """Disconnect, if this executor connected."""
        if self._ours and self._ray.is_initialized():
            self._ray.shutdown()
        self._ours = False

    def clean_hosts(self) -> List[str]:
        """Remove the segments dead tasks left, on every live node of the cluster."""
        ray = self._ray
        if not ray.is_initialized():
            return []
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy
        from r2d2_sim.farm.shm import clean_dead
        sweep = ray.remote(num_cpus=0, max_retries=0)(clean_dead)
        refs = [sweep.options(scheduling_strategy=NodeAffinitySchedulingStrategy(
            node['NodeID'], soft=False)).remote() for node in ray.nodes() if node['Alive']]
        removed: List[str] = []
        for names in ray.get(refs):
            removed += names
        return removed


def _note_key(run: str, item: Item) -> bytes:
    return f'r2d2-farm-{run}-{item.key}-where'.encode()


def run_noted(payload: Any, item: Item, record: str, run: str) -> TaskResult:
    """
    Note this task's host and process in Ray's key-value store, then run the variation.

    Should the worker die, the runner reads the note and names where it died
    (Ray's WorkerCrashedError does not say); a task that finishes removes it.
    """
    from ray.experimental import internal_kv
    key = _note_key(run, item)
    try:
        internal_kv._internal_kv_put(key, f'{socket.gethostname()}:{os.getpid()}'.encode())
    except Exception:  # a note is a nicety: never a reason not to run
        key = b''
    try:
        return run_variation(payload, item, record)
    finally:
        if key:
            try:
                internal_kv._internal_kv_del(key)
            except Exception:
                pass


def _noted(key: bytes) -> Tuple[str, Optional[int]]:
    """Return the host and process a task noted under ``key``; '?' and None if none."""
    try:
        from ray.experimental import internal_kv
        text = internal_kv._internal_kv_get(key)
        internal_kv._internal_kv_del(key)
        host, _, pid = text.decode().rpartition(':')
        return host or '?', int(pid)
    except Exception:  # never noted (it died before), or the cluster is gone
        return '?', None


def _reason(exc: BaseException) -> str:
    """Say in one line how a task's worker died."""
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else ''
    return f'its Ray worker died ({type(exc).__name__}: {first})'
