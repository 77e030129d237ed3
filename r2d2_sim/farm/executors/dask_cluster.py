"""
The Dask executor: each variation a task of a ``distributed`` cluster, a crash never run again.

Dask's scheduler runs a task again on another worker when the worker running
it dies (``distributed.scheduler.allowed-failures``, 3 by default), and that
setting belongs to the scheduler, which may be shared: it is not changed here.
Instead each task marks itself started (a ``distributed.Event`` named for
this run and variation) before it runs; a task that finds its mark set was
started before and its worker died under it, so it runs nothing and reports
the variation crashed. With ``allowed-failures`` 0 the scheduler gives up at
once (``KilledWorker``), also reported as a crash.

Where it runs: ``address`` (``tcp://HOST:8786``), else Dask's own setting
(``DASK_SCHEDULER_ADDRESS``, the ``scheduler-address`` key), else a
``LocalCluster`` started here with ``workers`` processes of one thread each.
Workers should have one thread (``dask worker --nthreads 1``): PyBullet holds
the GIL while it steps, so threads of one process would share a core. The
package (and the farm's module, unless named by a file path that exists on
every worker) must be installed on every worker.
"""

from concurrent.futures import CancelledError
import pickle
from typing import Any, Dict, List, Optional, Sequence, Tuple
import uuid

from r2d2_sim.farm.executors.base import (
    check_pickles, check_reachable, connect_within, Crash, ExecutorError, Finished,
    ship_by_value)
from r2d2_sim.farm.job import Item, LOAD_FAILED, run_variation, TaskResult

__all__ = ['DaskPool', 'run_once', 'take_finished']

SCHEDULER_PORT = 8786
CONNECT_TIMEOUT = '10s'


def run_once(payload: Any, item: Item, record: str, run: str) -> TaskResult:
    """Run the variation, unless an earlier start of it died (then report it crashed)."""
    import os
    import socket
    from distributed import Event, Variable
    mark = Event(f'r2d2-farm-{run}-{item.key}')
    where = Variable(f'r2d2-farm-{run}-{item.key}{WHERE}')
    if mark.is_set():  # the first start's host and process, which died: the crash's place
        host, pid = _where(where)
        return TaskResult(item.key, item.seed, None, CRASHED_BEFORE, None, None, None,
                          host, pid or 0, 0.0)
    where.set(f'{socket.gethostname()}:{os.getpid()}')
    mark.set()
    try:
        return run_variation(payload, item, record)
    finally:
        mark.clear()  # an event cleared is forgotten by the scheduler
        where.delete()


# The suffix of the Variable where a task notes its host and process before it runs.
WHERE = '-where'
WHERE_WAIT = 0.5  # how long a crash's place is looked for (s): a task noted it before it ran


def _where(note: Any) -> Tuple[str, Optional[int]]:
    """Return the host and process a task noted in ``note`` (a Variable); '?' if none."""
    try:
        host, _, pid = str(note.get(timeout=WHERE_WAIT)).rpartition(':')
        return host or '?', int(pid)
    except Exception:  # never noted (died before), the scheduler gone, no client here
        return '?', None


def _place(future: Any) -> Tuple[str, Optional[int]]:
    """Return where the task of ``future`` ran when its worker died, as it noted it."""
    key = getattr(future, 'key', None)
    if not isinstance(key, str):
        return '?', None
    try:
        from distributed import Variable
        return _where(Variable(key + WHERE))
    except Exception:
        return '?', None


# The error of a variation whose first start died: the runner reports it as a crash.
CRASHED_BEFORE = 'its Dask worker died while running it (Dask started it again: not run twice)'


def _why_lost(future: Any) -> str:
    """Say in one line why a task that did not finish ended: erred, cancelled or lost."""
    if future.status == 'cancelled':  # the scheduler forgot it, as after its worker died
        return 'its Dask worker died or the scheduler dropped it (cancelled)'
    try:
        error = future.exception()
    except CancelledError as exc:
        error = exc
    text = str(error).strip().splitlines()[0] if str(error).strip() else ''
    return f'its Dask worker died ({type(error).__name__}: {text})'


def _unloadable(future: Any) -> Optional[str]:
    """
    Return why a worker could not take the task's job in (unpickle it), or None.

    run_once returns every error of the variation itself: a task that erred
    with an import or unpickling error never began (a module of the farm not
    installed on the worker).
    """
    if future.status != 'error':
        return None
    try:
        error = future.exception()
    except CancelledError:
        return None
    if not isinstance(error, (ImportError, pickle.UnpicklingError)):
        return None
    text = str(error).strip().splitlines()[0] if str(error).strip() else ''
    return f'{type(error).__name__}: {text}'


def take_finished(pending: Dict[Any, Item], timeout_s: float) -> List[Finished]:
    """
    Wait up to ``timeout_s`` for one of ``pending``'s futures; take out and return those done.

    A future the scheduler dropped (its worker died: Dask's ``wait`` then
    raises for it, "already forgotten") is a crash with its seed, as is
    one that failed; a task that said it crashed before running is one too.
    """
    from distributed import wait
    try:
        wait(list(pending), timeout=timeout_s, return_when='FIRST_COMPLETED')
    except TimeoutError:
        return []
    except CancelledError:
        pass  # a task the scheduler dropped: a crash, below
    finished: List[Finished] = []
    for future in [f for f in pending if f.status != 'pending']:
        item = pending.pop(future)
        if future.status == 'finished':
            result = future.result()
            if result.error == CRASHED_BEFORE:
                finished.append((item, Crash(item.key, item.seed, CRASHED_BEFORE,
                                             result.host, result.pid or None)))
            else:
                finished.append((item, result))
        else:
            error = _unloadable(future)
            if error is not None:
                raise ExecutorError(f'{LOAD_FAILED}: {error}')
            finished.append((item, Crash(item.key, item.seed, _why_lost(future),
                                         *_place(future))))
    return finished


class DaskPool:
    """Variations of ``payload`` as tasks of a Dask cluster (see the module)."""

    name = 'dask'

    def __init__(self, payload: Any, record: str, address: Optional[str],
                 workers: Optional[int]) -> None:
        try:
            import cloudpickle
            import dask
            import distributed  # noqa: F401
        except ImportError:
            raise ExecutorError('the dask executor needs Dask\'s distributed scheduler: pip '
                                'install "r2d2_sim[dask]" (or pip install "dask[distributed]")'
                                ) from None
        ship_by_value(cloudpickle, payload)
        check_pickles(cloudpickle.dumps, payload)
        self._payload = payload
        self._record = record
        self._address = address or dask.config.get('scheduler-address', None)
        self._workers = workers
        self._run = uuid.uuid4().hex[:12]
        self._client: Any = None
        self._cluster: Any = None
        self._pending: Dict[Any, Item] = {}

    def start(self) -> None:
        """Connect to the scheduler (or start a LocalCluster); ExecutorError if it fails."""
        from distributed import Client, LocalCluster
        try:
            if self._address:
                check_reachable(self._address, 'Dask scheduler', SCHEDULER_PORT)
                address = self._address
                self._client = connect_within(
                    lambda: Client(address, timeout=CONNECT_TIMEOUT), 'Dask scheduler',
                    address)
            else:
                self._cluster = LocalCluster(n_workers=self._workers, threads_per_worker=1,
                                             processes=True, dashboard_address=None)
                self._client = Client(self._cluster)
        except ExecutorError:
            raise
        except (OSError, TimeoutError, ValueError) as exc:
            raise ExecutorError(f'cannot connect to the Dask scheduler at {self._address}: '
                                f'{str(exc).splitlines()[0] if str(exc) else repr(exc)}'
                                ) from None

    def submit(self, items: Sequence[Item]) -> None:
        """
        Submit one task per variation, each carrying the job (a few kB, pickled by value).

        Not scattered once: a scattered job lives on the workers that hold it,
        and once the last of them died the scheduler could not give it to any
        task still waiting, which all ended "crashed" for one dead worker.
        """
        for item in items:
            future = self._client.submit(run_once, self._payload, item, self._record, self._run,
                                         key=f'r2d2-farm-{self._run}-{item.key}', pure=False,
                                         retries=0)
            self._pending[future] = item

    def pending(self) -> int:
        """Return the tasks not finished."""
        return len(self._pending)

    def wait(self, timeout_s: float) -> List[Finished]:
        """Return the tasks finished, waiting up to ``timeout_s`` for one."""
        return take_finished(self._pending, timeout_s) if self._pending else []

    def stop(self) -> None:
        """Cancel the tasks not finished."""
        if self._client is not None and self._pending:
            self._client.cancel(list(self._pending), force=True)
        self._pending.clear()

    def close(self) -> None:
        """Disconnect (and end a LocalCluster started here)."""
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def clean_hosts(self) -> List[str]:
        """Remove the segments dead tasks left, on the host of every worker."""
        from r2d2_sim.farm.shm import clean_dead
        if self._client is None:
            return []
        removed: List[str] = []
        for names in self._client.run(clean_dead).values():
            removed += [n for n in names if n not in removed]
        return removed
