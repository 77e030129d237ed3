"""
``keep_large_blocks_mapped``: a large block gets pages of its own however large blocks came before.

glibc raises its mapping threshold to the size of each mapped block freed, so
by default a 256 kB block allocated after a 4 MB one was freed comes from an
arena; with the threshold kept, it is mapped (``mallinfo2``'s ``hblks`` counts
mapped blocks). Each case runs in a fresh interpreter: the setting is the process's.
"""

import subprocess
import sys

import pytest

PROBE = '''
import ctypes, sys
libc = ctypes.CDLL(None)
if not hasattr(libc, "mallinfo2"):
    print("skip"); sys.exit(0)
class MallInfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd",
                                               "usmblks", "fsmblks", "uordblks", "fordblks",
                                               "keepcost")]
libc.mallinfo2.restype = MallInfo2
libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, [ctypes.c_size_t]
libc.free.argtypes = [ctypes.c_void_p]
if sys.argv[1] == "kept":
    from r2d2_sim.memory import keep_large_blocks_mapped
    assert keep_large_blocks_mapped()
libc.free(libc.malloc(4 << 20))       # a large block freed: glibc raises its threshold
before = libc.mallinfo2().hblks
block = libc.malloc(256 << 10)
print("mapped" if libc.mallinfo2().hblks > before else "arena")
libc.free(block)
'''


def where_a_block_goes(mode):
    """Return where a 256 kB block after a freed 4 MB one goes: 'mapped', 'arena' or 'skip'."""
    done = subprocess.run([sys.executable, '-c', PROBE, mode], capture_output=True, text=True,
                          check=True, timeout=60)
    return done.stdout.split()[-1]


def test_a_large_block_is_mapped_once_kept_and_not_by_default():
    """Default glibc: the block comes from an arena; kept: it is mapped."""
    default = where_a_block_goes('default')
    if default == 'skip':
        pytest.skip('not glibc 2.33 or later (no mallinfo2)')
    assert (default, where_a_block_goes('kept')) == ('arena', 'mapped')
