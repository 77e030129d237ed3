"""
Simulated time as the kit sees it: ``/clock``, listened to, drained and waited for.

:class:`TargetClock` is a part of :class:`~r2d2_sim.conformance.target.Target`
(``t.clock``): it subscribes to the clock topic with its publisher's
reliability once one is there, takes every message already in after a round
trip to the simulator, and waits (by deadline) for the clock to move, to
reach a time or to go back. It owns the subscription and the latest time;
the stepping itself is the simulation part's ``advance``.
"""

from typing import Any, Callable, List, Optional, Sequence, Tuple, TYPE_CHECKING

from r2d2_sim.conformance.calls import TargetCalls
from r2d2_sim.conformance.clause import ClauseFailed, ClauseSkipped

if TYPE_CHECKING:
    from r2d2_sim.conformance.simulation_verbs import TargetSimulation

# How long the kit waits for a /clock publisher once the services are found (s).
CLOCK_WAIT_S = 2.0
# At most this many callbacks are run to take the /clock messages already in.
DRAIN_SPINS = 1000


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

    def after(self, action: Callable[[], None], doing: str) -> int:
        """Run ``action``, then wait for a clock newer than before it; return the clock after."""
        before = self.settled()
        action()
        if not self.target.wait(lambda: self._ns is not None
                                and (before is None or self._ns > before)):
            raise ClauseFailed(f'{self.topic} did not move within {self.target.timeout_s:g} s '
                               f'after {doing} (it read {before} ns)')
        got = self.settled()
        if got is None:  # cannot be: it moved
            raise ClauseFailed(f'{self.topic} read nothing after {doing}')
        return got

    def step_ns(self) -> Tuple[int, int]:
        """
        Return (the clock now, one step's length), a paused simulation stepped three times.

        The first step lets /clock messages from before it arrive.
        """
        self.after(lambda: self.sim.advance(1), 'one step')
        t0 = self.after(lambda: self.sim.advance(1), 'one step')
        t1 = self.after(lambda: self.sim.advance(1), 'one step')
        return t1, t1 - t0

    def expect(self, expected_ns: int, steps: int, doing: str) -> int:
        """Raise ClauseFailed unless the clock comes to ``expected_ns`` (a ns a step)."""
        tolerance = steps + 1
        self.target.wait(lambda: self._ns is not None and self._ns >= expected_ns - tolerance)
        got = self.settled()
        if got is None or abs(got - expected_ns) > tolerance:
            raise ClauseFailed(f'after {doing}, {self.topic} reads {got} ns, expected '
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
            got = self.after(lambda: sim.advance(1), f'{doing} and one step')
        finally:
            self._since = None
        extra = 0 if paused else slack_steps
        readings = since + [got]  # got was read last: never empty
        low = _steady_low(readings, run_steps // 2 * step_ns)
        start = got if paused or low is None else min(got, low + step_ns)  # stepped from low
        if start > (1 + extra) * step_ns + 1 + extra:  # a ns a step of rounding
            most = (f' (or up to {extra} more, run while the kit played to pause: the earliest '
                    f'read then was {min(readings)} ns)' if extra else '')
            raise ClauseFailed(f'after {doing}, one step reads {got} ns on {self.topic}: the time '
                               f'is not back at the start (0), where one step reads {step_ns} ns'
                               f'{most}')


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
