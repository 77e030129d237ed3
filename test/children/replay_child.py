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
        print(f'replay_child: maxrss_kib={resource.getrusage(resource.RUSAGE_SELF).ru_maxrss} '
              f'this_imported={"this" in sys.modules}', flush=True)
    return status


if __name__ == '__main__':
    sys.exit(main())
