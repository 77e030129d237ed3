#!/usr/bin/env python3
"""
What a LoadWorld costs: the room's manifest, a manifest of 36 boxes, a world of one big mesh.

    .venv/bin/python bench/worlds.py [--quick]

In the core (``Simulation.load_world``, no ROS), one robot with the default
outputs: each world is loaded in turn with the empty world, so every load
replaces a world, and the robot drives 0.1 s before each. Measured, in wall
milliseconds per load: the whole load (read and check the files, load every
model once in a scratch physics world, then build the world as launched),
and its first part alone (``read_world`` and the check: what a refused load
costs at most). The 36 boxes are 0.3 m cubes of one URDF in a 6 x 6 grid, in
a temporary directory given as ``world_paths``. The big mesh is pybullet_data's
samurai monastery (``samurai.world.yaml``), fewer samples. Medians and 90th
percentiles.

Prints a table and writes ``bench/worlds.json``. Numbers are printed, never asserted.
"""

import argparse
import os
import statistics
import tempfile
import time

from common import BENCH_DIR, local_date, machine_info, percentile, write_json

RESULTS_PATH = os.path.join(BENCH_DIR, 'worlds.json')
ROOM = 'package://r2d2_sim/urdf/room.world.yaml'
EMPTY = 'package://r2d2_sim/urdf/empty.world.yaml'
BOX = ('<robot name="box"><link name="box"><inertial><mass value="2"/><inertia ixx="0.03" '
       'iyy="0.03" izz="0.03" ixy="0" ixz="0" iyz="0"/></inertial><visual><geometry><box '
       'size="0.3 0.3 0.3"/></geometry></visual><collision><geometry><box size="0.3 0.3 0.3"/>'
       '</geometry></collision></link></robot>')


def boxes_world(directory, count=36):
    """Write a box URDF and a manifest of ``count`` boxes in a grid 1 m apart; return its name."""
    with open(os.path.join(directory, 'box.urdf'), 'w') as handle:
        handle.write(BOX)
    side = int(count ** 0.5)
    lines = ['r2d2_sim_world: 1', 'name: boxes', 'tags: [bench]', 'models:']
    for i in range(count):
        x, y = 2.0 + i % side, -side / 2.0 + i // side
        lines.append(f'  - {{uri: box.urdf, name: box_{i}, position: [{x}, {y}, 0.15], '
                     'tags: [box]}')
    with open(os.path.join(directory, 'boxes.world.yaml'), 'w') as handle:
        handle.write('\n'.join(lines) + '\n')
    return 'boxes.world.yaml'


def drive(simulation):
    """Drive the robot for 0.1 s (24 steps), so the world has moved before the load."""
    simulation.robot.command(0.3, 0.2)
    for _ in range(24):
        simulation.step()


def time_loads(simulation, uri, samples):
    """Return (whole load, read and check) wall times in ms, ``samples`` of each."""
    from r2d2_sim.sim.worlds import read_world
    whole, check = [], []
    for _ in range(samples):
        simulation.load_world(EMPTY)
        drive(simulation)
        start = time.perf_counter()
        world = read_world(uri, '', simulation.worlds.places)
        simulation._check_world(world)  # what load_world does before it builds
        check.append((time.perf_counter() - start) * 1e3)
        world.close()
        start = time.perf_counter()
        simulation.load_world(uri)
        whole.append((time.perf_counter() - start) * 1e3)
    return whole, check


def summary(times):
    """Return the median and 90th percentile of ``times``."""
    return {'median_ms': statistics.median(times), 'p90_ms': percentile(times, 90),
            'samples_ms': times}


def main():
    """Measure each world's load; print the table; write bench/worlds.json."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--quick', action='store_true', help='fewer samples (~15 s)')
    args = parser.parse_args()
    samples = 8 if args.quick else 30
    from r2d2_sim.sim.settings.robots import parse_world
    from r2d2_sim.sim.simulation import Simulation
    results = {}
    with tempfile.TemporaryDirectory() as directory:
        boxes = boxes_world(directory)
        simulation = Simulation(*parse_world({'world_paths': [directory]}))
        try:
            worlds = (('room', ROOM, samples), ('36 boxes', boxes, samples),
                      ('samurai (one big mesh)', 'samurai.world.yaml', max(3, samples // 6)))
            for label, uri, count in worlds:
                time_loads(simulation, uri, 1)  # warm-up
                whole, check = time_loads(simulation, uri, count)
                results[label] = {'load': summary(whole), 'read and check': summary(check),
                                  'entities': len(simulation.entities.names())}
        finally:
            simulation.close()
    print(f'{"ms per LoadWorld, median (p90)":34} {"whole load":>18} {"read and check":>18}')
    for label, row in results.items():
        cells = [row[k] for k in ('load', 'read and check')]
        print(f'{label:34} ' + ' '.join(
            f'{c["median_ms"]:8.1f} ({c["p90_ms"]:6.1f})'.rjust(18) for c in cells))
    write_json(RESULTS_PATH, {'date': local_date(), 'machine': machine_info(),
                              'samples': samples, 'results': results})


if __name__ == '__main__':
    main()
