#!/usr/bin/env python3
"""
Where the node's every-step overhead goes: in-process SimNode.advance at rtf 0.

Run from the repository root::

    .venv/bin/python bench/profile_step.py [--steps 3000] [--domain 95]

1. A breakdown timed inside ``advance``: each bridge function of node.py and
   world.py and each publisher is wrapped with a timer (inclusive and
   exclusive microseconds per step), no profiler attached.
2. The cProfile top list (tottime and cumtime per step; cProfile inflates
   Python-heavy functions, so read it for ranking, the breakdown for sizes).
3. Prototypes of edits not (yet) made, applied to in-process nodes by
   monkeypatching (nothing in r2d2_sim/ is changed), each timed against an
   unpatched node in interleaved rounds: the expected gain per edit. The
   earlier prototypes (bound PyBullet calls, integer publish schedule, one
   base-state and one joint-state read per publication) are now in the node.

Writes everything to ``bench/profile.json``.
"""

import argparse
import cProfile
import functools
import json
import math
import os
import pstats
import statistics
import sys
import time

BENCH_DIR = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(BENCH_DIR)
if REPO not in sys.path:
    sys.path.insert(0, REPO)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from r2d2_sim.stdio import silenced_stdout  # noqa: E402 (after the sys.path set-up)


PROFILE_PATH = os.path.join(BENCH_DIR, 'profile.json')


# -- 1. breakdown ----------------------------------------------------------------------

class Timers:
    """Nested wall-clock timers: inclusive and exclusive time and calls per label."""

    def __init__(self):
        self.inclusive, self.exclusive, self.calls = {}, {}, {}
        self._stack = []

    def wrap(self, label, function):
        """Return ``function`` wrapped to time each call under ``label``."""
        perf_counter, stack = time.perf_counter, self._stack

        @functools.wraps(function)
        def timed(*args, **kwargs):
            stack.append(0.0)                 # time spent in timed callees
            begin = perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                spent = perf_counter() - begin
                children = stack.pop()
                if stack:
                    stack[-1] += spent
                self.inclusive[label] = self.inclusive.get(label, 0.0) + spent
                self.exclusive[label] = self.exclusive.get(label, 0.0) + spent - children
                self.calls[label] = self.calls.get(label, 0) + 1
        return timed


def instrument(node, timers):
    """Wrap the bridge's functions on this node instance (and its world) with timers."""
    import r2d2_sim.node as node_module
    world = node.world
    for label, owner, name in (
            ('SimNode.advance (whole step loop)', node, 'advance'),
            ('SimWorld.step (physics)', world, 'step'),
            ('SimNode._update_command', node, '_update_command'),
            ('SimNode._checked_state (excl. queries)', node, '_checked_state'),
            ('SimWorld.state_problem', world, 'state_problem'),
            ('SimNode._publish_state (message filling)', node, '_publish_state'),
            ('SimWorld.joint_states (getJointStates + dataclass)', world, 'joint_states'),
            ('SimWorld.base_state (4 queries + dataclass)', world, 'base_state'),
            ('SimNode._update_odometry', node, '_update_odometry'),
            ('DiffDriveOdometry.update_from_positions', node.odometry, 'update_from_positions')):
        setattr(owner, name, timers.wrap(label, getattr(owner, name)))
    for label, publisher in (('publish /clock', node._clock_pub),
                             ('publish joint_states', node._joint_pub),
                             ('publish ground_truth', node._truth_pub),
                             ('publish odom', node._odom_pub)):
        publisher.publish = timers.wrap(label, publisher.publish)
    node_module.yaw_to_quaternion = timers.wrap('yaw_to_quaternion',
                                                node_module.yaw_to_quaternion)


def breakdown(context, steps):
    """Time each bridge function inside advance(steps); return rows sorted by exclusive time."""
    import r2d2_sim.node as node_module
    original_yaw = node_module.yaw_to_quaternion
    node = make_node(context, 'breakdown')
    try:
        node.advance(240)
        timers = Timers()
        instrument(node, timers)
        node.advance(steps)
        raw_us = per_step_us(node.world.client.stepSimulation, steps)
    finally:
        node_module.yaw_to_quaternion = original_yaw
        node.destroy_node()
    rows = [{'function': label, 'calls_per_step': timers.calls[label] / steps,
             'inclusive_us': 1e6 * timers.inclusive[label] / steps,
             'exclusive_us': 1e6 * timers.exclusive[label] / steps}
            for label in timers.inclusive]
    rows.sort(key=lambda row: -row['exclusive_us'])
    return {'rows': rows, 'raw_step_us': raw_us,
            'advance_us': 1e6 * timers.inclusive['SimNode.advance (whole step loop)'] / steps}


def per_step_us(step, steps):
    """Return the CPU microseconds per call of ``step()`` over ``steps`` calls."""
    begin = time.thread_time()
    for _ in range(steps):
        step()
    return 1e6 * (time.thread_time() - begin) / steps


# -- 2. cProfile ---------------------------------------------------------------------------

def cprofile_top(context, steps, top):
    """Run advance(steps) under cProfile; return the top functions by tottime, per step."""
    node = make_node(context, 'cprofile')
    try:
        node.advance(240)
        profiler = cProfile.Profile()
        profiler.enable()
        node.advance(steps)
        profiler.disable()
    finally:
        node.destroy_node()
    stats = pstats.Stats(profiler).stats
    rows = []
    for (path, line, name), (_, calls, tottime, cumtime, _) in stats.items():
        where = f'{os.path.basename(path)}:{line}({name})' if line else name
        rows.append({'function': where, 'calls_per_step': calls / steps,
                     'tottime_us': 1e6 * tottime / steps, 'cumtime_us': 1e6 * cumtime / steps})
    rows.sort(key=lambda row: -row['tottime_us'])
    return rows[:top]


# -- 3. prototypes of the recommended edits ------------------------------------------------

def patch_no_ground_truth(node):
    """Skip the ground_truth publication (e.g. while it has no subscriber)."""
    node._truth_pub.publish = lambda msg: None


PATCHES = (
    ('ground_truth not published', (patch_no_ground_truth,)),
)


def prototypes(context, rounds, steps):
    """
    Time the bridge of an unpatched node and of each patched one, interleaved; medians.

    Physics cost differs a little from one world to the next, so each node's
    bridge cost is its advance() time minus raw stepping of its own world,
    both measured in the same round.
    """
    variants = [('unpatched node', ())] + list(PATCHES)
    nodes = []
    try:
        for index, (label, patches) in enumerate(variants):
            node = make_node(context, f'proto{index}')
            for patch in patches:
                patch(node)
            nodes.append((label, node))
        for _, node in nodes:
            node.advance(240)
        advance_us = {label: [] for label, _ in nodes}
        raw_us = {label: [] for label, _ in nodes}
        for _ in range(rounds):
            for label, node in nodes:
                begin = time.thread_time()
                node.advance(steps)
                middle = time.thread_time()
                node.world.step(steps)
                advance_us[label].append(1e6 * (middle - begin) / steps)
                raw_us[label].append(1e6 * (time.thread_time() - middle) / steps)
    finally:
        for _, node in nodes:
            node.destroy_node()
    rows = []
    for label, _ in nodes:
        advance, raw = statistics.median(advance_us[label]), statistics.median(raw_us[label])
        bridge = statistics.median(a - r for a, r in zip(advance_us[label], raw_us[label]))
        rows.append({'variant': label, 'us_per_step': advance, 'raw_us_per_step': raw,
                     'bridge_us': bridge, 'ratio_to_raw': raw / advance})
    base = rows[0]['bridge_us']
    for row in rows:
        row['saved_us'] = base - row['bridge_us'] if row is not rows[0] else math.nan
    return rows


# -- driver --------------------------------------------------------------------------------

def make_node(context, name):
    """Build an every-step SimNode at rtf 0 in ``context`` under ``/profile_<name>``."""
    from rclpy.parameter import Parameter
    with silenced_stdout():
        from r2d2_sim.node import SimNode
        return SimNode(context=context, namespace=f'/profile_{name}', parameter_overrides=[
            Parameter('real_time_factor', value=0.0)])


def main(argv=None):
    """Run the breakdown, cProfile and the prototypes; print them and write profile.json."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--steps', type=int, default=3000, help='steps per measurement')
    parser.add_argument('--rounds', type=int, default=15, help='interleaved prototype rounds')
    parser.add_argument('--domain', type=int, default=95, help='ROS domain id (default 95)')
    parser.add_argument('--top', type=int, default=20, help='cProfile rows to show')
    parser.add_argument('--output', default=PROFILE_PATH, help='where to write the JSON')
    args = parser.parse_args(argv)

    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions
    context = Context()
    rclpy.init(context=context, domain_id=args.domain,
               signal_handler_options=SignalHandlerOptions.NO)
    try:
        parts = breakdown(context, args.steps)
        top = cprofile_top(context, args.steps, args.top)
        proto = prototypes(context, args.rounds, max(args.steps // 3, 240))
    finally:
        rclpy.try_shutdown(context=context)

    print(f'1. Breakdown inside SimNode.advance, every step, rtf 0 ({args.steps} steps, '
          'wall time, timer wrappers add ~0.3 us per call to the caller\'s exclusive time)')
    print(f'   advance: {parts["advance_us"]:.1f} us/step; raw stepSimulation '
          f'{parts["raw_step_us"]:.1f} us/step')
    print(f'   {"exclusive us":>12} {"inclusive us":>12} {"calls":>6}  function')
    for row in parts['rows']:
        print(f'   {row["exclusive_us"]:12.1f} {row["inclusive_us"]:12.1f} '
              f'{row["calls_per_step"]:6.1f}  {row["function"]}')
    print(f'\n2. cProfile top {args.top} by tottime (us per step)')
    print(f'   {"tottime":>8} {"cumtime":>8} {"calls":>6}  function')
    for row in top:
        print(f'   {row["tottime_us"]:8.1f} {row["cumtime_us"]:8.1f} '
              f'{row["calls_per_step"]:6.1f}  {row["function"]}')
    print(f'\n3. Prototyped edits (monkeypatched, CPU time, median of {args.rounds} '
          'interleaved rounds)')
    print(f'   {"node us":>8} {"raw us":>7} {"bridge":>7} {"saved":>7} {"ratio":>6}  variant')
    for row in proto:
        saved = '' if math.isnan(row['saved_us']) else f'{row["saved_us"]:7.1f}'
        print(f'   {row["us_per_step"]:8.1f} {row["raw_us_per_step"]:7.1f} '
              f'{row["bridge_us"]:7.1f} {saved:>7} {row["ratio_to_raw"]:6.3f}  {row["variant"]}')
    with open(args.output, 'w', encoding='utf-8') as out:
        json.dump({'steps': args.steps, 'breakdown': parts, 'cprofile_top': top,
                   'prototypes': proto}, out, indent=1)
    print(f'\nwrote {args.output}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
