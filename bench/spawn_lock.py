#!/usr/bin/env python3
"""
How long a spawn and a delete of a robot in a namespace hold the simulator's lock, and why.

    .venv/bin/python bench/spawn_lock.py [--cycles 60] [--domain 83]

A ``SimHarness`` in this process spawns our R2D2 in a namespace of its own and
deletes it again, ``--cycles`` times, as ``spawn_cycles.py`` does. The
harness's world verbs take the simulator's lock around the core's
``Simulation.spawn`` and ``delete_entity`` and nothing else, as the standard's
services in ``sim_node`` do, so the time of those two calls is the time the
lock is held (the paced loop waits that long for its next step). Timers put
on this harness's instances split it: the ROS side (``Fleet._add``: the
robot's ``RobotNode``; its ``RobotInterfaces``, of which its outputs, their
publishers and serialized templates, and its ``cmd_vel`` input; the executor
told of the node; ``Fleet._remove`` on delete) against the rest (reading and
loading the URDF, the robot's drive train and sensors, the world compacted
every 64 removals).

Printed: median, p90 and max of each part over the cycles (the first cycle
apart: it imports and warms caches). Writes ``bench/spawn_lock.json``.
Numbers are printed, never asserted.
"""

import argparse
import os
import statistics
import time

from common import BENCH_DIR, local_date, machine_info, percentile, write_json

RESULTS_PATH = os.path.join(BENCH_DIR, 'spawn_lock.json')
URDF = 'package://r2d2_sim/urdf/r2d2.urdf'
POSITION = (0.0, 2.0, 0.48)  # beside the default robot, as spawn_cycles.py
PARTS = ('spawn_lock', 'spawn_ros', 'robot_node', 'robot_interfaces', 'outputs', 'cmd_vel',
         'node_watchers', 'delete_lock', 'delete_ros')


def timed(parts, key, call):
    """Return ``call`` wrapped to add its wall time (ms) to ``parts[key]`` of this cycle."""
    def wrapper(*args, **kwargs):
        start = time.perf_counter()
        try:
            return call(*args, **kwargs)
        finally:
            parts[key] = parts.get(key, 0.0) + 1e3 * (time.perf_counter() - start)
    return wrapper


def measure(domain_id, cycles):
    """Spawn and delete ``cycles`` times; return each part's time per cycle (ms)."""
    import r2d2_sim.ros.fleet as fleet_module
    import r2d2_sim.ros.robot_interfaces as interfaces_module
    from r2d2_sim.testing import SimHarness
    samples = {key: [] for key in PARTS}
    parts = {}
    real_node, real_interfaces = fleet_module.RobotNode, fleet_module.RobotInterfaces
    real_outputs, real_cmd_vel = interfaces_module.RobotOutputs, interfaces_module.CmdVelInput
    with SimHarness(domain_id=domain_id) as sim:
        node = sim.sim
        simulation, fleet = node.simulation, node.fleet
        # Instance attributes shadow the methods the harness and the fleet look up.
        simulation.spawn = timed(parts, 'spawn_lock', simulation.spawn)
        simulation.delete_entity = timed(parts, 'delete_lock', simulation.delete_entity)
        fleet._add = timed(parts, 'spawn_ros', fleet._add)
        fleet._remove = timed(parts, 'delete_ros', fleet._remove)
        fleet._watchers = [(timed(parts, 'node_watchers', added), removed)
                           for added, removed in fleet._watchers]
        fleet_module.RobotNode = timed(parts, 'robot_node', real_node)
        fleet_module.RobotInterfaces = timed(parts, 'robot_interfaces', real_interfaces)
        interfaces_module.RobotOutputs = timed(parts, 'outputs', real_outputs)
        interfaces_module.CmdVelInput = timed(parts, 'cmd_vel', real_cmd_vel)
        try:
            for cycle in range(cycles):
                name = f'lock_{cycle}'
                parts.clear()
                sim.spawn(URDF, name=name, position=POSITION, namespace='/' + name)
                sim.advance()  # one control period: the robot publishes once
                sim.delete_entity(name)
                for key in PARTS:
                    samples[key].append(parts.get(key, 0.0))
        finally:
            fleet_module.RobotNode, fleet_module.RobotInterfaces = real_node, real_interfaces
            interfaces_module.RobotOutputs = real_outputs
            interfaces_module.CmdVelInput = real_cmd_vel
    return samples


def summarise(values):
    """Return the median, p90 and max of ``values`` (ms), the first cycle left out."""
    rest = values[1:]
    return {'first_ms': values[0], 'median_ms': statistics.median(rest),
            'p90_ms': percentile(rest, 90), 'max_ms': max(rest)}


def main(argv=None):
    """Measure, print and save."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--cycles', type=int, default=60, help='spawn/delete cycles')
    parser.add_argument('--domain', type=int, default=83, help='ROS domain id')
    args = parser.parse_args(argv)
    if args.cycles < 3:
        parser.error('at least 3 cycles')
    samples = measure(args.domain, args.cycles)
    summary = {key: summarise(samples[key]) for key in PARTS}
    print(f'{args.cycles} cycles of a robot in a namespace, spawned and deleted (ms):')
    print(f'{"part":<18} | {"first":>7} | {"median":>7} | {"p90":>7} | {"max":>7}')
    for key in PARTS:
        row = summary[key]
        print(f'{key:<18} | {row["first_ms"]:>7.2f} | {row["median_ms"]:>7.2f} | '
              f'{row["p90_ms"]:>7.2f} | {row["max_ms"]:>7.2f}')
    share = [ros / held for ros, held in zip(samples['spawn_ros'][1:],
                                             samples['spawn_lock'][1:]) if held > 0]
    print(f'the ROS side: {100 * statistics.median(share):.0f} % of a spawn\'s hold (median)')
    write_json(RESULTS_PATH, {'machine': machine_info(), 'date': local_date(),
                              'cycles': args.cycles, 'summary': summary, 'samples': samples})
    print(f'written to {RESULTS_PATH}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
