"""
Silence PyBullet's own chatter: its build-time banner and ``argv[0]=``.

PyBullet prints those from C on import (to stderr) and on every connect (to
stdout), so a ROS node's output would not be only its own log lines. Only
those two moments are silenced: warnings PyBullet prints while loading or
simulating still show, and an exception raised inside still propagates.
"""

from contextlib import contextmanager
import ctypes
import os
import sys
from typing import Iterator


def _flush_c_stdio() -> None:
    ctypes.CDLL(None).fflush(None)


@contextmanager
def silenced_output(stderr: bool = True) -> Iterator[None]:
    """
    Send file descriptor 1 (and 2, with ``stderr``) to /dev/null while the block runs.

    C stdio buffers are flushed on the way in and out, so what was printed
    inside is dropped, not delayed until exit.
    """
    fds = (1, 2) if stderr else (1,)
    sys.stdout.flush()
    sys.stderr.flush()
    _flush_c_stdio()
    saved = [os.dup(fd) for fd in fds]
    devnull = os.open(os.devnull, os.O_WRONLY)
    for fd in fds:
        os.dup2(devnull, fd)
    os.close(devnull)
    try:
        yield
    finally:
        _flush_c_stdio()
        for fd, copy in zip(fds, saved):
            os.dup2(copy, fd)
            os.close(copy)
