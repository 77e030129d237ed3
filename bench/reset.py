#!/usr/bin/env python3
"""
What a reset costs: the state reset (the physics world built again) and the full reset.

    .venv/bin/python bench/reset.py [--quick]

In the core (``Simulation``, no ROS), with 1 and 8 robots (a row 2 m apart,
default outputs: the laser's ray group is set again on every robot) on the
plane: before each reset the robots drive for 0.1 s, so there are contacts to
forget. Measured, in wall milliseconds per reset: a state reset
(``reset(state=True)``: ``resetSimulation``, every body loaded again in its
order with its changes, every robot started again); a full reset (time,
state and spawned, with one box spawned before each); beside them the former
reset in place (every body and robot put back, which does not repeat a run
bit for bit) and building a new ``Simulation`` from the same parameters (a
restart without the process and ROS). Medians and 90th percentiles of each.

Prints a table and writes ``bench/reset.json``. Numbers are printed, never asserted.
"""

import argparse
import os
import statistics
import time

from common import BENCH_DIR, local_date, machine_info, percentile, write_json

RESULTS_PATH = os.path.join(BENCH_DIR, 'reset.json')
ROBOTS = (1, 8)
SPACING_M = 2.0


def fleet(count):
    """Return the parameters of ``count`` robots in a row along y, all facing +x."""
    if count == 1:
        return {}
    names = [f'r{i}' for i in range(count)]
    params = {'robots': names}
    for i, name in enumerate(names):
        params[f'{name}.initial_pose'] = [0.0, SPACING_M * i, 0.0]
    return params


def build(count):
    """Return a new Simulation of ``count`` robots (default outputs)."""
    from r2d2_sim.sim.settings.robots import parse_world
    from r2d2_sim.sim.simulation import Simulation
    return Simulation(*parse_world(fleet(count)))


def drive(simulation):
    """Drive every robot for 0.1 s (24 steps)."""
    for robot in simulation.robots:
        robot.command(0.3, 0.2)
    for _ in range(24):
        simulation.step()


def reset_in_place(simulation):
    """Put every body and robot back where it started, in place (the reset before the rebuild)."""
    robots = {id(robot.body) for robot in simulation.robots}
    for body in simulation.world.bodies.values():
        if id(body) not in robots:
            body.reset()
    for robot in simulation.robots:
        robot.reset()


def spawn_box(simulation):
    """Spawn a small box the full reset then deletes."""
    from r2d2_sim.sim.simulation import SpawnRequest
    simulation.spawn(SpawnRequest('box', uri='cube_small.urdf', position=(1.0, 0.5, 0.025)))


def time_ms(simulation, how, samples):
    """Return ``samples`` wall times (ms) of reset ``how``, each after 0.1 s of driving."""
    times = []
    for _ in range(samples):
        drive(simulation)
        if how == 'full':
            spawn_box(simulation)
        start = time.perf_counter()
        if how == 'state':
            simulation.reset(state=True)
        elif how == 'full':
            simulation.reset(time=True, state=True, spawned=True)
        else:
            reset_in_place(simulation)
        times.append((time.perf_counter() - start) * 1e3)
    return times


def time_start_ms(count, samples):
    """Return ``samples`` wall times (ms) of building and closing a Simulation of ``count``."""
    times = []
    for _ in range(samples):
        start = time.perf_counter()
        simulation = build(count)
        times.append((time.perf_counter() - start) * 1e3)
        simulation.close()
    return times


def summary(times):
    """Return the median and 90th percentile of ``times``."""
    return {'median_ms': statistics.median(times), 'p90_ms': percentile(times, 90),
            'samples_ms': times}


def main():
    """Measure each reset with 1 and 8 robots; print the table; write bench/reset.json."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--quick', action='store_true', help='fewer samples (~10 s)')
    args = parser.parse_args()
    samples = 10 if args.quick else 40
    results = {}
    for count in ROBOTS:
        simulation = build(count)
        try:
            for how in ('state', 'full', 'in place'):
                time_ms(simulation, how, 2)  # warm-up
                results[f'{how}@{count}'] = summary(time_ms(simulation, how, samples))
        finally:
            simulation.close()
        results[f'start@{count}'] = summary(time_start_ms(count, max(3, samples // 4)))
    rows = (('state reset: world built again', 'state'),
            ('full reset (time, state, spawned; one box spawned)', 'full'),
            ('reset in place (before; not bit for bit)', 'in place'),
            ('a new Simulation (start-up, no ROS)', 'start'))
    heads = ' '.join(f'{n} robot(s)'.rjust(16) for n in ROBOTS)
    print(f'{"ms per reset, median (p90)":52} {heads}')
    for label, how in rows:
        cells = [results[f'{how}@{n}'] for n in ROBOTS]
        print(f'{label:52} ' + ' '.join(
            f'{c["median_ms"]:7.2f} ({c["p90_ms"]:6.2f})'.rjust(16) for c in cells))
    write_json(RESULTS_PATH, {'date': local_date(), 'machine': machine_info(),
                              'samples': samples, 'results': results})


if __name__ == '__main__':
    main()
