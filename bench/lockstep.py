#!/usr/bin/env python3
"""
Tests at the speed of the physics: the harness against raw PyBullet, and a suite over cores.

    .venv/bin/python bench/lockstep.py [--quick]

- **Open loop**: the ``r2d2_sim`` fixture's harness (the node's default outputs,
  ``cmd_vel_timeout`` 0) driving at 0.3 m/s, ``advance`` with no node of the
  user's.
- **Closed loop**: the same with the README's 20 Hz P-controller added
  (``test/examples/test_closed_loop.py``), so ``advance`` runs in lockstep,
  publishing every step and at ``publish_rate`` 50.

Each harness and raw ``stepSimulation`` of its very own world take turns every
simulated second (``common.alternate``, wall clock), so both see the same
load; the ratio is the harness's share of the physics' speed.

- **Breakdown**: where a closed-loop period (every step) goes: ``SimNode.advance``
  (physics and the bridge) and the lockstep part (the controller's callbacks and
  the polls), timed around each; an empty poll; a typed take of an Odometry and
  of a Clock (what rclpy costs the controller's node per message).
- **Fixture**: wall time to build a ``SimHarness`` and to close it (median).
- **Suite**: ``bench/scenarios`` (16 closed-loop scenarios of 5 simulated
  seconds) under ``pytest -n 1`` and ``-n 2``, wall time of each run.

Prints a table and writes ``bench/lockstep.json``. Numbers are printed, never asserted.
"""

import argparse
import importlib.util
import os
import statistics
import subprocess
import sys
import time

from common import alternate, BENCH_DIR, local_date, machine_info, raw_stepper, REPO, write_json

RESULTS_PATH = os.path.join(BENCH_DIR, 'lockstep.json')
EXAMPLE = os.path.join(REPO, 'test', 'examples', 'test_closed_loop.py')
SCENARIOS = os.path.join(BENCH_DIR, 'scenarios')
CHUNK_STEPS = 240  # the harness and raw stepping take turns every simulated second
GOALS = {'open loop': 0.9, 'closed loop, every step': 0.5, 'closed loop, publish_rate 50': 0.8}


def controller_class():
    """Return the README's DriveToX node class, from the example file."""
    spec = importlib.util.spec_from_file_location('closed_loop_example', EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.DriveToX


def measure_harnesses(rounds, min_s):
    """Steps/s of each harness configuration against raw stepping of its world."""
    from r2d2_sim.testing import SimHarness
    drive_to_x = controller_class()
    configurations = {'open loop': ({}, False), 'closed loop, every step': ({}, True),
                      'closed loop, publish_rate 50': ({'publish_rate': 50.0}, True)}
    results = {}
    for name, (parameters, closed) in configurations.items():
        with SimHarness(cmd_vel_timeout=0.0, **parameters) as harness:
            if closed:  # far away: it drives all along, one command per 20 Hz tick
                harness.add_node(drive_to_x(goal_m=1000.0, context=harness.context))
            else:
                harness.send_cmd_vel(linear=0.3)
            advances = [lambda steps: harness.advance(steps=steps),
                        raw_stepper(harness.sim.world)]
            for advance in advances:
                advance(CHUNK_STEPS)
            samples = [alternate(advances, min_s, CHUNK_STEPS)[1] for _ in range(rounds)]
        ratios = [node / raw for node, raw in samples]
        results[name] = {'harness_steps_per_s': [s[0] for s in samples],
                         'raw_steps_per_s': [s[1] for s in samples], 'ratios': ratios,
                         'ratio_median': statistics.median(ratios), 'goal': GOALS[name],
                         'real_time_factor': statistics.median(s[0] for s in samples) / 240.0}
    return results


def measure_breakdown(periods):
    """Wall us per closed-loop period in advance and in lockstep; an empty poll; typed takes."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import serialize_message
    from rosgraph_msgs.msg import Clock
    from r2d2_sim.testing import SimHarness
    with SimHarness(cmd_vel_timeout=0.0) as harness:
        harness.add_node(controller_class()(goal_m=1000.0, context=harness.context))
        harness.advance(steps=CHUNK_STEPS)
        advance_s = lockstep_s = 0.0
        clock = time.perf_counter
        with harness._own_executor():
            for _ in range(periods):
                started = clock()
                harness.sim.advance(1)
                stepped = clock()
                harness._run_until_idle(10.0)
                advance_s += stepped - started
                lockstep_s += clock() - stepped
            started = clock()
            for _ in range(periods):
                harness._run_until_idle(10.0)
            empty_s = clock() - started
        takes = {}
        node = harness.create_node('take_probe', use_sim_time=False)
        for name, msg_type in (('Odometry', Odometry), ('Clock', Clock)):
            publisher = node.create_publisher(msg_type, f'/probe_{name}', 10)
            subscription = node.create_subscription(msg_type, f'/probe_{name}', _unused, 10)
            harness._wait(lambda: publisher.get_subscription_count() > 0, 'the probe matched')
            data, spent = serialize_message(msg_type()), 0.0
            for _ in range(periods):
                publisher.publish(data)
                started = clock()
                with subscription.handle:
                    subscription.handle.take_message(msg_type, False)
                spent += clock() - started
            takes[name] = spent / periods * 1e6
    return {'advance_us_per_period': advance_s / periods * 1e6,
            'lockstep_us_per_period': lockstep_s / periods * 1e6,
            'empty_poll_us': empty_s / periods * 1e6, 'typed_take_us': takes}


def _unused(msg):
    """Stand in as the probe's callback: its messages are taken by hand."""


def measure_fixture(count):
    """Wall seconds to build a SimHarness (the r2d2_sim fixture's) and to close it."""
    from r2d2_sim.testing import SimHarness
    builds, closes = [], []
    for _ in range(count):
        started = time.perf_counter()
        harness = SimHarness(cmd_vel_timeout=0.0)
        built = time.perf_counter()
        harness.close()
        closes.append(time.perf_counter() - built)
        builds.append(built - started)
    return {'build_s_median': statistics.median(builds),
            'close_s_median': statistics.median(closes), 'build_s': builds, 'close_s': closes}


def measure_suite(workers):
    """Wall seconds of ``pytest -n N bench/scenarios`` for each N."""
    results = {}
    for count in workers:
        started = time.perf_counter()
        run = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                              '-n', str(count), SCENARIOS], cwd=REPO, capture_output=True,
                             text=True)
        results[str(count)] = {'workers': count, 'wall_s': time.perf_counter() - started,
                               'passed': run.returncode == 0,
                               'summary': run.stdout.strip().splitlines()[-1:]}
    return results


def print_table(results):
    """Print the rows."""
    print(f'\n{"configuration":32} | {"harness steps/s":>15} | {"raw steps/s":>11} | '
          f'{"ratio (median)":>14} | goal')
    for name, entry in results['harnesses'].items():
        print(f'{name:32} | {statistics.median(entry["harness_steps_per_s"]):>15.0f} | '
              f'{statistics.median(entry["raw_steps_per_s"]):>11.0f} | '
              f'{entry["ratio_median"]:>14.3f} | >= {entry["goal"]}')
    split = results['breakdown']
    print(f'\nclosed loop, every step, per period: advance '
          f'{split["advance_us_per_period"]:.0f} us, lockstep '
          f'{split["lockstep_us_per_period"]:.0f} us; an empty poll '
          f'{split["empty_poll_us"]:.1f} us; typed take: Odometry '
          f'{split["typed_take_us"]["Odometry"]:.1f} us, Clock '
          f'{split["typed_take_us"]["Clock"]:.1f} us')
    fixture = results['fixture']
    print(f'\nfixture: build {fixture["build_s_median"] * 1e3:.0f} ms, '
          f'close {fixture["close_s_median"] * 1e3:.0f} ms (medians)')
    for entry in results['suite'].values():
        print(f'suite of 16 scenarios, pytest -n {entry["workers"]}: {entry["wall_s"]:.1f} s '
              f'({" ".join(entry["summary"])})')


def main(argv=None):
    """Run the lockstep bench; print and save the results."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='fewer and shorter windows')
    parser.add_argument('--domain', type=int, help='ignored: every harness leases a free domain '
                        '(accepted so that ./run.sh bench can pass the same arguments)')
    args = parser.parse_args(argv)
    rounds, min_s, builds = (2, 1.0, 3) if args.quick else (5, 2.0, 9)
    results = {'machine': machine_info(), 'date': local_date(), 'quick': args.quick,
               'harnesses': measure_harnesses(rounds, min_s),
               'breakdown': measure_breakdown(1200 if args.quick else 4800),
               'fixture': measure_fixture(builds),
               'suite': measure_suite((1, 2))}
    write_json(RESULTS_PATH, results)
    print_table(results)
    print(f'\nwritten to {RESULTS_PATH}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
