"""
Freed memory given back to the system: glibc's ``malloc_trim``, for every layer.

Memory a C library frees (PyBullet's shapes after a world is built again,
the live view's buffers after its viewers left) stays in the process's
malloc arenas, one per thread that allocated it, until it is trimmed:
resident memory then grows in steps with the threads that touched it. No
imports from the package: the physics and the recording layers both use it.
"""

import ctypes
from typing import Callable

__all__ = ['malloc_trim']


def _load() -> Callable[[], int]:
    try:
        trim = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):  # not glibc: nothing to give back this way
        return lambda: 0
    trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
    return lambda: trim(0)


malloc_trim: Callable[[], int] = _load()
malloc_trim.__doc__ = 'Give the free memory of every malloc arena back to the system (glibc).'
