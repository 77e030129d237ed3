"""
An rclpy executor for lockstep: a poll costs little more than the callbacks it runs.

rclpy's executor builds a new wait set from every entity of every node on each
wait, and runs each callback as a Task whose guard-condition triggers make the
next wait return at once with nothing to do. In a lockstep run the harness
polls (timeout 0) two or more times per control period, and a cProfile of the
README's closed-loop example put 62 % of the run there (7.3 waits per period,
about 12 QoS event waitables each). And a wait itself is dear here: Fast DDS
(Jazzy) waits even with timeout 0 on a timed condition variable, about 90 us
on our machines whatever the wait set holds.

:class:`LockstepExecutor` polls in two ways, both keeping rclpy's order (per
node: timers, subscriptions, guard conditions, clients, services), except
that a node's ``/clock`` subscription comes before its other ones, so that a
simulated-time node's clock has moved before its messages of that time arrive:

- **A sweep**, when nodes have only timers, subscriptions with plain
  callbacks and QoS event handlers (the README's controller, the simulator,
  a TF listener): each due timer, then each subscription's next message,
  taken before any callback runs, with no wait set at all. Taking from an
  empty reader costs a few microseconds.
- **A wait on a kept wait set** otherwise (a client, a service some client
  here can call, a guard condition, an action client, a coroutine callback):
  the gathered entities and one wait set live until rclpy wakes the executor
  for a change (a node added or removed, an entity created or destroyed) or a
  handle turns invalid. It waits on the services a client here can call, not
  on every service: a request from another process is answered between
  advances, by rclpy's own waits.

Ready subscriptions with plain callbacks run directly (take, call, inside
their callback group's execution); everything else goes through rclpy's own
code, as do waits with a timeout and any poll while rclpy tasks are pending.
"""

import inspect
from typing import (
    Any, Callable, Dict, Generator, List, NamedTuple, Optional, Protocol, Set, Tuple, Union)

from rclpy.action import ActionServer
from rclpy.callback_groups import CallbackGroup
from rclpy.client import Client
from rclpy.context import Context
from rclpy.event_handler import EventHandler
from rclpy.exceptions import InvalidHandle
from rclpy.executors import ExternalShutdownException, ShutdownException, \
    SingleThreadedExecutor, TimeoutException, TimeoutObject
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.service import Service
from rclpy.subscription import Subscription
from rclpy.timer import Timer
from rclpy.waitable import NumberOfEntities, Waitable

__all__ = ['LockstepExecutor', 'TakenOnDemand', 'Handler']


class Handler(Protocol):
    """What a poll gives to run: rclpy's Task, or a ready subscription's callback run at once."""

    def __call__(self) -> None:
        """Run the callback (a Task: one step of its coroutine)."""

    def exception(self) -> Optional[BaseException]:
        """Return what the callback raised (None if nothing)."""


# One piece of ready work, as rclpy's executor yields it: (handler, entity, its node).
Work = Tuple[Handler, Any, Node]


class TakenOnDemand(CallbackGroup):
    """
    A callback group no executor runs: its subscriptions are read by taking, when asked.

    rclpy's executors leave out entities whose group cannot execute; so does
    :class:`LockstepExecutor`. The harness's state readers live in one, on
    its own node, and cost a lockstep period nothing.
    """

    def can_execute(self, entity: Any) -> bool:
        """Return False: nothing here runs from an executor."""
        return False

    def beginning_execution(self, entity: Any) -> bool:
        """Return False: nothing here runs from an executor."""
        return False

    def ending_execution(self, entity: Any) -> None:
        """Do nothing: nothing here ran."""


class _DirectCallback:
    """
    A ready subscription's plain callback run at once, as rclpy's Task would run it.

    With ``taken`` (a sweep took the message already) it calls back with that;
    else it takes the next message first. Inside the callback group's
    execution; an exception is kept for the caller, as a Task keeps it.
    """

    __slots__ = ('_subscription', '_taken', '_exception')

    def __init__(self, subscription: Subscription, taken: Optional[Tuple[Any, ...]] = None
                 ) -> None:
        self._subscription = subscription
        self._taken = taken
        self._exception: Optional[BaseException] = None

    def __call__(self) -> None:
        subscription = self._subscription
        group = subscription.callback_group
        if not group.beginning_execution(subscription):
            return
        try:
            taken = self._taken
            if taken is None:
                with subscription.handle:
                    taken = subscription.handle.take_message(subscription.msg_type,
                                                             subscription.raw)
            if taken is not None:
                if subscription._callback_type is Subscription.CallbackType.MessageOnly:
                    subscription.callback(taken[0])
                else:
                    subscription.callback(*taken)
        except InvalidHandle:
            pass  # destroyed meanwhile: nothing to do, as rclpy's take
        except Exception as exc:  # kept for the caller, as a Task keeps it
            self._exception = exc
        finally:
            group.ending_execution(subscription)

    def exception(self) -> Optional[BaseException]:
        """Return what the callback raised (None if nothing)."""
        return self._exception

    def result(self) -> None:
        """Raise what the callback raised, as Task.result does."""
        if self._exception is not None:
            raise self._exception

    def done(self) -> bool:
        """Return True: the callback has run by the time anyone asks."""
        return True


class _NodeEntities(NamedTuple):
    """One node's entities a poll looks at, in rclpy's order."""

    timers: List[Timer]
    subscriptions: List[Subscription]
    guards: List[GuardCondition]
    clients: List[Client]
    services: List[Service]


# The kinds of _NodeEntities, as a wait set names its ready entities.
KINDS = ('timer', 'subscription', 'guard_condition', 'client', 'service')


def _clock_first(node: Node) -> List[Subscription]:
    """
    Return the node's subscriptions a poll looks at, its ``/clock`` one first.

    rclpy's TimeSource subscribes to ``/clock`` when ``use_sim_time`` is set,
    after the node's own subscriptions; in creation order a sweep would hand
    the node a state message before the clock published ahead of it, and the
    node's clock would lag its messages by a publication (docs/limits.md).
    """
    clock = getattr(getattr(node, '_time_source', None), '_clock_sub', None)
    own = [s for s in node.subscriptions if not isinstance(s.callback_group, TakenOnDemand)]
    return sorted(own, key=lambda subscription: subscription is not clock)  # stable


class _Gathered:
    """The entities of a set of nodes, their handles, and one wait set sized for them."""

    def __init__(self, executor: 'LockstepExecutor') -> None:
        self.nodes = executor.get_nodes()
        # Only the services a client here may call: nobody else's request can
        # be part of a lockstep period (one from another process is served
        # between advances, by rclpy's own waits). The simulator's and the
        # standard's 21 services would otherwise be most of each poll's wait.
        called = {c.handle.service_name for n in self.nodes for c in n.clients}
        self.by_node = [(n, _NodeEntities(
            list(n.timers), _clock_first(n),
            list(n.guards), list(n.clients),
            [s for s in n.services if s.handle.name in called]))
            for n in self.nodes]
        entities = [e for _, e in self.by_node]
        self.timers = [t for e in entities for t in e.timers]
        self.subscriptions = [s for e in entities for s in e.subscriptions]
        self.guards = [g for e in entities for g in e.guards]
        self.clients = [c for e in entities for c in e.clients]
        self.services = [s for e in entities for s in e.services]
        self.waitables = [w for n in self.nodes for w in n.waitables]
        self.owner = {id(w): n for n in self.nodes for w in n.waitables}
        self.direct = {id(s) for s in self.subscriptions
                       if not inspect.iscoroutinefunction(s.callback)}
        # What only a wait set can tell: guard conditions, clients and services,
        # coroutine callbacks, action clients (an action server alone waits for
        # a client here, which would be an ActionClient). QoS event handlers
        # only warn, and are left to rclpy's waits between advances.
        self.sweepable = (
            not self.guards and not self.clients and not self.services
            and len(self.direct) == len(self.subscriptions)
            and all(isinstance(w, (EventHandler, ActionServer)) for w in self.waitables))
        guards = self.guards + [executor._guard, executor._sigint_gc]
        self.handles = [e.handle for e in self.subscriptions + self.clients + self.services
                        + self.timers + guards]
        self.wait_set = self._wait_set(executor, guards)

    def _wait_set(self, executor: 'LockstepExecutor', guards: List[GuardCondition]) -> Any:
        """Make the wait set for these entities and keep how to fill it (``adders``)."""
        count = NumberOfEntities(len(self.subscriptions), len(guards), len(self.timers),
                                 len(self.clients), len(self.services))
        for waitable in self.waitables:
            count += waitable.get_num_entities()
        wait_set = _rclpy.WaitSet(count.num_subscriptions, count.num_guard_conditions,
                                  count.num_timers, count.num_clients, count.num_services,
                                  count.num_events, executor._context.handle)
        self.adders: List[Tuple[Callable, object]] = (
            [(wait_set.add_subscription, s.handle) for s in self.subscriptions]
            + [(wait_set.add_client, c.handle) for c in self.clients]
            + [(wait_set.add_service, s.handle) for s in self.services]
            + [(wait_set.add_timer, t.handle) for t in self.timers]
            + [(wait_set.add_guard_condition, g.handle) for g in guards])
        return wait_set


class LockstepExecutor(SingleThreadedExecutor):
    """
    rclpy's SingleThreadedExecutor with polls (timeout 0) on a kept wait set.

    A drop-in for :class:`~r2d2_sim.testing.executor.RosHarness`: blocking
    waits and anything unusual take rclpy's path; see the module.
    """

    def __init__(self, *, context: Optional[Context] = None) -> None:
        super().__init__(context=context)
        self._gathered: Optional[_Gathered] = None

    def wake(self) -> None:
        """Wake the executor, and gather the entities again (rclpy wakes it on every change)."""
        self._gathered = None
        super().wake()

    def add_node(self, node: Node) -> bool:
        """Add a node, as rclpy does."""
        self._gathered = None
        return super().add_node(node)

    def remove_node(self, node: Node) -> None:
        """Remove a node, as rclpy does."""
        self._gathered = None
        super().remove_node(node)

    # Any, not rclpy's Task: a poll yields _DirectCallbacks among the Tasks (they run as a
    # Task does: called, then exception(), result(), done()).
    def _wait_for_ready_callbacks(self, timeout_sec: Optional[Union[float, TimeoutObject]] = None,
                                  nodes: Optional[List[Node]] = None,
                                  condition: Callable[[], bool] = lambda: False
                                  ) -> Generator[Tuple[Any, Any, Node], None, None]:
        if self._tasks:  # rclpy keeps finished Tasks until its next wait: drop them here
            with self._tasks_lock:
                self._tasks = [t for t in self._tasks if not (t[0].done() or t[0].cancelled())]
        if timeout_sec != 0 or nodes is not None or self._tasks:
            yield from super()._wait_for_ready_callbacks(timeout_sec, nodes, condition)
            return
        if self._is_shutdown:
            raise ShutdownException()
        if condition():
            return
        ready = self._poll()
        if ready is None:  # a handle went invalid: rclpy's way, once
            yield from super()._wait_for_ready_callbacks(timeout_sec, nodes, condition)
            return
        yield from ready
        raise TimeoutException()

    def _poll(self) -> Optional[List[Work]]:
        """Poll once; return the ready work in rclpy's order (None: gather anew first)."""
        gathered = self._gathered
        if gathered is None:
            gathered = self._gathered = _Gathered(self)
        if gathered.sweepable:
            return self._sweep(gathered)
        ready = self._wait_once(gathered)
        if ready is None:
            return None
        return self._ready_work(gathered, *ready)

    def _wait_once(self, gathered: _Gathered
                   ) -> Optional[Tuple[List[Waitable], Dict[str, Set[Any]]]]:
        """Wait on the kept wait set with timeout 0; return what is ready (None: stale handle)."""
        for guard in gathered.guards:  # triggered, not handled yet: keep it so (as rclpy)
            if guard._executor_triggered:
                guard.trigger()
        entered = []
        try:
            for item in gathered.handles + gathered.waitables + [self._context.handle]:
                item.__enter__()
                entered.append(item)
            wait_set = gathered.wait_set
            wait_set.clear_entities()
            for add, handle in gathered.adders:
                add(handle)
            for waitable in gathered.waitables:
                waitable.add_to_wait_set(wait_set)
            wait_set.wait(0)
            if self._is_shutdown:
                raise ShutdownException()
            if not self._context.ok():
                raise ExternalShutdownException()
            ready = {kind: set(wait_set.get_ready_entities(kind)) for kind in (
                'timer', 'subscription', 'guard_condition', 'client', 'service')}
            for guard in gathered.guards:
                if guard.handle.pointer in ready['guard_condition']:
                    guard._executor_triggered = True
            return [w for w in gathered.waitables if w.is_ready(wait_set)], ready
        except InvalidHandle:
            self._gathered = None
            return None
        finally:
            for item in reversed(entered):
                item.__exit__(None, None, None)

    def _ready_work(self, gathered: _Gathered, waitables: List[Waitable],
                    ready: Dict[str, Set[Any]]) -> List[Work]:
        """Return handlers for what is ready: waitables first, then per node in rclpy's order."""
        work: List[Work] = []
        for waitable in waitables:
            if waitable.callback_group.can_execute(waitable):
                node = gathered.owner[id(waitable)]
                work.append((self._make_handler(waitable, node, self._take_waitable),
                             waitable, node))
        if not (ready['timer'] or ready['subscription'] or ready['client']
                or ready['service'] or gathered.guards):
            return work  # the usual idle poll: nothing but the executor's own guards
        takes = (self._take_timer, self._take_subscription, self._take_guard_condition,
                 self._take_client, self._take_service)
        for node, entities in gathered.by_node:
            for index, kind in enumerate(KINDS):
                pointers, take = ready[kind], takes[index]
                for entity in entities[index]:
                    if isinstance(entity, GuardCondition):
                        if not entity._executor_triggered:
                            continue
                    elif entity.handle.pointer not in pointers:
                        continue
                    elif isinstance(entity, Timer) and not entity.handle.is_timer_ready():
                        continue
                    if isinstance(entity, Subscription) and id(entity) in gathered.direct:
                        work.append((_DirectCallback(entity), entity, node))
                    elif entity.callback_group.can_execute(entity):
                        work.append((self._make_handler(entity, node, take), entity, node))
        return work

    def _sweep(self, gathered: _Gathered) -> Optional[List[Work]]:
        """
        Take what is ready without a wait set: each due timer, each subscription's next message.

        Fast DDS's wait with timeout 0 is a timed condition wait, about 90 us
        on our machines whatever the wait set holds; taking from an empty
        reader is a few microseconds. Messages are taken before any callback
        runs, in rclpy's order (per node, timers, then subscriptions), so a
        message published by one of them waits for the next sweep, as it
        would wait for the next wait set.
        """
        if not self._context.ok():
            raise ExternalShutdownException()
        work: List[Work] = []
        try:
            for node, (timers, subscriptions, _, _, _) in gathered.by_node:
                for timer in timers:
                    if timer.handle.is_timer_ready() and timer.callback_group.can_execute(timer):
                        work.append((self._make_handler(timer, node, self._take_timer),
                                     timer, node))
                for subscription in subscriptions:
                    with subscription.handle:
                        taken = subscription.handle.take_message(subscription.msg_type,
                                                                 subscription.raw)
                    if taken is not None:
                        work.append((_DirectCallback(subscription, taken), subscription, node))
        except InvalidHandle:
            self._gathered = None
            if work:  # taken messages are not lost: their callbacks still run
                return work
            return None
        return work
