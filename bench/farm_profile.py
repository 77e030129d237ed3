#!/usr/bin/env python3
"""
Where a farm variation's time goes: docs/farm.md's example, run after run, part by part.

    .venv/bin/python bench/farm_profile.py --label before|after [--seeds 0-9]

A farm worker runs variation after variation: a harness built, the boxes
spawned, the user's node added, the run advanced in lockstep until the goal
or 20 simulated seconds, the harness closed. This runs the seeds given that
way (``run_scenario``, as every executor's task does), twice:

1. **plain**: wall time and physics steps; steps per second against raw
   ``stepSimulation`` of the same worlds (``farm.py``'s raw measure);
2. **timed**: class methods wrapped with wall-clock timers (no profiler:
   cProfile inflates Python-heavy code), each part's exclusive time: the
   physics, the run watch (contacts, closest points), the laser's rays, the
   robot's readouts and the step's glue, the simulator's publishing
   (patching, serializing, publishing), the lockstep executor (polls, takes
   and deserialization), the user's node (its callbacks), the simulator's
   ``cmd_vel`` input, building and closing the harness, and the rest (timer
   overhead included). A passing run records nothing.

Writes ``bench/farm_profile.json`` under the label (``before`` / ``after``
the per-core work of issue 36) and prints the table bench/README.md shows.
"""

import argparse
import json
import os
import statistics
import time

from common import BENCH_DIR, background_load, local_date, machine_info, write_json
from farm import measure_raw
from profile_step import Patches, Timers, timer_overhead_us

PROFILE_PATH = os.path.join(BENCH_DIR, 'farm_profile.json')
SECONDS = 20.0
PARTS = [
    # (label, module, class, method)
    ('physics (stepSimulation)', 'r2d2_sim.physics.world', 'SimWorld', 'step'),
    ('run watch (contacts, closest points)', 'r2d2_sim.sim.oracles', 'RunWatch', 'observe'),
    ('the laser\'s rays', 'r2d2_sim.physics.world', 'SimWorld', 'cast_requests'),
    ('robot readouts, drive, step glue', 'r2d2_sim.sim.simulation', 'Simulation', 'step'),
    ('simulator publishing (patch, serialize, publish)', 'r2d2_sim.ros.node', 'SimNode',
     '_publish'),
    ('simulator cmd_vel input', 'r2d2_sim.ros.cmd_vel', 'CmdVelInput', 'on_twist'),
    ('lockstep executor (polls, takes, deserialization)', 'r2d2_sim.testing.executor',
     'RosHarness', '_run_until_idle'),
    ('harness build (simulator, boxes, adding the node)', 'r2d2_sim.testing.harness',
     'SimHarness', '__init__'),
    ('harness build (simulator, boxes, adding the node)', 'r2d2_sim.testing.world_verbs',
     'WorldVerbs', 'spawn'),
    ('harness build (simulator, boxes, adding the node)', 'r2d2_sim.testing.harness',
     'SimHarness', 'add_node'),
    ('harness close', 'r2d2_sim.testing.executor', 'RosHarness', 'close'),
]
USER_NODE = 'the user\'s node (its callbacks)'
REST = 'the rest (run glue, timers)'


def parse_seeds(text):
    """Return the seeds of "a-b" or "a,b,c"."""
    if '-' in text:
        first, last = (int(part) for part in text.split('-'))
        return list(range(first, last + 1))
    return [int(part) for part in text.split(',')]


def example_module():
    """Return docs/farm.md's example module (its GoalStopper, controller and space)."""
    import importlib.util
    from farm import EXAMPLE
    spec = importlib.util.spec_from_file_location('farm_example', EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run_all(module, seeds):
    """Run every seed as a farm worker does; return (wall s, physics steps, outcomes)."""
    from r2d2_sim.farm.run import run_scenario, safe
    steps, outcomes = 0, []
    started = time.perf_counter()
    for seed in seeds:
        outcome = run_scenario(module.SPACE.draw(seed), module.goal_stopper, seconds=SECONDS,
                               verdict=safe, parameters=module.PARAMETERS)
        steps += outcome.steps
        outcomes.append(outcome)
    return time.perf_counter() - started, steps, outcomes


def instrument(patches, module):
    """Wrap every part's method with a timer; the user's callbacks under one label."""
    import importlib
    for label, module_name, class_name, method in PARTS:
        owner = importlib.import_module(module_name)
        if class_name is not None:
            owner = getattr(owner, class_name, None)
        if owner is None or not hasattr(owner, method):
            patches.missing.append(label)
            continue
        patches.wrap(label, owner, method)
    for method in ('__init__', 'on_odom', 'on_scan', 'on_tick'):
        patches.wrap(USER_NODE, module.GoalStopper, method)


def main(argv=None):
    """Profile the farm's variations; save and print the breakdown."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--label', required=True, help='before or after')
    parser.add_argument('--seeds', default='0-9')
    args = parser.parse_args(argv)
    seeds = parse_seeds(args.seeds)
    module = example_module()
    quiet = background_load()
    run_all(module, seeds[:1])  # imports and first-time costs out of the way
    wall_s, steps, _ = run_all(module, seeds)
    raw = measure_raw(seeds)
    timers = Timers()
    patches = Patches(timers)
    instrument(patches, module)
    try:
        timed_wall_s, timed_steps, _ = run_all(module, seeds)
    finally:
        patches.restore()
    parts = {label: timers.exclusive.get(label, 0.0) for label, *_ in PARTS}
    parts[USER_NODE] = timers.exclusive.get(USER_NODE, 0.0)
    parts[REST] = timed_wall_s - sum(parts.values())
    raw_median = statistics.median(raw)
    rate = steps / wall_s
    result = {
        'date': local_date(), 'machine': machine_info(), 'background_load_before': quiet,
        'seeds': seeds, 'seconds': SECONDS, 'physics_steps': steps, 'wall_s': wall_s,
        'steps_per_s': rate, 'raw_steps_per_s': raw, 'raw_steps_per_s_median': raw_median,
        'ratio_to_raw': rate / raw_median, 'timed_wall_s': timed_wall_s,
        'timer_overhead_us': timer_overhead_us(), 'missing': patches.missing,
        'parts_s': parts, 'calls': {k: timers.calls.get(k, 0) for k in parts}}
    everything = {}
    if os.path.exists(PROFILE_PATH):
        with open(PROFILE_PATH, encoding='utf-8') as source:
            everything = json.load(source)
    everything[args.label] = result
    write_json(PROFILE_PATH, everything)
    print(f'{len(seeds)} variations, {steps:,} physics steps in {wall_s:.2f} s: '
          f'{rate:,.0f} steps/s; raw stepSimulation of the same worlds {raw_median:,.0f} '
          f'steps/s: {rate / raw_median:.2f} of raw (other processes: '
          f'{quiet["busy_cores"]:.2f} cores busy before)')
    print(f'\n| part ({args.label}) | s | % | us per physics step |\n|---|---|---|---|')
    for label, seconds in sorted(parts.items(), key=lambda item: -item[1]):
        print(f'| {label} | {seconds:.2f} | {100 * seconds / timed_wall_s:.1f} | '
              f'{1e6 * seconds / timed_steps:.1f} |')
    per_step = 1e6 * timed_wall_s / timed_steps
    print(f'| total (timed run) | {timed_wall_s:.2f} | 100 | {per_step:.1f} |')
    if patches.missing:
        print(f'not found (not timed): {", ".join(patches.missing)}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
