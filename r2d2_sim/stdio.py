"""
Silence PyBullet's own stdout chatter: its build-time banner and ``argv[0]=``.

PyBullet prints those from C on import and on every connect, so a ROS node's
output would not be only its own log lines. Only those two moments are
silenced: warnings PyBullet prints while loading or simulating still show.
"""

from contextlib import contextmanager
import ctypes
import os
import sys
from typing import Iterator


def _flush_c_stdio() -> None:
    ctypes.CDLL(None).fflush(None)


@contextmanager
def silenced_stdout() -> Iterator[None]:
    """
    Send file descriptor 1 to /dev/null while the block runs.

    C stdio buffers are flushed on the way in and out, so what was printed
    inside is dropped, not delayed until exit.
    """
    sys.stdout.flush()
    _flush_c_stdio()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.close(devnull)
    try:
        yield
    finally:
        _flush_c_stdio()
        os.dup2(saved, 1)
        os.close(saved)
