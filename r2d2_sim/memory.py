"""
Freed memory given back to the system: glibc's ``malloc_trim``, for every layer.

Memory a C library frees (PyBullet's shapes after a world is built again,
the live view's buffers after its viewers left) stays in the process's
malloc arenas, one per thread that allocated it, until it is trimmed:
resident memory then grows in steps with the threads that touched it. No
imports from the package: the physics and the recording layers both use it.

:func:`keep_large_blocks_mapped` is for a long-lived process (``sim_node``):
glibc raises its threshold for mapping large blocks each time one is freed,
so after a while the large blocks PyBullet allocates when a world is built
again come from the arenas instead, and are not all given back: spawning
and deleting robots, ``sim_node`` grew by about 7 MB at some compactions
and gave it back at a later one (issue 39; ``bench/spawn_cycles.py``).
"""

import ctypes
from typing import Callable

__all__ = ['malloc_trim', 'keep_large_blocks_mapped', 'LARGE_BLOCK_BYTES']

# glibc's initial threshold: a block this large gets pages of its own, which go
# back to the system the moment it is freed.
LARGE_BLOCK_BYTES = 128 * 1024
M_MMAP_THRESHOLD = -3  # mallopt's parameter number (malloc.h)


def _load() -> Callable[[], int]:
    try:
        trim = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):  # not glibc: nothing to give back this way
        return lambda: 0
    trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
    return lambda: trim(0)


malloc_trim: Callable[[], int] = _load()
malloc_trim.__doc__ = 'Give the free memory of every malloc arena back to the system (glibc).'


def keep_large_blocks_mapped() -> bool:
    """
    Keep blocks of LARGE_BLOCK_BYTES and more in pages of their own (glibc); False elsewhere.

    Setting the threshold stops glibc from raising it as large blocks are
    freed (see the module), for the whole process.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return mallopt(M_MMAP_THRESHOLD, LARGE_BLOCK_BYTES) == 1
