"""
Spawning and deleting a robot for long: the core's memory stays flat (issue 30, U3-2).

PyBullet keeps every loaded URDF's shapes (14-17 kB for our R2D2) until the
world is built again; the world compacts itself every 64 removals, so 192
cycles after a warm-up leave the process's resident memory where it was
(before compaction: about 3.2 MB more). Resident memory is the process's,
read from /proc; the bound leaves room for the allocator's noise.
"""

import os

import pytest

from r2d2_sim.physics.world import COMPACT_AFTER_REMOVALS
from r2d2_sim.sim.simulation import SpawnRequest

ROBOT = 'package://r2d2_sim/urdf/r2d2.urdf'
CYCLES = 3 * COMPACT_AFTER_REMOVALS  # 192
MAX_GROWTH_MB = 1.0


def resident_mb() -> float:
    with open('/proc/self/statm') as statm:
        return int(statm.read().split()[1]) * os.sysconf('SC_PAGE_SIZE') / 2**20


@pytest.mark.slow
@pytest.mark.skipif(not os.path.exists('/proc/self/statm'), reason='needs Linux /proc')
def test_robots_spawned_and_deleted_for_long_leave_memory_flat(make):
    simulation = make(scan_rate=0.0, imu_rate=0.0)
    count = 0

    def cycles(n):
        nonlocal count
        for _ in range(n):
            count += 1
            name = f'cycle_{count}'
            simulation.spawn(SpawnRequest(name, uri=ROBOT, namespace='/' + name,
                                          position=(0.0, 3.0, 0.5)))
            simulation.step()
            simulation.delete_entity(name)
    cycles(COMPACT_AFTER_REMOVALS)  # warm up: the allocator's arenas, one compaction
    before = resident_mb()
    cycles(CYCLES)
    growth = resident_mb() - before
    assert growth < MAX_GROWTH_MB, f'{growth:.2f} MB after {CYCLES} cycles'
    assert simulation.world.removed_since_built == 0  # compacted three times more
