#!/usr/bin/env python3
"""
Several robots in one world: what each robot costs, as fast as possible and at real time.

    .venv/bin/python bench/fleet.py [--quick] [--domain 80]

N robots (1, 2, 4, 8, 16) stand in a row 2 m apart, in one world.

- **Throughput**: an in-process node (rtf 0, ``advance`` without an executor, as
  ``SimHarness`` steps it) and raw ``stepSimulation`` of the very same world
  take turns every 60 steps (``common.alternate``), so both see the same load
  from other processes; their ratio is the bridge's share. Three configurations:
  ``state`` (every step, sensors and TF off, as the main bench's rows),
  ``defaults`` (every step, scan 10 Hz, IMU 100 Hz, TF), both with every topic
  taken by a subscription in this process (``common.take_every_topic``: the
  outputs build only what someone takes), and ``untaken`` (the defaults, nobody
  subscribed: the robots are measured, no message is built). The bridge's cost per
  robot is (1/node - 1/raw) / N; the node's whole step (1/node) against the
  4,167 us a step may take at 240 Hz says whether one core can keep real time.
- **Real time**: ``sim_node`` with N robots (1, 2, 4, 8, 12, 16, 24, 28) in a process
  of its own at ``real_time_factor`` 1 with the default outputs, nobody
  subscribed but this bench's ``/clock`` listener; the achieved rate (simulated
  over wall time, from the ``/clock`` messages as they arrive) and the process's
  CPU share, over back-to-back one-second windows (ten; four with ``--quick``): N
  keeps real time when its lowest window reaches 239 Hz; and how long the node
  took to answer ``~/get_status`` (asked once a window) at most. Twice: the
  robots standing (parked: their wheels braked, as after start-up) and driving
  (each sent one ``cmd_vel``, 0.3 m/s turning at 0.6 rad/s, with
  ``cmd_vel_timeout`` 0 so it never stops: circles of 0.5 m, 2 m apart), since
  a parked robot's physics costs less. Then driving again with every topic
  taken (N = 1, 8, 12, 16), by subscriptions in another context
  (``common.TopicTaker``): what a node pays when its robots are listened to.

- **Ray threads**: 16 robots driving at real time, ``ray_threads`` 1 (every
  scan on the physics thread) and auto (two threads on two cores), in turns.

Prints a table and writes ``bench/fleet.json``. Numbers are printed, never asserted.
"""

import argparse
import os
import statistics
import time

from common import (
    alternate, BENCH_DIR, init_ros, local_date, machine_info, make_sim_node, outputs_off,
    process_cpu_s, process_tree_cpu_s, raw_stepper, take_every_topic, TopicTaker, write_json)

RESULTS_PATH = os.path.join(BENCH_DIR, 'fleet.json')
# A robot's topics with the default outputs: joint_states, odom, ground_truth, scan, imu.
TAKEN_TOPICS_PER_ROBOT = 5
SPACING_M = 2.0
THROUGHPUT_ROBOTS = (1, 2, 4, 8, 16)
STEP_BUDGET_US = 1e6 / 240.0  # a step's share of one core at 240 Hz
REAL_TIME_ROBOTS = (1, 2, 4, 8, 12, 16, 24, 28)  # a world holds at most 29 with a laser
# The same with every topic taken (the outputs build only what someone takes).
REAL_TIME_ROBOTS_TAKEN = (1, 8, 12, 16)
KEEPS_REAL_TIME_HZ = 239.0  # the lowest one-second window's rate
DRIVE = (0.3, 0.6)  # m/s, rad/s: a circle of 0.5 m
RAY_THREADS_ROBOTS = 16  # scans on one thread against two, in turns, at this many


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
            # Every message taken by a subscription in this process (the outputs build
            # only what someone takes), and the default outputs with nobody subscribed.
            for config, extra, taken in (('state', outputs_off(), True), ('defaults', {}, True),
                                         ('untaken', {}, False)):
                node = make_sim_node(context, f'/fleet_{config}_{count}',
                                     dict(fleet(count), real_time_factor=0.0, **extra))
                nodes.append(node)
                taker = take_every_topic(context, [node]) if taken else None
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
                if taker is not None:
                    taker.destroy_node()
                node.destroy_node()
                nodes.remove(node)
    finally:
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=context)
    return results


def window_rates(arrivals, start, window_s, windows):
    """
    Return the rate (Hz of physics steps) of each back-to-back window from ``start`` on.

    ``arrivals`` are (wall s, stamp ns) of ``/clock`` messages as they came: a
    window runs from the first message at or after its start to the first at
    or after its end, and its rate is the simulated time between the two over
    the wall time between them, times 240.
    """
    def first_from(t):
        found = next((a for a in arrivals if a[0] >= t), None)
        if found is None:
            raise RuntimeError(f'no /clock message came after {t - start:.1f} s')
        return found
    rates = []
    for k in range(windows):
        begin, end = first_from(start + k * window_s), first_from(start + (k + 1) * window_s)
        if end is begin:
            raise RuntimeError(f'no /clock message in window {k + 1} ({window_s:g} s)')
        rates.append((end[1] - begin[1]) * 1e-9 / (end[0] - begin[0]) * 240.0)
    return rates


def measure_real_time(domain_id, counts, settle_s, window_s, windows, driving=False,
                      parameters=None, taken=False):
    """
    Achieved rate and CPU share of sim_node at rtf 1 with N robots and the default outputs.

    ``windows`` back-to-back windows of ``window_s`` per N, timed by the
    ``/clock`` messages as they arrive here (a reply's delay would tilt a
    window timed by ``~/get_status``); N keeps real time if its lowest
    reached KEEPS_REAL_TIME_HZ; the rate and CPU reported are their medians.
    ``~/get_status`` is asked once a window, and its longest answer kept.
    ``driving``: every robot drives a circle from the start (one command
    each, no timeout). ``parameters``: more of sim_node's. ``taken``: a
    :class:`~common.TopicTaker` takes every topic (else only ``/clock`` is
    taken, and the robots' outputs are not built).
    """
    from clock_gaps import ClockListener
    from r2d2_sim.testing import SimProcess
    results = {}
    for count in counts:
        extra = {'cmd_vel_timeout': 0.0} if driving else {}
        extra.update(parameters or {})
        sim = SimProcess(domain_id=domain_id, state_subscriptions=False, timeout_s=60.0,
                         **fleet(count), **extra)
        listener = ClockListener(domain_id)
        taker = TopicTaker(domain_id) if taken else None
        # CPU of a core (the simulator's process; with its children); how long each
        # ~/get_status took (s).
        shares, tree_shares, answers = [], [], []

        def status():
            asked = time.monotonic()
            reply = sim.status()
            answers.append(time.monotonic() - asked)
            return reply
        try:
            pid = sim.process.process.pid
            listener.wait_clock()
            if taker is not None:
                taker.wait(TAKEN_TOPICS_PER_ROBOT * count + 2)  # and /tf, /clock
            if driving:
                for name in sim.status()['robots']:
                    sim.robot(name).send_cmd_vel(*DRIVE)
            time.sleep(settle_s)
            start, cpu_before = time.monotonic(), process_cpu_s(pid)
            tree_before = process_tree_cpu_s(pid)
            read_before = start
            for k in range(windows):
                time.sleep(max(0.0, start + (k + 1) * window_s - time.monotonic()))
                status()
                cpu_after, read_after = process_cpu_s(pid), time.monotonic()
                tree_after = process_tree_cpu_s(pid)
                shares.append((cpu_after - cpu_before) / (read_after - read_before))
                tree_shares.append((tree_after - tree_before) / (read_after - read_before))
                cpu_before, read_before, tree_before = cpu_after, read_after, tree_after
            time.sleep(0.2)  # the message that ends the last window
            rates = window_rates(listener.since(start), start, window_s, windows)
        finally:
            listener.close()
            if taker is not None:
                taker.close()
            sim.stop()
        results[str(count)] = {'robots': count, 'driving': driving, 'taken': taken,
                               'rate_hz': statistics.median(rates), 'rates_hz': rates,
                               'lowest_hz': min(rates),
                               'status_answer_ms_max': max(answers) * 1e3,
                               'cpu_share': statistics.median(shares), 'cpu_shares': shares,
                               'cpu_share_with_children': statistics.median(tree_shares),
                               'keeps_real_time': min(rates) >= KEEPS_REAL_TIME_HZ}
    return results


def measure_ray_threads(domain_id, count, rounds, settle_s, window_s, windows):
    """
    ``count`` robots driving at rtf 1: scans on one thread against auto (two), in turns.

    The same measurement as the real-time rows, ``ray_threads`` 1 (every
    scan cast on the physics thread, as before the parameter) and 0 (auto:
    two threads on two cores), alternating ``rounds`` times: each one's
    lowest window and CPU share per round.
    """
    results = {'robots': count, 'one_thread': [], 'auto': []}
    for _ in range(rounds):
        for key, threads in (('one_thread', 1), ('auto', 0)):
            entry = measure_real_time(domain_id, [count], settle_s, window_s, windows,
                                      driving=True, parameters={'ray_threads': threads})
            entry = entry[str(count)]
            results[key].append({'lowest_hz': entry['lowest_hz'], 'rate_hz': entry['rate_hz'],
                                 'cpu_share': entry['cpu_share']})
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
    for key, title in (('real_time', 'standing'), ('real_time_driving', 'driving'),
                       ('real_time_driving_taken', 'driving, every topic taken')):
        if key not in results:
            continue
        print(f'\n{"robots":>6} | {title + ": rate at rtf 1 (Hz), lowest 1 s":>40} | '
              f'{"CPU of a core":>13} | get_status, longest | keeps 240 Hz')
        for entry in results[key].values():
            keeps = 'yes' if entry['keeps_real_time'] else 'no'
            rates = f'{entry["rate_hz"]:.2f}, {entry["lowest_hz"]:.2f}'
            print(f'{entry["robots"]:>6} | {rates:>40} | {entry["cpu_share"] * 100:>12.1f}% | '
                  f'{entry["status_answer_ms_max"]:>16.1f} ms | {keeps}')
    threads = results.get('ray_threads')
    if threads:
        print(f'\n{threads["robots"]} robots driving, in turns: lowest 1 s window (Hz), CPU of '
              'a core')
        for key, title in (('one_thread', 'ray_threads 1'), ('auto', 'ray_threads auto (2)')):
            rounds = ', '.join(f'{r["lowest_hz"]:.1f} ({r["cpu_share"] * 100:.0f}%)'
                               for r in threads[key])
            print(f'{title:>22}: {rounds}')


def main(argv=None):
    """Run the fleet bench; print and save the results."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='fewer and shorter windows')
    parser.add_argument('--domain', type=int, default=80, help='ROS domain id to run on')
    parser.add_argument('--output', default=RESULTS_PATH, help='where to write the results')
    args = parser.parse_args(argv)
    rounds, min_s = (2, 0.5) if args.quick else (5, 1.0)
    settle_s, window_s, windows = (1.0, 1.0, 4) if args.quick else (2.0, 1.0, 10)
    results = {'machine': machine_info(), 'date': local_date(), 'quick': args.quick,
               'throughput': measure_throughput(args.domain, THROUGHPUT_ROBOTS, rounds, min_s),
               'real_time': measure_real_time(args.domain + 1, REAL_TIME_ROBOTS, settle_s,
                                              window_s, windows),
               'real_time_driving': measure_real_time(args.domain + 1, REAL_TIME_ROBOTS,
                                                      settle_s, window_s, windows,
                                                      driving=True),
               'real_time_driving_taken': measure_real_time(
                   args.domain + 1, REAL_TIME_ROBOTS_TAKEN, settle_s, window_s, windows,
                   driving=True, taken=True),
               'ray_threads': measure_ray_threads(args.domain + 1, RAY_THREADS_ROBOTS,
                                                  2 if args.quick else 3, settle_s, window_s,
                                                  windows)}
    write_json(args.output, results)
    print_table(results)
    print(f'\nwritten to {args.output}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
