"""
Where a farm's variations run: a local process pool, a Ray cluster, a Dask cluster.

Each executor runs :func:`r2d2_sim.farm.job.run_variation` once per
variation, one task per variation, and gives back each task's
:class:`~r2d2_sim.farm.job.TaskResult`, or a :class:`Crash` when the process
running it died (killed, out of memory, a crash in C): never retried, so a
crash is reported as a crash, with its seed. They share one small interface
(:class:`Executor`); the runner (:mod:`r2d2_sim.farm.runner`) drives it.

- ``local`` (:mod:`.local`): processes of this machine started with ``spawn``
  (never ``fork`` after DDS started), one variation at a time each, a dead
  one replaced; no dependency beyond the package.
- ``ray`` (:mod:`.ray_cluster`) and ``dask`` (:mod:`.dask_cluster`): optional
  extras (``pip install 'r2d2_sim[ray]'`` / ``'r2d2_sim[dask]'``), imported
  only when chosen.

:func:`choose` picks one: the name given, else the kind of the address
given, else ``RAY_ADDRESS`` (Ray), else ``DASK_SCHEDULER_ADDRESS`` (Dask),
else local.
"""

import os
from typing import Any, Optional

from r2d2_sim.farm.executors.base import (
    check_pickles, check_reachable, Crash, default_workers, Executor, ExecutorError, EXECUTORS,
    Finished, ship_by_value)

__all__ = ['Crash', 'Executor', 'ExecutorError', 'Finished', 'choose', 'EXECUTORS',
           'check_reachable', 'check_pickles', 'ship_by_value', 'default_workers']


def _kind_of(address: str) -> Optional[str]:
    """Return the executor an address belongs to by its form, or None if it does not say."""
    if address == 'auto' or address.startswith('ray://'):
        return 'ray'
    if address.split('://', 1)[0] in ('tcp', 'tls', 'ucx', 'inproc', 'ws', 'wss'):
        return 'dask'
    return None


def choose(name: Optional[str], address: Optional[str], *, payload: Any, record: str,
           workers: Optional[int]) -> 'Executor':
    """
    Return the executor to use (not started); ExecutorError (one line) when none fits.

    ``name`` (local, ray, dask) wins; else an ``address`` of a known form
    (``ray://``, ``auto``: Ray; ``tcp://``...: Dask); else ``RAY_ADDRESS``,
    then ``DASK_SCHEDULER_ADDRESS``; else local. ``payload`` is the
    :class:`~r2d2_sim.farm.job.FarmJob` or its
    :class:`~r2d2_sim.farm.job.JobSource`.
    """
    if name is not None and name not in EXECUTORS:
        raise ExecutorError(f'--executor {name}: one of {", ".join(EXECUTORS)}')
    if workers is not None and workers < 1:  # None: each executor's default
        raise ExecutorError(f'--workers {workers}: at least 1')
    if name is None and address:
        name = _kind_of(address)
        if name is None:
            raise ExecutorError(f'--address {address}: say which cluster it is with --executor '
                                'ray or --executor dask (or write ray://HOST:PORT or '
                                'tcp://HOST:PORT)')
    if name is None:
        if os.environ.get('RAY_ADDRESS'):
            name = 'ray'
        elif os.environ.get('DASK_SCHEDULER_ADDRESS'):
            name = 'dask'
        else:
            name = 'local'
    if name == 'local':
        if address:
            raise ExecutorError(f'--address {address}: the local executor takes no address')
        from r2d2_sim.farm.executors.local import LocalPool
        return LocalPool(payload, record, default_workers() if workers is None else workers)
    if name == 'ray':
        from r2d2_sim.farm.executors.ray_cluster import RayPool
        return RayPool(payload, record, address, workers)
    from r2d2_sim.farm.executors.dask_cluster import DaskPool
    return DaskPool(payload, record, address, workers)
