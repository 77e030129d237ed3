"""
Simulated time as the kit sees it: ``/clock``, listened to, drained and waited for.

:class:`ClockVerbs` is mixed into :class:`~r2d2_sim.conformance.target.Target`:
it subscribes to the clock topic with its publisher's reliability once one
is there, takes every message already in after a round trip to the
simulator, and waits (by deadline) for the clock to move, to reach a time or
to go back. The stepping itself is :class:`SimulationVerbs`'s ``advance``.
"""

from typing import Callable, Optional, Tuple

from r2d2_sim.conformance.clause import ClauseFailed, ClauseSkipped

# How long the kit waits for a /clock publisher once the services are found (s).
CLOCK_WAIT_S = 2.0
# At most this many callbacks are run to take the /clock messages already in.
DRAIN_SPINS = 1000


class ClockVerbs:
    """The Target's clock: its subscription, the latest time, and waits for it to move."""

    def _listen_to_clock(self) -> None:
        """Subscribe to the clock with the publisher's reliability, once one is there."""
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock
        topic = self.options.clock_topic
        if not self.probe.spin_until(lambda: self.node.count_publishers(topic) > 0,
                                     min(CLOCK_WAIT_S, self.timeout_s)):
            return
        reliable = any(info.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                       for info in self.node.get_publishers_info_by_topic(topic))
        # Depth 1: only the newest time is of use, and a burst (a fast SimulateSteps
        # goal publishes one per step) must not queue up ahead of it.
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE if reliable
                         else ReliabilityPolicy.BEST_EFFORT)

        def keep(msg) -> None:
            self._clock_ns = msg.clock.sec * 10**9 + msg.clock.nanosec
            self._clock_count += 1
        self._clock_subscription = self.node.create_subscription(Clock, topic, keep, qos)
        self.has_clock = self.probe.spin_until(
            lambda: self._clock_subscription.get_publisher_count() > 0, self.timeout_s)

    def need_clock(self) -> None:
        """Raise ClauseSkipped when nobody publishes the clock topic."""
        if not self.has_clock:
            raise ClauseSkipped(f'no {self.options.clock_topic} publisher')

    def clock_settled(self) -> Optional[int]:
        """
        Return the latest clock after one round trip to the simulator.

        A /clock published before a reply may arrive after it (another
        writer): the round trip gives it the time to come.
        """
        self.call('GetSimulatorFeatures', self.srv.GetSimulatorFeatures.Request())
        self._drain_clock()
        return self._clock_ns

    def _drain_clock(self) -> None:
        """Take every /clock message already received: one spin_once runs one callback."""
        for _ in range(DRAIN_SPINS):
            seen = self._clock_count
            self.probe.executor.spin_once(timeout_sec=0.0)
            if self._clock_count == seen:
                self.probe.executor.spin_once(timeout_sec=0.0)  # another callback ran first?
                if self._clock_count == seen:
                    return

    def clock_after(self, action: Callable[[], None], doing: str) -> int:
        """Run ``action``, then wait for a clock newer than before it; return the clock after."""
        before = self.clock_settled()
        action()
        if not self.probe.spin_until(
                lambda: self._clock_ns is not None and (before is None or self._clock_ns > before),
                self.timeout_s):
            raise ClauseFailed(f'{self.options.clock_topic} did not move within '
                               f'{self.timeout_s:g} s after {doing} (it read {before} ns)')
        return self.clock_settled()

    def step_ns(self) -> Tuple[int, int]:
        """
        Return (the clock now, one step's length), a paused simulation stepped three times.

        The first step lets /clock messages from before it arrive.
        """
        self.clock_after(lambda: self.advance(1), 'one step')
        t0 = self.clock_after(lambda: self.advance(1), 'one step')
        t1 = self.clock_after(lambda: self.advance(1), 'one step')
        return t1, t1 - t0

    def expect_clock(self, expected_ns: int, steps: int, doing: str) -> int:
        """Raise ClauseFailed unless the clock comes to ``expected_ns`` (a ns a step)."""
        tolerance = steps + 1
        self.probe.spin_until(lambda: self._clock_ns is not None
                              and self._clock_ns >= expected_ns - tolerance, self.timeout_s)
        got = self.clock_settled()
        if got is None or abs(got - expected_ns) > tolerance:
            raise ClauseFailed(f'after {doing}, {self.options.clock_topic} reads {got} ns, '
                               f'expected {expected_ns} ns')
        return got

    def expect_time_back(self, before_ns: int, doing: str) -> None:
        """Raise ClauseFailed unless a step from here reads a time before ``before_ns``."""
        got = self.clock_after(lambda: self.advance(1), f'{doing} and one step')
        if got >= before_ns:
            raise ClauseFailed(f'after {doing}, one step reads {got} ns on '
                               f'{self.options.clock_topic}: time did not go back from '
                               f'{before_ns} ns')
