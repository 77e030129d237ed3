"""
Wall-clock pacing with absolute deadlines.

Sleeping a fixed period after each step (``time.sleep(1/240)``) adds the step's
own cost to every period and drifts (measured: 221 Hz instead of 240). Here the
n-th tick is due at ``start + n * period``, so lateness is never accumulated.
"""

import time
from typing import Callable


class DeadlinePacer:
    """
    Wait for absolute deadlines spaced ``period_s`` apart.

    If the loop falls more than ``max_lag_s`` behind (a debugger stop, a
    suspended process), the schedule is re-anchored instead of replaying the
    missed ticks in a burst; ``overruns`` counts how often that happened.
    """

    def __init__(self, period_s: float, max_lag_s: float = 0.25,
                 clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        if not period_s > 0.0:
            raise ValueError(f'period must be > 0 s, got {period_s}')
        self.period_s = period_s
        self.max_lag_s = max_lag_s
        self._clock = clock
        self._sleep = sleep
        self._next = clock() + period_s
        self.overruns = 0

    def reanchor(self) -> None:
        """Start the schedule afresh from now (after a pause)."""
        self._next = self._clock() + self.period_s

    def wait(self) -> None:
        """Sleep until the next deadline, then schedule the one after it."""
        remaining = self._next - self._clock()
        if remaining > 0.0:
            self._sleep(remaining)
        elif -remaining > self.max_lag_s:
            self.overruns += 1
            self._next = self._clock()
        self._next += self.period_s
