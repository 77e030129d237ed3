"""
Scheduling: wall-clock pacing with absolute deadlines, and events in step counts.

Also :class:`ThrottledLog`, which lets each kind of message out at most once a period.

Sleeping a fixed period after each step (``time.sleep(1/240)``) adds the step's
own cost to every period and drifts (measured: 221 Hz instead of 240). Here the
n-th tick is due at ``start + n * period``, so lateness is never accumulated.
"""

from fractions import Fraction
import threading
import time
from typing import Any, Callable, Dict, Tuple

NS_PER_S = 10**9


def stamp_of(time_ns: int) -> Tuple[int, int]:
    """Return integer nanoseconds as a ROS stamp's ``(sec, nanosec)``."""
    return divmod(time_ns, NS_PER_S)


def stamp_ns(stamp: Any) -> int:
    """Return a ``builtin_interfaces/Time`` (a header stamp, a Clock) in integer nanoseconds."""
    return stamp.sec * NS_PER_S + stamp.nanosec


def exact_rate(rate_hz: float) -> Fraction:
    """Return a rate as an exact fraction (240.0 -> 240, 0.1 -> 1/10)."""
    return Fraction(rate_hz).limit_denominator(1_000_000)


class StepSchedule:
    """
    The physics steps at which an event of ``event_rate_hz`` falls due.

    The n-th event is due at the first step at or after n / event_rate_hz of
    simulated time counted from ``start_step``: every 4 steps for 60 Hz at 240
    Hz, every 4 or 5 for 50 Hz. Integer arithmetic only (Fraction costs ~7 us
    per event on the physics loop).
    """

    def __init__(self, physics_rate_hz: float, event_rate_hz: float,
                 start_step: int = 0) -> None:
        event_rate = exact_rate(event_rate_hz)
        if event_rate <= 0:  # includes rates too small for a millionth: 1e-7 Hz rounds to 0
            raise ValueError(f'event rate must be a positive number of Hz, got {event_rate_hz}')
        steps_per_event = exact_rate(physics_rate_hz) / event_rate
        self._num = steps_per_event.numerator
        self._den = steps_per_event.denominator
        self.restart(start_step)

    def restart(self, start_step: int) -> None:
        """Count events afresh from ``start_step`` (the first is due one period after it)."""
        self.start_step = start_step
        self.count = 0
        self.next_step = self._due_step(1)

    def _due_step(self, count: int) -> int:
        return self.start_step - (-count * self._num // self._den)

    def due(self, step: int) -> bool:
        """Return True (and schedule the next event) if an event is due at ``step``."""
        if step < self.next_step:
            return False
        self.count += 1
        self.next_step = self._due_step(self.count + 1)
        return True


class DeadlinePacer:
    """
    Wait for absolute deadlines spaced ``period_s`` apart.

    If the loop falls more than ``max_lag_s`` behind (a debugger stop, a
    suspended process), the schedule is re-anchored instead of replaying the
    missed ticks in a burst; ``overruns`` counts how often that happened.
    """

    def __init__(self, period_s: float, max_lag_s: float = 0.25,
                 clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], object] = time.sleep) -> None:
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

    def wait(self) -> bool:
        """
        Sleep until the next deadline, then schedule the one after it.

        Return True when it slept, False when the deadline had passed (the loop
        is behind): then it did not sleep at all.
        """
        remaining = self._next - self._clock()
        if remaining > 0.0:
            self._sleep(remaining)
        elif -remaining > self.max_lag_s:
            self.overruns += 1
            self._next = self._clock()
        self._next += self.period_s
        return remaining > 0.0


class StepClock:
    """Simulated time of a physics step in integer nanoseconds: exact, with no drift."""

    def __init__(self, physics_rate_hz: float) -> None:
        rate = exact_rate(physics_rate_hz)
        self._num, self._den = 10**9 * rate.denominator, rate.numerator

    def time_ns(self, step: int) -> int:
        """Return the time after ``step`` steps, floored to the nanosecond (k * 10**9 // 240)."""
        return step * self._num // self._den


class ThrottledLog:
    """
    Logs each kind of message at most once per ``period_s`` (wall clock), counting the rest.

    Thread-safe: a callback thread and a library's own threads may share one.
    """

    def __init__(self, period_s: float = 5.0) -> None:
        self.period_s = period_s
        self._last: Dict[str, Tuple[float, int]] = {}  # kind -> (logged at, suppressed)
        self._lock = threading.Lock()

    def __call__(self, kind: str, log: Callable[[str], None], text: str) -> None:
        """Log ``text`` with ``log`` unless a message of this kind went out recently."""
        now = time.monotonic()
        with self._lock:
            last, suppressed = self._last.get(kind, (None, 0))
            if last is not None and now - last < self.period_s:
                self._last[kind] = (last, suppressed + 1)
                return
            self._last[kind] = (now, 0)
        log(text + (f' ({suppressed} more since the last one)' if suppressed else ''))
