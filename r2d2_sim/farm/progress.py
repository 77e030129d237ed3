"""
A farm's progress on one line: done of total, passes, failures, crashes, time left.

On a terminal the line is redrawn in place (at most ten times a second);
elsewhere (a CI log) a line is written every tenth of the variations or 30
seconds, whichever comes first, so a log stays short. Time left is the time
per variation so far (this run's, not a resumed run's) times what is left.
"""

import sys
import time
from typing import Optional, TextIO

__all__ = ['Progress']

BAR_WIDTH = 24
REDRAW_S = 0.1
LOG_EVERY_S = 30.0


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, seconds = divmod(rest, 60)
    return f'{hours}:{minutes:02d}:{seconds:02d}' if hours else f'{minutes}:{seconds:02d}'


class Progress:
    """
    The progress of ``total`` variations, ``done`` of them finished before this run.

    ``stream`` (default stderr) and ``live`` (default: whether it is a
    terminal) choose the form; ``enabled=False`` writes nothing.
    """

    def __init__(self, total: int, done: int = 0, *, stream: Optional[TextIO] = None,
                 live: Optional[bool] = None, enabled: bool = True) -> None:
        self.total = total
        self.stream = stream or sys.stderr
        self.live = self.stream.isatty() if live is None else live
        self.enabled = enabled
        self.passed = self.failed = self.crashed = 0
        self.resumed = done
        self.started = time.monotonic()
        self._drawn = 0.0
        self._logged_at = self.started
        self._logged_count = done

    @property
    def done(self) -> int:
        """Return the variations finished, resumed ones included."""
        return self.resumed + self.passed + self.failed + self.crashed

    def add(self, verdict: str) -> None:
        """Count one finished variation: ``passed``, ``failed`` or ``crashed``."""
        setattr(self, verdict, getattr(self, verdict) + 1)
        self._show()

    def line(self) -> str:
        """Return the progress line."""
        done, total = self.done, max(self.total, 1)
        filled = int(BAR_WIDTH * done / total)
        bar = '#' * filled + '-' * (BAR_WIDTH - filled)
        ran = done - self.resumed
        elapsed = time.monotonic() - self.started
        left = '?' if ran == 0 else _clock(elapsed / ran * (self.total - done))
        crashed = f', {self.crashed} crashed' if self.crashed else ''
        return (f'[{bar}] {done}/{self.total}: {self.passed} passed, {self.failed} failed'
                f'{crashed}; {_clock(elapsed)} so far, {left} left')

    def _show(self) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if self.live:
            if now - self._drawn >= REDRAW_S or self.done == self.total:
                self.stream.write('\r' + self.line() + '\x1b[K')
                self.stream.flush()
                self._drawn = now
            return
        step = max(1, self.total // 10)
        if (self.done - self._logged_count >= step or now - self._logged_at >= LOG_EVERY_S
                or self.done == self.total):
            self.stream.write(self.line() + '\n')
            self.stream.flush()
            self._logged_at, self._logged_count = now, self.done

    def finish(self) -> None:
        """End the line on a terminal."""
        if self.enabled and self.live:
            self.stream.write('\r' + self.line() + '\x1b[K\n')
            self.stream.flush()
