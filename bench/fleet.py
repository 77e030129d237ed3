#!/usr/bin/env python3
"""
Several robots in one world: what each robot costs, as fast as possible and at real time.

    .venv/bin/python bench/fleet.py [--quick] [--domain 80]

N robots (1, 2, 4, 8, 16) stand in a row 2 m apart, in one world.

- **Throughput**: an in-process node (rtf 0, ``advance`` without an executor, as
  ``SimHarness`` steps it) and raw ``stepSimulation`` of the very same world
  take turns every 60 steps (``common.alternate``), so both see the same load
  from other processes; their ratio is the bridge's share. Two configurations:
  ``state`` (every step, sensors and TF off, as the main bench's rows) and
  ``defaults`` (every step, scan 10 Hz, IMU 100 Hz, TF). The bridge's cost per
  robot is (1/node - 1/raw) / N; the node's whole step (1/node) against the
  4,167 us a step may take at 240 Hz says whether one core can keep real time.
- **Real time**: ``sim_node`` with N robots (1, 2, 4, 8, 12, 16) in a process
  of its own at ``real_time_factor`` 1 with the default outputs, nobody
  subscribed; the achieved rate (simulated over wall time, from ``~/get_status``)
  and the process's CPU share, over three 5 s windows (one of 4 s with ``--quick``).

Prints a table and writes ``bench/fleet.json``. Numbers are printed, never asserted.
"""

import argparse
import os
import statistics
import time

from common import (
    alternate, BENCH_DIR, init_ros, local_date, machine_info, make_sim_node, outputs_off,
    process_cpu_s, raw_stepper, write_json)

RESULTS_PATH = os.path.join(BENCH_DIR, 'fleet.json')
SPACING_M = 2.0
THROUGHPUT_ROBOTS = (1, 2, 4, 8, 16)
STEP_BUDGET_US = 1e6 / 240.0  # a step's share of one core at 240 Hz
REAL_TIME_ROBOTS = (1, 2, 4, 8, 12, 16)
KEEPS_REAL_TIME = 0.995  # achieved rate / 240 Hz


def fleet(count):
    """Return the parameters of ``count`` robots in a row along y, all facing +x."""
    if count == 1:
        return {}
    names = [f'r{i}' for i in range(count)]
    params = {'robots': names}
    for i, name in enumerate(names):
        params[f'{name}.initial_pose'] = [0.0, SPACING_M * i, 0.0]
    return params


def measure_throughput(domain_id, counts, rounds, min_s):
    """Steps/s of node and raw stepping of one world, per robot count and configuration."""
    import rclpy
    from rclpy.context import Context
    context = Context()
    init_ros(domain_id, context)
    results = {}
    nodes = []
    try:
        for count in counts:
            for config, extra in (('state', outputs_off()), ('defaults', {})):
                node = make_sim_node(context, f'/fleet_{config}_{count}',
                                     dict(fleet(count), real_time_factor=0.0, **extra))
                nodes.append(node)
                advances = [node.advance, raw_stepper(node.world)]
                for advance in advances:  # warm-up: the robots settle, code paths get hot
                    advance(240)
                samples = [alternate(advances, min_s)[0] for _ in range(rounds)]
                node_rates = [s[0] for s in samples]
                raw_rates = [s[1] for s in samples]
                ratios = [n / r for n, r in samples]
                best_node, best_raw = max(node_rates), max(raw_rates)
                results[f'{config}@{count}'] = {
                    'robots': count, 'config': config,
                    'node_steps_per_s': node_rates, 'raw_steps_per_s': raw_rates,
                    'ratio_median': statistics.median(ratios), 'ratios': ratios,
                    'raw_us_per_robot': 1e6 / best_raw / count,
                    'node_us_per_step': 1e6 / best_node,
                    'bridge_us_per_robot': (1e6 / best_node - 1e6 / best_raw) / count,
                }
                node.destroy_node()
                nodes.remove(node)
    finally:
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=context)
    return results


def measure_real_time(domain_id, counts, settle_s, window_s, windows):
    """
    Achieved rate and CPU share of sim_node at rtf 1 with N robots and the default outputs.

    ``windows`` back-to-back windows per N: N keeps real time if every one
    reached 99.5 % of 240 Hz; the rate and CPU reported are their medians.
    """
    from r2d2_sim.testing import SimProcess
    results = {}
    for count in counts:
        sim = SimProcess(domain_id=domain_id, state_subscriptions=False, timeout_s=60.0,
                         **fleet(count))
        factors, shares = [], []
        try:
            pid = sim.process.process.pid
            time.sleep(settle_s)
            for _ in range(windows):
                before, cpu_before, wall_before = (sim.status(), process_cpu_s(pid),
                                                   time.monotonic())
                time.sleep(window_s)
                after, cpu_after, wall_after = (sim.status(), process_cpu_s(pid),
                                                time.monotonic())
                wall = wall_after - wall_before
                factors.append((after['sim_time'] - before['sim_time']) / wall)
                shares.append((cpu_after - cpu_before) / wall)
        finally:
            sim.stop()
        factor = statistics.median(factors)
        results[str(count)] = {'robots': count, 'real_time_factor': factor,
                               'rate_hz': factor * 240.0, 'rates_hz': [f * 240 for f in factors],
                               'cpu_share': statistics.median(shares), 'cpu_shares': shares,
                               'keeps_real_time': min(factors) >= KEEPS_REAL_TIME}
    return results


def print_table(results):
    """Print the throughput and real-time rows."""
    print(f'\n{"robots":>6} | {"config":>8} | {"node/raw (median)":>18} | '
          f'{"raw us/robot":>12} | {"bridge us/robot":>15} | '
          f'node us/step (240 Hz: {STEP_BUDGET_US:.0f})')
    for entry in results['throughput'].values():
        print(f'{entry["robots"]:>6} | {entry["config"]:>8} | {entry["ratio_median"]:>18.3f} | '
              f'{entry["raw_us_per_robot"]:>12.1f} | {entry["bridge_us_per_robot"]:>15.1f} | '
              f'{entry.get("node_us_per_step", float("nan")):.0f}')
    print(f'\n{"robots":>6} | {"rate at rtf 1 (Hz), lowest":>26} | {"CPU of a core":>13} | '
          'keeps 240 Hz')
    for entry in results['real_time'].values():
        keeps = 'yes' if entry['keeps_real_time'] else 'no'
        rates = f'{entry["rate_hz"]:.2f}, {min(entry["rates_hz"]):.2f}'
        print(f'{entry["robots"]:>6} | {rates:>26} | {entry["cpu_share"] * 100:>12.1f}% | '
              f'{keeps}')


def main(argv=None):
    """Run the fleet bench; print and save the results."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='fewer and shorter windows')
    parser.add_argument('--domain', type=int, default=80, help='ROS domain id to run on')
    parser.add_argument('--output', default=RESULTS_PATH, help='where to write the results')
    args = parser.parse_args(argv)
    rounds, min_s = (2, 0.5) if args.quick else (5, 1.0)
    settle_s, window_s, windows = (1.0, 4.0, 1) if args.quick else (2.0, 5.0, 3)
    results = {'machine': machine_info(), 'date': local_date(), 'quick': args.quick,
               'throughput': measure_throughput(args.domain, THROUGHPUT_ROBOTS, rounds, min_s),
               'real_time': measure_real_time(args.domain + 1, REAL_TIME_ROBOTS, settle_s,
                                              window_s, windows)}
    write_json(args.output, results)
    print_table(results)
    print(f'\nwritten to {args.output}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
