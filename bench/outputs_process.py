#!/usr/bin/env python3
"""
What `outputs_process` takes off the physics thread: the node publishing itself, or the relay.

    .venv/bin/python bench/outputs_process.py [--quick]

Both in one run, in turns, every topic taken (a subscription on each, so every
output is built and published):

- **in process**, 1, 4 and 16 robots in a row with the default outputs: the node
  publishing itself (``direct``), the node handing its bytes to the outputs
  process (``relay``, ``advance_if_running``: the real-time loop's, which
  does not wait for the child) and raw ``stepSimulation`` of the same world,
  taking turns every 60 steps (``common.alternate``). Steps per second of the stepping thread's CPU
  (what the physics thread spends: the child's work is on the other core) and
  per wall second (which also counts waiting for a child that fell behind).
- **recording**, the same in process with ``record`` on: the node's own
  sink (``direct``), and the outputs process's (``relay``: the child writes the
  MCAP file), 1 and 16 robots.
- **at real time**: ``sim_node`` at rtf 1 with 16 robots driving and every topic
  taken by another context, with and without ``outputs_process``, in turns:
  the rate of one-second windows timed by ``/clock`` as it arrives (median and
  lowest) and the simulator's CPU (its own process; the child's beside it);
  then the same with nobody subscribed and every topic recorded.

Prints a table and writes ``bench/outputs_process.json``. Numbers are printed,
never asserted.
"""

import argparse
import os
import statistics
import tempfile

from common import (
    alternate, BENCH_DIR, init_ros, local_date, machine_info, make_sim_node, raw_stepper,
    TopicTaker, write_json)
from fleet import fleet, measure_real_time

RESULTS_PATH = os.path.join(BENCH_DIR, 'outputs_process.json')
THROUGHPUT_ROBOTS = (1, 4, 16)
RECORDING_ROBOTS = (1, 16)
REAL_TIME_ROBOTS = 16
TOPICS_PER_ROBOT = 5  # joint_states, odom, ground_truth, scan, imu (and /tf, /clock)


def measure_throughput(domain_id, counts, rounds, min_s, record_in=None):
    """
    Steps/s (thread CPU and wall) of direct, relay and raw stepping, per robot count.

    ``record_in``: a folder; each node records to a file of its own there.
    """
    import rclpy
    from rclpy.context import Context
    context = Context()
    init_ros(domain_id, context)
    results = {}
    try:
        for count in counts:
            nodes = {mode: make_sim_node(context, f'/{mode}_{count}', dict(
                fleet(count), real_time_factor=0.0, outputs_process=(mode == 'relay'),
                **({} if record_in is None else
                   {'record': os.path.join(record_in, f'{mode}_{count}.mcap')})))
                for mode in ('direct', 'relay')}
            taker = TopicTaker(domain_id)
            try:
                # /clock is one topic for both; /tf one per simulator.
                taker.wait(2 * TOPICS_PER_ROBOT * count + 2)
                advances = [lambda s: nodes['direct'].advance(s),
                            nodes['relay'].advance_if_running,
                            raw_stepper(nodes['direct'].world)]
                for advance in advances:
                    advance(240)
                nodes['relay'].relay.wait()
                samples = [alternate(advances, min_s) for _ in range(rounds)]
                nodes['relay'].relay.wait()
            finally:
                taker.close()
                for node in nodes.values():
                    node.destroy_node()
            cpu = [s[0] for s in samples]
            wall = [s[1] for s in samples]
            results[str(count)] = {
                'robots': count,
                'cpu_steps_per_s': {m: [c[i] for c in cpu]
                                    for i, m in enumerate(('direct', 'relay', 'raw'))},
                'wall_steps_per_s': {m: [w[i] for w in wall]
                                     for i, m in enumerate(('direct', 'relay', 'raw'))},
                'cpu_ratio': {m: statistics.median(c[i] / c[2] for c in cpu)
                              for i, m in enumerate(('direct', 'relay'))},
                'wall_ratio': {m: statistics.median(w[i] / w[2] for w in wall)
                               for i, m in enumerate(('direct', 'relay'))},
                'us_per_step': {m: 1e6 / statistics.median(c[i] for c in cpu)
                                for i, m in enumerate(('direct', 'relay', 'raw'))},
            }
    finally:
        rclpy.try_shutdown(context=context)
    return results


def measure_real_time_in_turns(domain_id, rounds, settle_s, window_s, windows, record_in=None):
    """
    sim_node at rtf 1, 16 robots driving: direct and relay in turns.

    Every topic taken; or, with ``record_in`` (a folder), nobody subscribed and
    every topic recorded there.
    """
    runs = {'direct': [], 'relay': []}
    for round_index in range(rounds):
        for mode in runs:
            parameters = {'outputs_process': mode == 'relay'}
            if record_in is not None:
                parameters['record'] = os.path.join(record_in, f'{mode}_{round_index}.mcap')
            result = measure_real_time(domain_id, (REAL_TIME_ROBOTS,), settle_s, window_s,
                                       windows, driving=True, taken=record_in is None,
                                       parameters=parameters)
            runs[mode].append(result[str(REAL_TIME_ROBOTS)])
    return runs


def print_table(results):
    """Print the in-process rows and the real-time runs."""
    for part in ('throughput', 'recording'):
        if part in results:
            print_rows(part, results[part])
    for part, what in (('real_time', 'every topic taken'),
                       ('real_time_recorded', 'nobody subscribed, every topic recorded')):
        if part not in results:
            continue
        print(f'\nsim_node at rtf 1, {REAL_TIME_ROBOTS} robots driving, {what} '
              '(median (lowest second) Hz, CPU of the simulator process):')
        for mode, runs in results[part].items():
            text = ', '.join(f"{r['rate_hz']:.2f} ({r['lowest_hz']:.2f}) at "
                             f"{r['cpu_share']:.0%} ({r['cpu_share_with_children']:.0%} with "
                             'the outputs process)' for r in runs)
            print(f'  {mode}: {text}')


def print_rows(part, rows):
    """Print one in-process table: every topic taken, or recorded too."""
    print(f'\n{part}:')
    print('| robots | node / raw, thread CPU: direct | relay | µs a step: direct / relay / raw '
          '| node / raw, wall: direct | relay |')
    print('|---|---|---|---|---|---|')
    for row in rows.values():
        us = row['us_per_step']
        print(f"| {row['robots']} | {row['cpu_ratio']['direct']:.3f} | "
              f"{row['cpu_ratio']['relay']:.3f} | {us['direct']:.0f} / {us['relay']:.0f} / "
              f"{us['raw']:.0f} | {row['wall_ratio']['direct']:.3f} | "
              f"{row['wall_ratio']['relay']:.3f} |")


def main(argv=None):
    """Run the bench; print and save the results."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='fewer and shorter windows')
    parser.add_argument('--domain', type=int, default=87, help='ROS domain id to run on')
    parser.add_argument('--output', default=RESULTS_PATH, help='where to write the results')
    parser.add_argument('--rounds', type=int, default=3, help='real-time runs of each, in turns')
    args = parser.parse_args(argv)
    rounds, min_s = (2, 0.5) if args.quick else (5, 1.0)
    settle_s, window_s, windows = (1.0, 1.0, 4) if args.quick else (2.0, 1.0, 8)
    real_time_rounds = 1 if args.quick else args.rounds
    with tempfile.TemporaryDirectory() as folder:
        recording = measure_throughput(args.domain, RECORDING_ROBOTS, rounds, min_s, folder)
    with tempfile.TemporaryDirectory() as folder:
        recorded_real_time = measure_real_time_in_turns(
            args.domain + 1, real_time_rounds, settle_s, window_s, windows, folder)
    results = {'machine': machine_info(), 'date': local_date(), 'quick': args.quick,
               'throughput': measure_throughput(args.domain, THROUGHPUT_ROBOTS, rounds, min_s),
               'recording': recording,
               'real_time': measure_real_time_in_turns(args.domain + 1, real_time_rounds,
                                                       settle_s, window_s, windows),
               'real_time_recorded': recorded_real_time}
    write_json(args.output, results)
    print_table(results)
    print(f'\nwritten to {args.output}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
