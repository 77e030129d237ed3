"""
What every executor shares: a crash, an executor's one-line error, its interface, address checks.

See :mod:`r2d2_sim.farm.executors` for the executors themselves.
"""

import os
import socket
import sys
import threading
from typing import (Any, Callable, Dict, List, NamedTuple, Optional, Protocol, Sequence, Tuple,
                    TypeVar, Union)

from r2d2_sim.farm.job import FarmJob, Item, TaskResult

__all__ = ['Crash', 'Executor', 'ExecutorError', 'Finished', 'EXECUTORS', 'check_reachable',
           'check_pickles', 'ship_by_value', 'default_workers', 'connect_within',
           'handshake_timeout_s']

EXECUTORS = ('local', 'ray', 'dask')
# How long a cluster's address may take to accept a connection before it counts as
# unreachable (s).
CONNECT_TIMEOUT_S = 5.0
# How long connecting to a cluster may take in all, handshake included (s): something else
# answering on the port (a dashboard, another service) makes the clients wait for ever.
HANDSHAKE_TIMEOUT_S = 30.0
HANDSHAKE_TIMEOUT_ENV = 'R2D2_FARM_CONNECT_TIMEOUT_S'

T = TypeVar('T')


class ExecutorError(RuntimeError):
    """An executor that cannot be used (missing extra, unreachable address...): one line."""


class Crash(NamedTuple):
    """A variation whose process died while running it: ``reason`` says how, in one line."""

    key: int
    seed: int
    reason: str
    host: str
    pid: Optional[int]


Finished = Tuple[Item, Union[TaskResult, Crash]]


class Executor(Protocol):
    """What the runner asks of an executor."""

    name: str

    def start(self) -> None:
        """Start or connect; ExecutorError (one line) when it cannot."""

    def submit(self, items: Sequence[Item]) -> None:
        """Queue these variations."""

    def wait(self, timeout_s: float) -> List[Finished]:
        """Return the variations finished since the last call, waiting up to ``timeout_s``."""

    def pending(self) -> int:
        """Return how many submitted variations have not finished."""

    def stop(self) -> None:
        """Cancel what has not finished (killing its processes) and let go of the workers."""

    def close(self) -> None:
        """Let go of the workers once everything finished."""

    def clean_hosts(self) -> List[str]:
        """Remove the Fast DDS segments dead tasks left on every host; return the names."""


def default_workers() -> int:
    """Return the number of cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def check_reachable(address: str, what: str, default_port: int) -> None:
    """
    Connect to ``host:port`` of ``address`` once; ExecutorError (one line) if nothing answers.

    Cluster clients retry an unreachable address for a long while before
    failing with a traceback: this says so in one line, at once.
    """
    rest = address.split('://', 1)[-1].split('/', 1)[0]
    host, colon, port_text = rest.rpartition(':')
    if not colon:
        host, port_text = rest, str(default_port)
    host = host.strip('[]') or 'localhost'
    try:
        port = int(port_text)
    except ValueError:
        raise ExecutorError(f'{what} address {address!r}: the port is not a number') from None
    try:
        with socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise ExecutorError(f'cannot reach the {what} at {address} ({host}:{port}: {reason}); '
                            f'is it running, and is the address right?') from None


def handshake_timeout_s() -> float:
    """Return how long a connect may take (``R2D2_FARM_CONNECT_TIMEOUT_S``, default 30 s)."""
    text = os.environ.get(HANDSHAKE_TIMEOUT_ENV, '')
    try:
        value = float(text) if text else HANDSHAKE_TIMEOUT_S
    except ValueError:
        raise ExecutorError(f'{HANDSHAKE_TIMEOUT_ENV}={text!r}: a number of seconds') from None
    if not value > 0:
        raise ExecutorError(f'{HANDSHAKE_TIMEOUT_ENV}={text!r}: more than 0 s')
    return value


def connect_within(connect: Callable[[], T], what: str, address: str) -> T:
    """
    Return ``connect()``, run in a thread; ExecutorError (one line) if it takes too long.

    A cluster client that reaches a port where something else answers (a
    dashboard, an HTTP server, a load balancer) retries its handshake for
    ever: the connect is given :func:`handshake_timeout_s`, then abandoned
    (its daemon thread ends with the process). What ``connect`` raises is
    raised here.
    """
    seconds = handshake_timeout_s()
    box: Dict[str, Any] = {}

    def attempt() -> None:
        try:
            box['value'] = connect()
        except BaseException as exc:  # handed to the caller's thread
            box['error'] = exc
    thread = threading.Thread(target=attempt, name='r2d2_farm-connect', daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        raise ExecutorError(f'the {what} at {address} did not answer as one within {seconds:g} s '
                            f'(something else listens there? is the port the {what}\'s?); '
                            f'{HANDSHAKE_TIMEOUT_ENV} sets the wait')
    if 'error' in box:
        raise box['error']
    return box['value']


def ship_by_value(pickler: Any, payload: Any) -> None:
    """
    Have cloudpickle copy the modules of the job's functions that the workers cannot import.

    A farm defined in a test file or a script is a module of the driver only:
    its controller, verdict and space travel by value instead. Installed
    packages (site-packages) and r2d2_sim itself travel by reference.
    """
    if not isinstance(payload, FarmJob):
        return
    for thing in (payload.controller, payload.verdict, type(payload.space)):
        module = sys.modules.get(getattr(thing, '__module__', '') or '')
        path = getattr(module, '__file__', None) or ''
        if (module is None or module.__name__ in ('__main__', 'builtins')
                or module.__name__.split('.')[0] == 'r2d2_sim'
                or 'site-packages' in path or 'dist-packages' in path):
            continue
        pickler.register_pickle_by_value(module)


def check_pickles(dumps: Any, payload: Any) -> None:
    """Raise ExecutorError (one line) if the job does not pickle with the cluster's pickler."""
    try:
        dumps(payload)
    except Exception as exc:
        raise ExecutorError(f'the farm does not pickle, so it cannot reach the cluster\'s '
                            f'workers ({type(exc).__name__}: {exc})') from None
