"""
Simulated time as the kit sees it: ``/clock``, listened to, drained and waited for.

:class:`TargetClock` is a part of :class:`~r2d2_sim.conformance.target.Target`
(``t.clock``): it subscribes to the clock topic with its publisher's
reliability once one is there, takes every message already in after a round
trip to the simulator, and waits (by deadline) for the clock to move, to
reach a time or to go back. It owns the subscription and the latest time;
the stepping itself is the simulation part's ``advance``.

The standard says nothing of how often ``/clock`` goes out: a simulator may
publish it at every step or only every few (r2d2_sim with a ``publish_rate``
below its physics rate). Where the clock has not moved as far as the steps
asked should take it, the kit steps one step more at a time, counting them,
until it has (within the timeout): the clock it then reads is the time of
that step, and every expectation counts the steps taken in all, so a step
too many or too few still shows.
"""

import time
from typing import Any, Callable, List, Optional, Sequence, Tuple, TYPE_CHECKING

from r2d2_sim.conformance.calls import TargetCalls
from r2d2_sim.conformance.clause import ClauseFailed, ClauseSkipped

if TYPE_CHECKING:
    from r2d2_sim.conformance.simulation_verbs import TargetSimulation

# How long the kit waits for a /clock publisher once the services are found (s).
CLOCK_WAIT_S = 2.0
# At most this many callbacks are run to take the /clock messages already in.
DRAIN_SPINS = 1000
# How long the kit waits for the clock to move after the steps it asked for, before it
# takes it for a clock published every few steps and steps once more (s).
CLOCK_QUIET_S = 0.25


class TargetClock:
    """The clock of ``target``: its subscription, the latest time, and waits for it to move."""

    def __init__(self, target: TargetCalls, sim: 'TargetSimulation') -> None:
        self.target = target
        self.sim = sim
        self.topic = target.options.clock_topic
        self.present = False  # someone publishes the clock topic, and we are linked to it
        self._ns: Optional[int] = None  # the latest time received
        self._count = 0  # messages received
        self._since: Optional[List[int]] = None  # every time received since expect_start's mark
        self._subscription: Any = None

    def listen(self) -> None:
        """Subscribe to the clock with the publisher's reliability, once one is there."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        t, topic = self.target, self.topic
        if not t.wait(lambda: t.node.count_publishers(topic) > 0,
                      min(CLOCK_WAIT_S, t.timeout_s)):
            return
        reliable = any(info.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                       for info in t.node.get_publishers_info_by_topic(topic))
        # Depth 1: only the newest time is of use, and a burst (a fast SimulateSteps
        # goal publishes one per step) must not queue up ahead of it.
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE if reliable
                         else ReliabilityPolicy.BEST_EFFORT)

        def keep(msg: Any) -> None:
            ns = self._ns = msg.clock.sec * 10**9 + msg.clock.nanosec
            self._count += 1
            if self._since is not None:
                self._since.append(ns)
        subscription = self._subscription = t.node.create_subscription(Clock, topic, keep, qos)
        self.present = t.wait(lambda: subscription.get_publisher_count() > 0)

    def need(self) -> None:
        """Raise ClauseSkipped when nobody publishes the clock topic."""
        if not self.present:
            raise ClauseSkipped(f'no {self.topic} publisher')

    def settled(self) -> Optional[int]:
        """
        Return the latest clock after one round trip to the simulator.

        A /clock published before a reply may arrive after it (another
        writer): the round trip gives it the time to come.
        """
        t = self.target
        t.call('GetSimulatorFeatures', t.srv.GetSimulatorFeatures.Request())
        self._drain()
        return self._ns

    def _drain(self) -> None:
        """Take every /clock message already received: one spin_once runs one callback."""
        executor = self.target.probe.executor
        for _ in range(DRAIN_SPINS):
            seen = self._count
            executor.spin_once(timeout_sec=0.0)
            if self._count == seen:
                executor.spin_once(timeout_sec=0.0)  # another callback ran first?
                if self._count == seen:
                    return

    def _reach(self, at_least: Callable[[int], int], doing: str) -> Tuple[Optional[int], int]:
        """
        Wait for the clock to read ``at_least(extra)`` ns, stepping ``extra`` single steps more.

        Return (the clock then, the steps taken more). A paused simulation
        whose clock is short of it after :data:`CLOCK_QUIET_S` is stepped once
        more at a time (a clock published every few steps), until the
        timeout; a clock that moved and is still short after a second round
        trip is returned as it is: the caller's check then fails.
        """
        t = self.target

        def reached(extra: int) -> bool:
            return self._ns is not None and self._ns >= at_least(extra)
        if t.wait(lambda: reached(0), min(CLOCK_QUIET_S, t.timeout_s)):
            return self.settled(), 0
        deadline = time.monotonic() + t.timeout_s
        extra = 0
        while time.monotonic() < deadline:
            seen = self.settled()
            self.sim.advance(1)
            extra += 1
            now = self.settled()
            if now != seen and not reached(extra):
                now = self.settled()  # a second round trip for messages still on their way
            if reached(extra) or now != seen:
                return now, extra  # there; or moved and still short: a step of time missing
        raise ClauseFailed(f'{self.topic} did not reach {at_least(extra)} ns within '
                           f'{t.timeout_s:g} s after {doing} and {extra} single steps more '
                           f'(it read {self._ns} ns)')

    def after_counted(self, action: Callable[[], None], doing: str) -> Tuple[int, int]:
        """
        Run ``action``, then wait for a clock newer than before it; return (it, steps more).

        Steps more: single steps taken after ``action`` for a clock published
        every few steps to move (0 where it moved at once).
        """
        before = self.settled()
        action()
        got, extra = self._reach(lambda extra: -1 if before is None else before + 1, doing)
        if got is None:  # cannot be: it moved
            raise ClauseFailed(f'{self.topic} read nothing after {doing}')
        return got, extra

    def after(self, action: Callable[[], None], doing: str) -> int:
        """Run ``action``, then wait for a clock newer than before it; return the clock after."""
        return self.after_counted(action, doing)[0]

    def step_ns(self) -> Tuple[int, int]:
        """
        Return (the clock now, one step's length), a paused simulation stepped three times.

        The first step lets /clock messages from before it arrive. Each step
        is followed by single steps until the clock moves: the length is the
        time between two moves over the steps taken between them.
        """
        self.after(lambda: self.sim.advance(1), 'one step')
        t0, _ = self.after_counted(lambda: self.sim.advance(1), 'one step')
        t1, extra = self.after_counted(lambda: self.sim.advance(1), 'one step')
        return t1, round((t1 - t0) / (1 + extra))

    def expect(self, expected_ns: int, steps: int, doing: str, step_ns: int) -> int:
        """
        Raise ClauseFailed unless the clock comes to ``expected_ns`` (a ns a step).

        While the clock is short of it, single steps more are taken (a clock
        published every few steps), each adding ``step_ns`` to what is expected.
        """
        def at_least(extra: int) -> int:
            return expected_ns + extra * step_ns - (steps + extra + 1)
        got, extra = self._reach(at_least, doing)
        expected_ns += extra * step_ns
        tolerance = steps + extra + 1
        if got is None or abs(got - expected_ns) > tolerance:
            more = (f' ({extra} single steps more for a clock published every few steps)'
                    if extra else '')
            raise ClauseFailed(f'after {doing}{more}, {self.topic} reads {got} ns, expected '
                               f'{expected_ns} ns')
        return got

    def expect_start(self, step_ns: int, doing: str, slack_steps: int, run_steps: int) -> None:
        """
        Pause, step once: raise ClauseFailed unless the clock reads one step from the start.

        The start is time 0, where a simulator starts (as it is launched)
        and where a reset of the time puts it back ("Reset simulation time
        to start"); ``run_steps`` ran before the reset. Where the kit must
        play to pause (from STOPPED), the simulator runs meanwhile for as long
        as the two calls take (under load, more than ``slack_steps``): then
        the clock counts from the earliest time it read meanwhile, if the
        readings climb from there to the last one by less than half of
        ``run_steps`` at a time (one low reading, a stray 0 before a time
        that went on, does not count), with ``slack_steps`` allowed on it.
        """
        sim = self.sim
        paused = (self.target.declared('SIMULATION_STATE_GETTING')
                  and sim.state() == sim.S.STATE_PAUSED)
        self.settled()
        since: List[int] = []
        self._since = since
        try:
            sim.pause()
            got, more = self.after_counted(lambda: sim.advance(1), f'{doing} and one step')
        finally:
            self._since = None
        extra = 0 if paused else slack_steps
        readings = since + [got]  # got was read last: never empty
        low = _steady_low(readings, run_steps // 2 * step_ns)
        one = got - more * step_ns  # the time of the kit's one step, before the steps more
        start = one if paused or low is None else min(one, low + step_ns)  # stepped from low
        if start > (1 + extra) * step_ns + 1 + extra + more:  # a ns a step of rounding
            most = (f' (or up to {extra} more, run while the kit played to pause: the earliest '
                    f'read then was {min(readings)} ns)' if extra else '')
            steps = (f'one step and {more} more (for a clock published every few steps) read '
                     f'{got} ns' if more else f'one step reads {got} ns')
            raise ClauseFailed(f'after {doing}, {steps} on {self.topic}: the time is not back '
                               f'at the start (0), where one step reads {step_ns} ns{most}')


def _steady_low(readings: Sequence[int], max_jump_ns: int) -> Optional[int]:
    """
    Return the lowest of ``readings`` if they climb steadily from it to the last; else None.

    Steadily: never down, never more than ``max_jump_ns`` at a time. A low
    reading the time did not go on from (a stray 0) gives None.
    """
    first = min(range(len(readings)), key=readings.__getitem__)  # the first of the lowest
    climb = readings[first:]
    if all(0 <= b - a <= max_jump_ns for a, b in zip(climb, climb[1:])):
        return climb[0]
    return None
