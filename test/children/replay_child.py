"""
``replay`` in a child process that reports on itself, for the tests of hostile recordings.

    python replay_child.py LIMIT_MIB FILE [replay arguments...]

Limits the process's address space to LIMIT_MIB (so a bound that fails
ends in a MemoryError instead of taking the machine's memory), runs
``replay``'s ``main``, then prints one last stdout line,
``replay_child: maxrss_kib=N this_imported=B``, and exits with replay's status.
"""

import resource
import sys


def main() -> int:
    limit = int(sys.argv[1]) * 2**20
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    status = 1
    try:
        from r2d2_sim.apps.replay import main as replay
        status = replay(['replay'] + sys.argv[2:])
    finally:
        print(f'replay_child: maxrss_kib={peak_rss_kib()} '
              f'this_imported={"this" in sys.modules}', flush=True)
    return status


def peak_rss_kib() -> int:
    """
    Return this process's own peak resident memory (KiB): VmHWM of its address space.

    Not getrusage's ru_maxrss: Linux keeps that across fork and exec, so a
    child started from a big test worker reports the worker's peak as its own.
    """
    with open('/proc/self/status', encoding='ascii') as status:
        for line in status:
            if line.startswith('VmHWM:'):
                return int(line.split()[1])
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


if __name__ == '__main__':
    sys.exit(main())
