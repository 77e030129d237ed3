"""
The file an MCAP recording goes through: the first write error ends the recording, in one report.

Given a path, foxglove-sdk 0.30 opens the file itself and keeps write errors
to itself: on a full disk every later message failed on its own
(``error logging message: McapError(AttemptedWriteAfterFailure)``, one stderr
line per message: about 35,000 in 25 s), and the final ``close()`` raised, a
traceback at Ctrl-C. Given a :class:`McapOutput` instead (the SDK takes
any object with ``write``, ``seek`` and ``flush``), the first failing write
or seek goes to ``on_failure`` once; from then on every call succeeds
without touching the disk, so the SDK never sees an error and finishes
quietly, and the owner stops feeding the file. The file then ends where
the disk did (no summary: a reader sees an unfinished recording).

The SDK calls these methods holding the GIL, from inside its writer's
lock. A thread that holds the GIL and waits for that lock (another
thread's ``log`` on the file's channels, or ``close``) would deadlock with
one inside it that waits for the GIL again after ``os.write`` (measured:
two threads logging at once hung at once). So every SDK call that may
touch the writer (making, logging on and closing the file's channels,
closing the writer) must hold :attr:`McapOutput.lock`.
"""

import os
import stat
import threading
from typing import Callable, Optional, Union

__all__ = ['McapOutput']


class McapOutput:
    """
    A new file at ``path`` for the MCAP writer; ``on_failure(OSError)`` at its first failure.

    Refuses (``FileExistsError``) any existing path, a dangling symlink
    included, unless ``overwrite``; refuses anything but a regular file
    (``IsADirectoryError``-like ``OSError``) even then. ``error`` holds the
    failure once there was one.
    """

    def __init__(self, path: str, overwrite: bool,
                 on_failure: Callable[[OSError], None]) -> None:
        self.path = path
        self.error: Optional[OSError] = None
        self.lock = threading.Lock()
        self._on_failure = on_failure
        # O_NONBLOCK: opening a FIFO with no reader fails instead of waiting forever.
        flags = (os.O_WRONLY | os.O_CREAT | os.O_NONBLOCK | getattr(os, 'O_CLOEXEC', 0)
                 | (os.O_TRUNC if overwrite else os.O_EXCL))
        self._fd: Optional[int] = os.open(path, flags, 0o666)
        if not stat.S_ISREG(os.fstat(self._fd).st_mode):
            os.close(self._fd)
            self._fd = None
            raise OSError(f'{path} is not a regular file')
        os.set_blocking(self._fd, True)
        self._position = 0  # where the next write goes (kept on after a failure)
        self._end = 0       # the size the file would have

    def write(self, data: Union[bytes, bytearray]) -> int:
        """Write all of ``data``; after a failure, pretend to (the SDK must not see it)."""
        view = memoryview(data).cast('B')
        size = view.nbytes
        if self.error is None:
            fd = self._fd
            assert fd is not None, 'the recording was written after it was closed'
            try:
                while view:
                    view = view[os.write(fd, view):]
            except OSError as exc:
                self._fail(exc)
        self._position += size
        self._end = max(self._end, self._position)
        return size

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        """Move to ``offset`` (from the start, the current place or the end); return it."""
        base = {os.SEEK_SET: 0, os.SEEK_CUR: self._position, os.SEEK_END: self._end}[whence]
        target = base + offset
        if self.error is None:
            fd = self._fd
            assert fd is not None, 'the recording was sought after it was closed'
            try:
                os.lseek(fd, target, os.SEEK_SET)
            except OSError as exc:
                self._fail(exc)
        self._position = target
        return target

    def tell(self) -> int:
        """Return where the next write goes."""
        return self._position

    def flush(self) -> None:
        """Nothing to do: every write went to the kernel at once."""

    def close(self) -> None:
        """Close the file (again: nothing happens)."""
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)

    def _fail(self, exc: OSError) -> None:
        self.error = exc
        self.close()  # the descriptor back at once; what was written stays
        self._on_failure(exc)

    def __repr__(self) -> str:
        return f'McapOutput({self.path!r}, error={self.error!r})'
