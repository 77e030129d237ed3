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
node: timers, subscriptions, guard conditions, clients, services):

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
from typing import Callable, List, Optional, Tuple

from rclpy.action import ActionServer
from rclpy.callback_groups import CallbackGroup
from rclpy.event_handler import EventHandler
from rclpy.exceptions import InvalidHandle
from rclpy.executors import ExternalShutdownException, ShutdownException, \
    SingleThreadedExecutor, TimeoutException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.subscription import Subscription

__all__ = ['LockstepExecutor', 'TakenOnDemand']


class TakenOnDemand(CallbackGroup):
    """
    A callback group no executor runs: its subscriptions are read by taking, when asked.

    rclpy's executors leave out entities whose group cannot execute; so does
    :class:`LockstepExecutor`. The harness's state readers live in one, on
    its own node, and cost a lockstep period nothing.
    """

    def can_execute(self, entity) -> bool:
        """Return False: nothing here runs from an executor."""
        return False

    def beginning_execution(self, entity) -> bool:
        """Return False: nothing here runs from an executor."""
        return False

    def ending_execution(self, entity) -> None:
        """Do nothing: nothing here ran."""


class _DirectCallback:
    """
    A ready subscription's plain callback run at once, as rclpy's Task would run it.

    With ``taken`` (a sweep took the message already) it calls back with that;
    else it takes the next message first. Inside the callback group's
    execution; an exception is kept for the caller, as a Task keeps it.
    """

    __slots__ = ('_subscription', '_taken', '_exception')

    def __init__(self, subscription: Subscription, taken=None) -> None:
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


class _Gathered:
    """The entities of a set of nodes, their handles, and one wait set sized for them."""

    def __init__(self, executor: 'LockstepExecutor') -> None:
        self.nodes = executor.get_nodes()
        self.subscriptions = [s for n in self.nodes for s in n.subscriptions
                              if not isinstance(s.callback_group, TakenOnDemand)]
        self.timers = [t for n in self.nodes for t in n.timers]
        self.clients = [c for n in self.nodes for c in n.clients]
        # Only the services a client here may call: nobody else's request can
        # be part of a lockstep period (one from another process is served
        # between advances, by rclpy's own waits). The simulator's and the
        # standard's 21 services would otherwise be most of each poll's wait.
        called = {c.handle.service_name for c in self.clients}
        self.services = [s for n in self.nodes for s in n.services if s.handle.name in called]
        self.guards = [g for n in self.nodes for g in n.guards]
        self.waitables = [w for n in self.nodes for w in n.waitables]
        self.owner = {id(w): n for n in self.nodes for w in n.waitables}
        # Per node, in rclpy's order, with the pointers the wait set reports.
        self.by_node = [(n, (list(n.timers), [(s, s.handle.pointer) for s in n.subscriptions
                                              if not isinstance(s.callback_group, TakenOnDemand)],
                             list(n.guards), [(c, c.handle.pointer) for c in n.clients],
                             [(s, s.handle.pointer) for s in n.services
                              if s.handle.name in called]))
                        for n in self.nodes]
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
        self.handles = ([s.handle for s in self.subscriptions] + [c.handle for c in self.clients]
                        + [s.handle for s in self.services] + [t.handle for t in self.timers]
                        + [g.handle for g in guards])
        events = 0
        extra = [0, 0, 0, 0, 0]  # subscriptions, guards, timers, clients, services of waitables
        for waitable in self.waitables:
            entities = waitable.get_num_entities()
            extra[0] += entities.num_subscriptions
            extra[1] += entities.num_guard_conditions
            extra[2] += entities.num_timers
            extra[3] += entities.num_clients
            extra[4] += entities.num_services
            events += entities.num_events
        self.wait_set = _rclpy.WaitSet(
            len(self.subscriptions) + extra[0], len(guards) + extra[1],
            len(self.timers) + extra[2], len(self.clients) + extra[3],
            len(self.services) + extra[4], events, executor._context.handle)
        wait_set = self.wait_set
        self.adders: List[Tuple[Callable, object]] = (
            [(wait_set.add_subscription, s.handle) for s in self.subscriptions]
            + [(wait_set.add_client, c.handle) for c in self.clients]
            + [(wait_set.add_service, s.handle) for s in self.services]
            + [(wait_set.add_timer, t.handle) for t in self.timers]
            + [(wait_set.add_guard_condition, g.handle) for g in guards])


class LockstepExecutor(SingleThreadedExecutor):
    """
    rclpy's SingleThreadedExecutor with polls (timeout 0) on a kept wait set.

    A drop-in for :class:`~r2d2_sim.testing.executor.RosHarness`: blocking
    waits and anything unusual take rclpy's path; see the module.
    """

    def __init__(self, *, context=None) -> None:
        super().__init__(context=context)
        self._gathered: Optional[_Gathered] = None

    def wake(self) -> None:
        """Wake the executor, and gather the entities again (rclpy wakes it on every change)."""
        self._gathered = None
        super().wake()

    def add_node(self, node) -> bool:
        """Add a node, as rclpy does."""
        self._gathered = None
        return super().add_node(node)

    def remove_node(self, node) -> None:
        """Remove a node, as rclpy does."""
        self._gathered = None
        super().remove_node(node)

    def _wait_for_ready_callbacks(self, timeout_sec=None, nodes=None,
                                  condition: Callable[[], bool] = lambda: False):
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

    def _poll(self):
        """Wait once with timeout 0; return the ready work in rclpy's order (None: gather anew)."""
        gathered = self._gathered
        if gathered is None:
            gathered = self._gathered = _Gathered(self)
        if gathered.sweepable:
            return self._sweep(gathered)
        for guard in gathered.guards:  # triggered, not handled yet: keep it so (as rclpy)
            if guard._executor_triggered:
                guard.trigger()
        entered = []
        try:
            for handle in gathered.handles:
                handle.__enter__()
                entered.append(handle)
            for waitable in gathered.waitables:
                waitable.__enter__()
                entered.append(waitable)
            self._context.handle.__enter__()
            entered.append(self._context.handle)
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
            subscriptions = set(wait_set.get_ready_entities('subscription'))
            guards = set(wait_set.get_ready_entities('guard_condition'))
            timers = set(wait_set.get_ready_entities('timer'))
            clients = set(wait_set.get_ready_entities('client'))
            services = set(wait_set.get_ready_entities('service'))
            for guard in gathered.guards:
                if guard.handle.pointer in guards:
                    guard._executor_triggered = True
            waitables = [w for w in gathered.waitables if w.is_ready(wait_set)]
        except InvalidHandle:
            self._gathered = None
            return None
        finally:
            for item in reversed(entered):
                item.__exit__(None, None, None)
        work = []
        for waitable in waitables:
            if waitable.callback_group.can_execute(waitable):
                node = gathered.owner[id(waitable)]
                work.append((self._make_handler(waitable, node, self._take_waitable),
                             waitable, node))
        if not (timers or subscriptions or clients or services or gathered.guards):
            return work  # the usual idle poll: nothing but the executor's own guards
        direct = gathered.direct
        for node, kinds in gathered.by_node:
            timers_of, subscriptions_of, guards_of, clients_of, services_of = kinds
            if timers:
                for timer in timers_of:
                    if timer.handle.pointer in timers and timer.handle.is_timer_ready() \
                            and timer.callback_group.can_execute(timer):
                        work.append((self._make_handler(timer, node, self._take_timer),
                                     timer, node))
            if subscriptions:
                for subscription, pointer in subscriptions_of:
                    if pointer in subscriptions:
                        if id(subscription) in direct:
                            work.append((_DirectCallback(subscription), subscription, node))
                        elif subscription.callback_group.can_execute(subscription):
                            work.append((self._make_handler(
                                subscription, node, self._take_subscription), subscription,
                                node))
            for guard in guards_of:
                if guard._executor_triggered and guard.callback_group.can_execute(guard):
                    work.append((self._make_handler(guard, node, self._take_guard_condition),
                                 guard, node))
            if clients:
                for client, pointer in clients_of:
                    if pointer in clients and client.callback_group.can_execute(client):
                        work.append((self._make_handler(client, node, self._take_client),
                                     client, node))
            if services:
                for service, pointer in services_of:
                    if pointer in services and service.callback_group.can_execute(service):
                        work.append((self._make_handler(service, node, self._take_service),
                                     service, node))
        return work

    def _sweep(self, gathered: _Gathered):
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
        work = []
        try:
            for node, (timers, subscriptions, _, _, _) in gathered.by_node:
                for timer in timers:
                    if timer.handle.is_timer_ready() and timer.callback_group.can_execute(timer):
                        work.append((self._make_handler(timer, node, self._take_timer),
                                     timer, node))
                for subscription, _ in subscriptions:
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
