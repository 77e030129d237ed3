#!/usr/bin/env python3
"""
What a robot's own links cost its scans: hidden from the rays, or tested and masked.

    .venv/bin/python bench/hidden_links.py [--rounds N]

A robot alone with rays in its world hides its own links from every ray
(``SimWorld.exclude_from_rays``: a collision mask without the group PyBullet
casts rays in, so Bullet never tests them); before, each beam tested them
and PyBullet dropped the hit. For each world, two simulations of one R2D2
with the default laser (360 beams): one as built (hidden), one whose links a
cast with a seeing mask showed again (as a second robot would). Both drive
the same circle for half a second, then take turns: 100 scans each, thread
CPU time, ``--rounds`` times; the median per scan of each, and whether
every scan of the two is the same, byte for byte.

Prints a table and writes ``bench/hidden_links.json``. Numbers are printed,
never asserted.
"""

import argparse
import os
import statistics
import time

from common import BENCH_DIR, local_date, machine_info, write_json

RESULTS_PATH = os.path.join(BENCH_DIR, 'hidden_links.json')
WORLDS = {'empty': '', 'room (room.world.yaml)': 'room.world.yaml',
          'samurai (samurai.world.yaml)': 'samurai.world.yaml'}
SCANS = 100


def simulation(world):
    """Return a one-robot simulation of ``world`` with the laser at 10 Hz, commands kept."""
    from r2d2_sim.sim.settings.robots import parse_world
    from r2d2_sim.sim.simulation import Simulation
    parameters = {'scan_rate': 10.0, 'cmd_vel_timeout': 0.0}
    if world:
        parameters['world'] = world
    return Simulation(*parse_world(parameters))


def measure(world, rounds):
    """Median µs per scan, hidden and shown, in turns; and whether the scans are identical."""
    import numpy
    hidden, shown = simulation(world), simulation(world)
    try:
        shown.world.cast_rays(numpy.zeros((1, 3)), numpy.ones((1, 3)), mask=-1)  # shows them
        assert hidden.robot.body.hidden_ray_groups and not shown.robot.body.hidden_ray_groups
        for sim in (hidden, shown):
            sim.robot.command(0.3, 0.4)
            for _ in range(120):
                sim.step()
        times = {'hidden': [], 'shown': []}
        same = True
        for _ in range(rounds):
            scans = {}
            for name, sim in (('hidden', hidden), ('shown', shown)):
                laser = sim.robot.laser
                started = time.thread_time()
                for _ in range(SCANS):
                    scans[name] = laser.scan()
                times[name].append((time.thread_time() - started) / SCANS * 1e6)
            same = same and scans['hidden'].tobytes() == scans['shown'].tobytes()
        return {'hidden_us': statistics.median(times['hidden']),
                'shown_us': statistics.median(times['shown']), 'samples_us': times,
                'same_scans': same}
    finally:
        hidden.close()
        shown.close()


def main():
    """Measure each world; print the table; write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rounds', type=int, default=7)
    args = parser.parse_args()
    results = {'date': local_date(), 'machine': machine_info(), 'rounds': args.rounds,
               'worlds': {name: measure(world, args.rounds) for name, world in WORLDS.items()}}
    print(f"{results['date']}, {results['machine']['cpu_model']}, one R2D2, 360 beams, "
          f'median of {args.rounds} x {SCANS} scans, thread CPU:')
    for name, row in results['worlds'].items():
        print(f"  {name:30s} shown {row['shown_us']:6.0f} us, hidden {row['hidden_us']:6.0f} "
              f"us ({row['hidden_us'] / row['shown_us']:.2f}); the same scans: "
              f"{row['same_scans']}")
    write_json(RESULTS_PATH, results)


if __name__ == '__main__':
    main()
