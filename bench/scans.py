#!/usr/bin/env python3
"""
What a laser scan costs per robot with 1-16 robots in one world, one code tree against another.

    .venv/bin/python bench/scans.py [--before TREE] [--rounds 3]

N robots (1, 2, 4, 8, 16) stand in a row 2 m apart (as ``fleet.py``) with the
default outputs, in the ROS-free core (no node, no executor). Per N:

- **scan step**: every robot's 360-beam scan of one step, as the simulation
  casts them (the code of the tree: each scan on its own before, every
  robot's rays collected and cast together after), divided by N;
- **one robot's own call**: ``LaserScanner.scan()`` of each robot alone;
- **core step**: ``Simulation.step`` with the default outputs (state every
  step, scan 10 Hz, IMU 100 Hz) minus raw ``stepSimulation`` of the same
  world, per robot (thread CPU time, the best of three 240-step windows).

Then the same for 16 robots 30 m apart (``16 spread``), out of each other's
reach: what a scan costs without other robots in its way.

With ``--before TREE`` (a checkout of another commit: ``git archive COMMIT |
tar -x -C TREE``) each round runs that tree and this one in turn, each in a
fresh interpreter, so both see the same load from other processes. Prints a
table and writes ``bench/scans.json``. Numbers are printed, never asserted.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
RESULTS_PATH = os.path.join(HERE, 'scans.json')
COUNTS = ('1', '2', '4', '8', '16', '16 spread')
SPACING_M = {'spread': 30.0}


def fleet(count):
    """Return the parameters of ``count`` robots in a row along y, all facing +x."""
    number, _, layout = count.partition(' ')
    number = int(number)
    if number == 1:
        return {}
    names = [f'r{i}' for i in range(number)]
    params = {'robots': names}
    for i, name in enumerate(names):
        params[f'{name}.initial_pose'] = [0.0, SPACING_M.get(layout, 2.0) * i, 0.0]
    return params


def best_us(function, repeats, windows=3):
    """Return the best per-call thread CPU time of ``function`` over ``windows`` windows, us."""
    best = float('inf')
    for _ in range(windows):
        begin = time.thread_time()
        for _ in range(repeats):
            function()
        best = min(best, (time.thread_time() - begin) / repeats)
    return best * 1e6


def scan_step(simulation):
    """Return a function making every robot's scan of one step as this tree's simulation does."""
    robots = simulation.robots
    world = simulation.world
    if not hasattr(robots[0], 'pending_rays'):  # before batching: a call per robot
        return lambda: [robot.laser.scan() for robot in robots]

    def batched():
        requests = [robot.laser.rays() for robot in robots]
        answers = world.cast_requests(requests)
        return [robot.laser.ranges(answer) for robot, answer in zip(robots, answers)]
    return batched


def measure_tree():
    """Measure this interpreter's r2d2_sim (the tree on sys.path); return results by N."""
    from r2d2_sim.sim.settings.robots import parse_world
    from r2d2_sim.sim.simulation import Simulation
    import pybullet
    results = {}
    for count in COUNTS:
        config, robots = parse_world(fleet(count))
        simulation = Simulation(config, robots)
        number = len(simulation.robots)
        try:
            for _ in range(240):  # the robots settle on their wheels
                simulation.step()
            step = scan_step(simulation)
            alone = [robot.laser.scan for robot in simulation.robots]
            client = simulation.world.client._client

            def raw(steps=240):
                for _ in range(steps):
                    pybullet.stepSimulation(physicsClientId=client)

            def core(steps=240):
                for _ in range(steps):
                    simulation.step()
            step()
            repeats = max(3, 48 // number)
            raw_us = best_us(raw, 1)
            results[count] = {
                'scan_step_us_per_robot': best_us(step, repeats) / number,
                'own_call_us_per_robot': best_us(lambda: [scan() for scan in alone],
                                                 repeats) / number,
                'core_minus_raw_us_per_robot_step': (best_us(core, 1) - raw_us) / 240 / number,
                'raw_us_per_robot_step': raw_us / 240 / number,
            }
        finally:
            simulation.close()
    return results


def run_tree(tree):
    """Run the measurement in a fresh interpreter on ``tree``; return its results."""
    env = dict(os.environ, PYTHONPATH=tree)
    output = subprocess.run([sys.executable, os.path.abspath(__file__), '--measure'],
                            cwd=tree, env=env, capture_output=True, text=True, timeout=600)
    if output.returncode != 0:
        raise SystemExit(f'scans.py: the measurement on {tree} failed:\n{output.stderr[-2000:]}')
    return json.loads(output.stdout.splitlines()[-1])


def summary(rounds):
    """Return per N and measure: the best and the median over rounds."""
    table = {}
    for count in COUNTS:
        table[count] = {}
        for key in rounds[0][count]:
            values = [r[count][key] for r in rounds]
            table[count][key] = {'best': min(values), 'median': statistics.median(values),
                                 'rounds': values}
    return table


def main(argv=None):
    """Run the rounds; print and save the table."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--before', help='another checkout to measure in turns with this one')
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--measure', action='store_true', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.measure:
        from r2d2_sim.physics.stdio import silenced_output
        with silenced_output():
            results = measure_tree()
        print(json.dumps(results))
        return 0
    sys.path.insert(0, HERE)
    from common import local_date, machine_info, write_json
    trees = {'after': REPO}
    if args.before:
        trees = {'before': os.path.abspath(args.before), 'after': REPO}
    rounds = {name: [] for name in trees}
    load = []
    for _ in range(args.rounds):
        for name, tree in trees.items():
            rounds[name].append(run_tree(tree))
        load.append(os.getloadavg()[0])
    results = {'date': local_date(), 'machine': machine_info(), 'load_average': load,
               'trees': trees, 'summary': {name: summary(r) for name, r in rounds.items()}}
    write_json(RESULTS_PATH, results)
    print(f'\n{"robots":>9} | ' + ' | '.join(
        f'{name} scan/robot (own call), core-raw/robot/step' for name in trees))
    for count in COUNTS:
        cells = []
        for name in trees:
            row = results['summary'][name][count]
            cells.append(f'{row["scan_step_us_per_robot"]["best"]:7.0f} us '
                         f'({row["own_call_us_per_robot"]["best"]:5.0f}), '
                         f'{row["core_minus_raw_us_per_robot_step"]["best"]:5.1f} us')
        print(f'{count:>9} | ' + ' | '.join(cells))
    print(f'\nload average during the rounds: {", ".join(f"{v:.2f}" for v in load)}')
    print(f'written to {RESULTS_PATH}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
