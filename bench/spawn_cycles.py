#!/usr/bin/env python3
"""
Spawn and delete a robot in a namespace, again and again: what it leaves behind.

    .venv/bin/python bench/spawn_cycles.py [--quick] [--cycles 300] [--domain 84]
        [--variants process,handles,harness,core,pybullet]

Each cycle spawns our R2D2 as a driven robot in a namespace of its own
(``/cycle_<i>``, a new one every cycle; ``--same-namespace`` keeps ``/cycle``)
and deletes it again. Five variants:

- **process**: ``sim_node`` in a process of its own (``SimProcess``, default
  parameters, running at real time), driven through the simulation standard's
  ``spawn_entity`` and ``delete_entity`` from this process, as a client of the
  standard would; RSS is the simulator process's (``/proc/PID/status`` VmRSS)
  and the times are each call's wall time here, reply included.
- **handles**: the same ``sim_node`` process through ``SimProcess``'s own
  ``spawn`` and ``delete_entity``, its state subscriptions on (its default): each
  robot gets its handle, which subscribes the robot's state topics and TF
  from the spawn on and stops at the delete. What a test that spawns and
  deletes robots costs the simulator (issue 39: a handle's TF listener
  outlived its robot, 44 kB a cycle and slower every cycle).
- **harness**: ``SimHarness`` in this process: ``spawn`` and ``delete_entity``
  through the core, one control period advanced in between; RSS is this
  process's.
- **core**: the same through ``Simulation.spawn`` and ``delete_entity`` with no
  ROS at all, two physics steps in between.
- **pybullet**: ``loadURDF`` (with a driven robot's flags) and ``removeBody``
  of the same URDF in a world of its own, one step in between: PyBullet's own
  share, which nothing above it can give back.

Printed at cycles 1, 50, 100... N: RSS and the spawn and delete times (medians
of the 10 cycles up to there). Then the slope of RSS against the cycle (a line
through every cycle after the first 10 %, and one through the second half, where
the warm-up is over) and the ratio of late to early cycle
times (medians of the last 10 % of cycles over those of the first 10 %, cycle 1
left out), and the slope of a line through the medians of 10 cycles at a time over
the same cycles as RSS's (ms per 100 cycles; steadier than the ratio when other
processes load the machine in bursts). A leak shows as an RSS slope of tens of kB per
cycle, a slowdown as a time slope of a few ms per 100 cycles and a ratio well above 1.
Needs simulation_interfaces for the process variant.

Each variant runs in a fresh process of its own, so memory one of them freed
cannot hide another's growth. Writes ``bench/spawn_cycles.json``. Numbers are
printed, never asserted.
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

from common import (
    BENCH_DIR, fit_line, LoadMeter, local_date, machine_info, read_json, REPO, write_json)

RESULTS_PATH = os.path.join(BENCH_DIR, 'spawn_cycles.json')
URDF = 'package://r2d2_sim/urdf/r2d2.urdf'
POSITION = (0.0, 2.0, 0.48)  # beside the default robot, R2D2's base link above the ground
WINDOW = 10                   # cycles per printed median
VARIANTS = ('process', 'handles', 'harness', 'core', 'pybullet')


def rss_mb(pid):
    """Return the resident set size (MB) of process ``pid`` from /proc/<pid>/status."""
    with open(f'/proc/{pid}/status', encoding='utf-8') as status:
        for line in status:
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024.0
    raise RuntimeError(f'no VmRSS for process {pid}')


def namespace_of(cycle, same):
    """Return the namespace (and entity name) of a cycle's robot."""
    return 'cycle' if same else f'cycle_{cycle}'


def run_cycles(spawn, delete, rss, cycles, same):
    """Run ``cycles`` spawn/delete cycles; return per-cycle RSS (MB) and times (ms)."""
    samples = {'rss_mb': [], 'spawn_ms': [], 'delete_ms': []}
    for cycle in range(1, cycles + 1):
        name = namespace_of(cycle, same)
        start = time.perf_counter()
        spawn(name)
        spawned = time.perf_counter()
        delete(name)
        deleted = time.perf_counter()
        samples['spawn_ms'].append(1e3 * (spawned - start))
        samples['delete_ms'].append(1e3 * (deleted - spawned))
        samples['rss_mb'].append(rss())
    return samples


def measure_process(domain_id, cycles, same):
    """Run the cycles through the standard's services of a sim_node process."""
    from r2d2_sim.testing import SimProcess
    with SimProcess(domain_id=domain_id, state_subscriptions=False, timeout_s=60.0) as sim:
        standard = sim.standard
        pid = sim.process.process.pid

        def spawn(name):
            standard.spawn(uri=URDF, name=name, position=POSITION, allow_renaming=False,
                           namespace='/' + name)
        return run_cycles(spawn, standard.delete, lambda: rss_mb(pid), cycles, same)


def measure_handles(domain_id, cycles, same):
    """Run the cycles through SimProcess's own spawn and delete, a handle for each robot."""
    from r2d2_sim.testing import SimProcess
    with SimProcess(domain_id=domain_id, timeout_s=60.0) as sim:
        pid = sim.process.process.pid

        def spawn(name):
            sim.spawn(URDF, name=name, position=POSITION, allow_renaming=False,
                      namespace='/' + name)
        return run_cycles(spawn, sim.delete_entity, lambda: rss_mb(pid), cycles, same)


def measure_harness(domain_id, cycles, same):
    """Run the cycles through the core of a SimHarness in this process."""
    from r2d2_sim.testing import SimHarness
    with SimHarness(domain_id=domain_id) as sim:
        pid = os.getpid()

        def spawn(name):
            sim.spawn(URDF, name=name, position=POSITION, namespace='/' + name)
            sim.advance()  # one control period: the robot publishes once
        return run_cycles(spawn, sim.delete_entity, lambda: rss_mb(pid), cycles, same)


def measure_core(domain_id, cycles, same):
    """Run the cycles through the simulation core alone, no ROS (``domain_id`` unused)."""
    from r2d2_sim.sim.settings.robots import parse_world
    from r2d2_sim.sim.simulation import Simulation, SpawnRequest
    config, robots = parse_world({})
    simulation = Simulation(config, robots)
    pid = os.getpid()
    try:
        def spawn(name):
            simulation.spawn(SpawnRequest(name, uri=URDF, namespace='/' + name,
                                          position=POSITION))
            simulation.step()
            simulation.step()
        return run_cycles(spawn, simulation.delete_entity, lambda: rss_mb(pid), cycles, same)
    finally:
        simulation.close()


def measure_pybullet(domain_id, cycles, same):
    """Run loadURDF/removeBody of our R2D2 with a robot's flags, raw (``domain_id`` unused)."""
    from r2d2_sim.physics.description import resolve_description_path
    from r2d2_sim.physics.world import SimWorld
    world = SimWorld()
    client, path, bodies = world.client, resolve_description_path(URDF), {}
    pid = os.getpid()
    try:
        def spawn(name):
            bodies[name] = client.loadURDF(path, POSITION, flags=world.robot_flags)
            client.stepSimulation()

        def delete(name):
            client.removeBody(bodies.pop(name))
        return run_cycles(spawn, delete, lambda: rss_mb(pid), cycles, same)
    finally:
        world.close()


def summarise(samples):
    """Return the RSS slope (kB per cycle) and the late/early ratios of the cycle times."""
    cycles = len(samples['rss_mb'])
    tenth = max(1, cycles // 10)
    xs = list(range(tenth + 1, cycles + 1))
    _, slope_mb = fit_line(xs, samples['rss_mb'][tenth:])
    half = cycles // 2
    _, late_slope_mb = fit_line(list(range(half + 1, cycles + 1)), samples['rss_mb'][half:])
    summary = {'cycles': cycles, 'rss_first_mb': samples['rss_mb'][0],
               'rss_last_mb': samples['rss_mb'][-1],
               'rss_slope_kb_per_cycle': slope_mb * 1024.0,
               'rss_late_slope_kb_per_cycle': late_slope_mb * 1024.0}
    for key in ('spawn_ms', 'delete_ms'):
        early = statistics.median(samples[key][1:tenth + 1])
        late = statistics.median(samples[key][-tenth:])
        summary[key.replace('_ms', '_early_ms')] = early
        summary[key.replace('_ms', '_late_ms')] = late
        summary[key.replace('_ms', '_ratio')] = late / early
        summary[key.replace('_ms', '_slope_ms_per_100')] = time_slope(samples[key], tenth)
    return summary


def time_slope(times, first):
    """
    Return the slope (ms per 100 cycles) of a line through the medians of ``WINDOW`` cycles.

    From cycle ``first`` on. A burst of load from other processes slows a few
    cycles by tens of ms; the windows' medians leave those out, where a line
    through every cycle (or the ratio of two windows) swings with them.
    """
    medians, centres = [], []
    for start in range(first, len(times) - WINDOW + 1, WINDOW):
        medians.append(statistics.median(times[start:start + WINDOW]))
        centres.append(start + WINDOW / 2.0)
    return 100.0 * fit_line(centres, medians)[1]


def checkpoints(cycles):
    """Return the cycles a table row is printed at: 1, 50, 100... and the last."""
    return sorted({1, cycles} | set(range(50, cycles + 1, 50)))


def print_variant(name, result):
    """Print one variant's rows and its summary."""
    samples, summary = result['samples'], result['summary']
    print(f'\n{name}: {summary["cycles"]} cycles, {result["load"]["busy_cores"]:.2f} of the '
          'machine\'s cores busy meanwhile (the variant\'s own processes included)')
    print(f'{"cycle":>6} | {"RSS (MB)":>9} | {"spawn (ms)":>10} | {"delete (ms)":>11}')
    for cycle in checkpoints(summary['cycles']):
        window = slice(max(0, cycle - WINDOW), cycle)
        print(f'{cycle:>6} | {samples["rss_mb"][cycle - 1]:>9.1f} | '
              f'{statistics.median(samples["spawn_ms"][window]):>10.1f} | '
              f'{statistics.median(samples["delete_ms"][window]):>11.1f}')
    print(f'RSS slope {summary["rss_slope_kb_per_cycle"]:.1f} kB/cycle '
          f'({summary["rss_first_mb"]:.1f} -> {summary["rss_last_mb"]:.1f} MB), '
          f'{summary["rss_late_slope_kb_per_cycle"]:.1f} over the second half; '
          f'late/early: spawn {summary["spawn_early_ms"]:.1f} -> '
          f'{summary["spawn_late_ms"]:.1f} ms ({summary["spawn_ratio"]:.2f}), delete '
          f'{summary["delete_early_ms"]:.1f} -> {summary["delete_late_ms"]:.1f} ms '
          f'({summary["delete_ratio"]:.2f}); time slope: spawn '
          f'{summary["spawn_slope_ms_per_100"]:+.2f}, delete '
          f'{summary["delete_slope_ms_per_100"]:+.2f} ms per 100 cycles')


def run_child(variant, domain_id, cycles, same, workdir):
    """Run one variant in a fresh process of its own; return its samples."""
    out = os.path.join(workdir, f'{variant}.json')
    log = os.path.join(workdir, f'{variant}.log')
    args = [sys.executable, os.path.abspath(__file__), '--child', variant, '--out', out,
            '--cycles', str(cycles), '--domain', str(domain_id)]
    args += ['--same-namespace'] if same else []
    with open(log, 'w', encoding='utf-8') as log_file:
        subprocess.run(args, cwd=REPO, stdout=log_file, stderr=subprocess.STDOUT, check=False)
    return read_json(out, log, f'the {variant} variant')


def main(argv=None):
    """Run the spawn/delete cycles; print and save the results."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='100 cycles instead of 300')
    parser.add_argument('--cycles', type=int, default=None, help='cycles per variant')
    parser.add_argument('--domain', type=int, default=84,
                        help='ROS domain id of the first variant (the next: +1 each)')
    parser.add_argument('--same-namespace', action='store_true',
                        help='spawn every robot in /cycle (default: a new namespace each)')
    parser.add_argument('--variants', default=','.join(VARIANTS),
                        help='comma-separated, of: ' + ', '.join(VARIANTS))
    parser.add_argument('--child', choices=VARIANTS, help=argparse.SUPPRESS)
    parser.add_argument('--out', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    cycles = args.cycles or (100 if args.quick else 300)
    if args.child:  # one variant, in this fresh process: its samples to --out
        measures = {'process': measure_process, 'handles': measure_handles,
                    'harness': measure_harness,
                    'core': measure_core, 'pybullet': measure_pybullet}
        write_json(args.out, measures[args.child](args.domain, cycles, args.same_namespace))
        return 0
    variants = [v for v in args.variants.split(',') if v]
    unknown = [v for v in variants if v not in VARIANTS]
    if cycles < 20 or unknown:
        parser.error(f'unknown variant {unknown[0]!r}' if unknown else 'at least 20 cycles')
    results = {'machine': machine_info(), 'date': local_date(), 'repo': REPO,
               'cycles': cycles, 'same_namespace': args.same_namespace, 'variants': {}}
    with tempfile.TemporaryDirectory(prefix='spawn_cycles_') as workdir:
        for i, variant in enumerate(variants):
            meter = LoadMeter().start()
            samples = run_child(variant, args.domain + i, cycles, args.same_namespace, workdir)
            result = {'samples': samples, 'summary': summarise(samples), 'load': meter.stop()}
            results['variants'][variant] = result
            print_variant(variant, result)
    write_json(RESULTS_PATH, results)
    print(f'\nwritten to {RESULTS_PATH}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
