"""
One rclpy context on a leased domain, with an executor the caller can take over.

:class:`RosHarness` is the base of :class:`~r2d2_sim.testing.harness.SimHarness`:
an rclpy context of its own on a ROS domain no other harness uses, and an
executor that a thread spins until the caller's thread takes it over to run
callbacks to idleness itself (lockstep). Errors raised in callbacks come back
to the caller as :class:`CallbackError`. :func:`import_interface` imports the
interface packages that are not on PyPI, or says in one line how to get them.
"""

import atexit
import importlib
from contextlib import contextmanager
import math
import os
import threading
import time
from types import TracebackType
import weakref
from typing import Any, Callable, Iterator, List, Mapping, Optional, Type

import rclpy
from rclpy.context import Context
from rclpy.executors import (
    ConditionReachedException, ExternalShutdownException, ShutdownException, TimeoutException)
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.subscription import Subscription

from r2d2_sim.client import numbers_alike, wait_for
from r2d2_sim.testing.domains import lease_domain
from r2d2_sim.testing.lockstep import Handler, LockstepExecutor

__all__ = ['HarnessError', 'CallbackError', 'parameter_overrides', 'RosHarness']

# The spinning thread looks for a stop request at least this often (s).
SPIN_POLL_S = 0.05


class HarnessError(RuntimeError):
    """The harness or the simulator did not do what was asked before the deadline."""


class CallbackError(HarnessError):
    """A callback in the harness's executor raised; the original exception is the cause."""


class MissingInterfaceError(HarnessError):
    """A verb needs an interface package (tf2_msgs, simulation_interfaces) that is not there."""


def import_interface(module: str, needed_by: str) -> Any:
    """
    Import ``module`` of an interface package not on PyPI (``tf2_msgs.msg``...) and return it.

    A pip-only venv has it only after ``tools/build_interfaces.sh VENV``:
    without it, :class:`MissingInterfaceError` says so in one line naming
    ``needed_by`` (the verb), not a traceback from deep in the harness.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        package = module.split('.')[0]
        raise MissingInterfaceError(
            f'{package} is needed by {needed_by} and does not import here ({exc}): source a '
            f'ROS 2 install that has it, or build it into a pip-only venv with '
            f'tools/build_interfaces.sh VENV') from None


def parameter_overrides(parameters: Mapping[str, Any]) -> List[Parameter]:
    """
    Turn ``{'name': value}`` into the ``parameter_overrides`` list of an rclpy Node.

    A list of numbers with a float among them becomes all floats
    (``[2, 0, 3.14]``): rclpy refuses a list of mixed types.
    """
    return [Parameter(name, value=numbers_alike(value)) for name, value in parameters.items()]


def check_timeout(timeout_s: Any) -> float:
    """Return ``timeout_s`` (s) if it is a finite number > 0; ValueError (one line) if not."""
    if isinstance(timeout_s, bool) or not isinstance(timeout_s, (int, float)) \
            or not math.isfinite(timeout_s) or timeout_s <= 0:
        raise ValueError(f'timeout_s must be a finite number of seconds > 0, got {timeout_s!r}')
    return float(timeout_s)


class RosHarness:
    """
    One rclpy context on a leased domain, with an executor spinning in a thread.

    The base of :class:`SimHarness`; on its own, a place to build simulator
    nodes by hand. Nodes added here are destroyed by :meth:`close`, which stops
    the spinning thread before it shuts the executor down: shutting an executor
    down while another thread spins it races in rclpy 7.1 (a callback made
    ready meanwhile fails on a destroyed guard condition). An exception raised
    by a callback is raised again, as :class:`CallbackError`, by the next
    harness call (or by :meth:`close`). ``timeout_s`` bounds every wait (wall
    clock). Use it as a context manager, or call :meth:`close`.

    Attributes: ``context``, ``executor``, ``nodes``, ``domain_id`` and its
    ``lease`` (:class:`DomainLease`, released on close).
    """

    def __init__(self, *, domain_id: Optional[int] = None, timeout_s: float = 10.0) -> None:
        self.timeout_s = check_timeout(timeout_s)
        self.lease = lease_domain(domain_id, timeout_s=max(timeout_s, 60.0))
        self.domain_id = self.lease.domain_id
        self.nodes: List[Node] = []
        self._closed = False
        self._error: Optional[BaseException] = None
        self._stop = threading.Event()
        # The caller's thread takes the executor over (the spinning thread
        # parks) to run callbacks to idleness itself: see _own_executor().
        self._state = threading.Condition()
        self._park_requests = 0
        self._parked = False
        self._owned = 0
        # Every subscription a message was handled for, by either thread, with how many
        # (weakly: a destroyed one's id may be another's later): SimHarness counts a
        # latched message taken before it looked as served.
        self._handled: 'weakref.WeakKeyDictionary[Subscription, int]' = \
            weakref.WeakKeyDictionary()
        # Discovery must stay on this host (a default, set before rclpy.init).
        os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        self.context = Context()
        try:
            rclpy.init(context=self.context, domain_id=self.domain_id)
        except BaseException:
            self.lease.release()
            raise
        self.executor = LockstepExecutor(context=self.context)
        self._thread = threading.Thread(target=self._spin, daemon=True,
                                        name=f'ros-harness-{self.domain_id}')
        self._thread.start()
        _left_open.add(self)

    def create_node(self, name: str, *, use_sim_time: bool = True, **node_kwargs: Any) -> Node:
        """
        Create an rclpy Node in this context, spun by the harness's executor.

        ``use_sim_time`` (on by default) makes the node's clock and timers
        follow the simulator's ``/clock``. Other keywords go to ``Node``.
        """
        self.check_open()
        overrides = list(node_kwargs.pop('parameter_overrides', None) or [])
        if use_sim_time and not any(p.name == 'use_sim_time' for p in overrides):
            overrides.append(Parameter('use_sim_time', value=True))
        node = Node(name, context=self.context, parameter_overrides=overrides, **node_kwargs)
        return self.add_node(node, use_sim_time=False)

    def add_node(self, node: Node, *, use_sim_time: bool = True) -> Node:
        """
        Spin ``node`` (built with ``context=harness.context``) and destroy it on close.

        ``use_sim_time`` (on by default) switches the node to the simulator's
        clock: its timers then count from the first ``/clock`` it receives.
        """
        self._check_new_node(node)
        if use_sim_time and not node.get_parameter('use_sim_time').value:
            node.set_parameters([Parameter('use_sim_time', value=True)])
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    @contextmanager
    def _own_executor(self) -> Iterator[None]:
        """
        Run the executor in the caller's thread for the duration of the block.

        The spinning thread parks; :meth:`settle` then runs callbacks directly,
        with no hand-over between threads for each one. Nests.
        """
        if self._owned:
            self._owned += 1
            try:
                yield
            finally:
                self._owned -= 1
            return
        with self._state:
            self._park_requests += 1
        try:
            self.executor.wake()
            with self._state:
                parked = self._state.wait_for(
                    lambda: self._parked or not self._thread.is_alive(), self.timeout_s)
            if not parked:
                raise HarnessError('the executor thread is stuck in a callback')
            self._owned = 1
            try:
                yield
            finally:
                self._owned = 0
        finally:
            with self._state:
                self._park_requests -= 1
                self._state.notify_all()

    @contextmanager
    def driving(self) -> Iterator[None]:
        """
        Drive the executor from this thread for as long as the block lasts.

        The spinning thread parks; every :meth:`settle`, advance and wait
        inside runs the callbacks in this thread at once, without handing
        the executor over between threads each time (0.1-0.3 ms a handover
        on a loaded machine: a loop of short periods, as a learning
        environment's steps, pays it twice a period). Meanwhile callbacks run
        only inside those calls: a request from another process is answered
        at the next one. Nests; ``close`` ends it.
        """
        with self._own_executor():
            yield

    def _check_new_node(self, node: Any) -> None:
        """Refuse (one line) a node this open harness cannot spin: none, or another context's."""
        self.check_open()
        if not isinstance(node, Node):
            raise TypeError(f'add_node takes an rclpy Node, got {type(node).__name__}')
        if node.context is not self.context:
            raise ValueError(f'node {node.get_name()} belongs to another context: build it '
                             'with context=harness.context')

    def check_open(self) -> None:
        """Raise HarnessError (one line) once the harness is closed."""
        if self._closed:
            raise HarnessError('the harness is closed: make a new one')

    def settle(self, timeout_s: Optional[float] = None) -> None:
        """
        Return once every callback that is ready has run, and those they made ready too.

        Publications within one context are delivered synchronously, so after
        ``settle`` every node here has handled what was published before the
        call, and whatever it published in response. Raises HarnessError at the
        deadline (callbacks that never stop making work), and ValueError (one
        line) unless ``timeout_s`` is None (the harness's) or a finite number > 0.
        """
        self.check_open()
        limit_s = self.timeout_s if timeout_s is None else check_timeout(timeout_s)
        with self._own_executor():
            self._run_until_idle(limit_s)
        self.raise_callback_error()

    def _run_until_idle(self, timeout_s: float) -> None:
        """Run ready callbacks in this thread (which owns the executor) until a poll finds none."""
        deadline = time.monotonic() + timeout_s
        worked = False
        entity: Any
        while True:
            try:
                # A zero timeout polls; every batch ends with TimeoutException,
                # and a batch that yielded nothing means idle.
                handler, entity, _ = self.executor.wait_for_ready_callbacks(0.0)
            except TimeoutException:
                if not worked:
                    return
                worked = False
                if time.monotonic() > deadline:
                    raise HarnessError(f'callbacks kept coming for {timeout_s:g} s') from None
                continue
            except (ShutdownException, ExternalShutdownException):
                raise HarnessError('the harness was shut down') from None
            worked = True
            self._run(handler, entity)

    def _run(self, handler: Handler, entity: Any) -> None:
        if isinstance(entity, Subscription):
            self._handled[entity] = self._handled.get(entity, 0) + 1
        handler()
        error = handler.exception()
        if error is not None:
            with self._state:
                if self._error is None:
                    self._error = error

    def _wait(self, condition: Callable[[], Any], what: str) -> Any:
        """Wait for ``condition`` (by deadline) while callbacks run; HarnessError with ``what``."""
        if self._owned:
            def check() -> Any:
                self._run_until_idle(self.timeout_s)
                return condition()
        else:
            check = condition
        value = wait_for(check, self.timeout_s, interval_s=0.0005)
        self.raise_callback_error()
        if not value:
            raise HarnessError(f'{what} within {self.timeout_s:g} s')
        return value

    def raise_callback_error(self) -> None:
        """Raise (once) what a callback raised in the executor, if anything did."""
        with self._state:
            error, self._error = self._error, None
        if error is not None:
            raise CallbackError(f'a callback raised {type(error).__name__}: {error}') from error

    def _park_wanted(self) -> bool:
        # Checked after each wake of a wait: a stop request ends the wait at once
        # (rclpy's wait would go on until its timeout after a wake with no work).
        return self._park_requests > 0 or self._stop.is_set()

    def _spin(self) -> None:
        """Serve callbacks until stopped, parking while a caller drives."""
        executor = self.executor
        entity: Any
        while not self._stop.is_set():
            if self._park_requests:
                with self._state:
                    self._parked = True
                    self._state.notify_all()
                    self._state.wait_for(lambda: not self._park_requests or self._stop.is_set())
                    self._parked = False
                continue
            try:
                handler, entity, _ = executor.wait_for_ready_callbacks(
                    SPIN_POLL_S, None, self._park_wanted)
            except (TimeoutException, ConditionReachedException):
                continue
            except (ShutdownException, ExternalShutdownException):
                break
            self._run(handler, entity)
        with self._state:
            self._state.notify_all()

    def close(self) -> None:
        """
        Stop spinning, shut the executor down, destroy the nodes, shut the context down.

        In that order (see the class). Releases the domain; safe to call twice.
        Raises CallbackError if a callback raised and no harness call reported it,
        and HarnessError (leaving the nodes and the domain as they are) if a
        callback is still running ``timeout_s`` later.
        """
        if self._closed:
            return
        self._closed = True
        _left_open.discard(self)
        problems: List[BaseException] = []
        waited_s = max(self.timeout_s, 1.0)
        self._stop.set()
        with self._state:
            self._state.notify_all()
        self.executor.wake()
        self._thread.join(timeout=waited_s)
        if self._thread.is_alive():
            # A callback that does not return: its nodes are not destroyed under it (it
            # would go on against destroyed handles), and the domain stays leased while
            # they live, so that no other harness shares it.
            raise HarnessError(f'a callback was still running {waited_s:g} s after close(): '
                               'the harness\'s nodes are left to it, and its domain '
                               f'{self.domain_id} stays leased until this process ends')
        try:
            self.executor.shutdown(timeout_sec=1.0)
            for node in reversed(self.nodes):
                try:
                    node.destroy_node()
                except Exception as exc:  # destroy the others, then report it
                    problems.append(exc)
            self.nodes.clear()
            rclpy.try_shutdown(context=self.context)
        finally:
            self.lease.release()
        if problems:
            raise problems[0]
        self.raise_callback_error()

    def __enter__(self) -> 'RosHarness':
        return self

    def __exit__(self, exc_type: Optional[Type[BaseException]],
                 exc_value: Optional[BaseException], traceback: Optional[TracebackType]) -> None:
        try:
            self.close()
        except CallbackError:
            if exc_type is None:  # do not hide the exception already on its way out
                raise


# Harnesses not closed yet. One left open when the interpreter exits (a script that
# forgot close(), or raised outside ``with``) is closed on the way out: its thread
# otherwise still spun rclpy's executor while the interpreter tore the context down,
# and the process died of SIGABRT ("terminate called without an active exception").
_left_open: 'weakref.WeakSet[RosHarness]' = weakref.WeakSet()


@atexit.register
def _close_left_open() -> None:
    for harness in list(_left_open):
        try:
            harness.close()
        except Exception:  # noqa: B902 (the process is ending: a callback's error is moot)
            pass
