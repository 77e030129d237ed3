#!/usr/bin/env python3
"""
Where a step's microseconds go: in-process SimNode.advance at rtf 0, part by part.

Run from the repository root::

    .venv/bin/python bench/profile_step.py [--steps 3000] [--domain 95]

1. A breakdown timed inside ``advance``: the parts of a step (Simulation.step
   and .frame, the physics, the readouts, the blow-up checks, the drive
   controller's update and odometry, each output's publish with its patching
   and its rclpy publish) are wrapped with timers, no profiler attached;
   inclusive and exclusive microseconds per step. Run publishing every step
   (a publication round per step), at ``publish_rate`` 10 (nearly every step
   publishes nothing) and, when the node has sensor parameters, with the
   default outputs. Sensor outputs are off otherwise, as in ``run.py``.
2. The cProfile top list of the every-step node (cProfile inflates
   Python-heavy functions: read it for ranking, the breakdown for sizes).

An output's exclusive time is what its ``publish`` does besides the timed
calls: the patching glue of a state output, the ray casting or the IMU model
of a sensor output.

Writes everything to ``bench/profile.json``.
"""

import argparse
import cProfile
import functools
import os
import pstats
import sys
import time

from common import (
    BENCH_DIR, init_ros, local_date, machine_info, make_sim_node, missing_parameters, outputs_off,
    write_json)

PROFILE_PATH = os.path.join(BENCH_DIR, 'profile.json')
ADVANCE = 'SimNode.advance (the step loop)'
PHYSICS = 'SimWorld.step (physics)'
_INHERITED = object()  # an attribute found on the class, not on the wrapped object itself


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


def timer_overhead_us(calls=20000):
    """Return the microseconds one timed call adds to its caller's exclusive time."""
    timers = Timers()
    child = timers.wrap('child', lambda: None)

    def parent():
        for _ in range(calls):
            child()
    plain = time.perf_counter()
    for _ in range(calls):
        (lambda: None)()
    plain = time.perf_counter() - plain
    timers.wrap('parent', parent)()
    return 1e6 * (timers.exclusive['parent'] - plain) / calls


class Patches:
    """Attributes replaced by timed wrappers, put back by :meth:`restore`."""

    def __init__(self, timers):
        self.timers = timers
        self.missing = []
        self._saved = []

    def wrap(self, label, owner, name):
        """Time ``owner.name`` under ``label``; note it as missing if ``owner`` has none."""
        function = getattr(owner, name, None)
        if function is None:
            self.missing.append(label)
            return
        self._saved.append((owner, name, owner.__dict__.get(name, _INHERITED)))
        setattr(owner, name, self.timers.wrap(label, function))

    def restore(self):
        """Put every wrapped attribute back as it was."""
        for owner, name, original in reversed(self._saved):
            if original is _INHERITED:
                delattr(owner, name)
            else:
                setattr(owner, name, original)
        self._saved.clear()


def instrument(node, patches):
    """Wrap the parts of a step on this node, its simulation, world, robot and controller."""
    from r2d2_sim.ros import outputs
    from r2d2_sim.sim.robots import sensors as sensor_mounts
    from r2d2_sim.ros import sensor_outputs
    from r2d2_sim.ros import serialization
    from r2d2_sim.ros import tf_outputs
    simulation = node.simulation
    world, robot = simulation.world, simulation.robot
    body, controller = robot.body, robot.controller
    patches.wrap(ADVANCE, node, 'advance')
    patches.wrap('SimNode._publish (clock, then each robot\'s outputs)', node, '_publish')
    patches.wrap('Simulation.step (glue)', simulation, 'step')
    patches.wrap('Robot.measure (glue, what is due)', robot, 'measure')
    patches.wrap('Robot.read_frame (glue, Frame)', robot, 'read_frame')
    patches.wrap(PHYSICS, world, 'step')
    patches.wrap('Body.joint_states (read)', body, 'joint_states')
    patches.wrap('Body.base_state (read)', body, 'base_state')
    patches.wrap('Body.state_problem (blow-up check)', body, 'state_problem')
    patches.wrap('Body.joint_problem (blow-up check)', body, 'joint_problem')
    patches.wrap('Body.twist_problem (blow-up check)', body, 'twist_problem')
    if controller is not None:
        patches.wrap('DriveController.update (command -> wheels)', controller, 'update')
        patches.wrap('DriveController.update_odometry', controller, 'update_odometry')
    for name, method in (('LaserScanner', 'scan'), ('ImuSensor', 'read'),
                         ('HeadCamera', 'render')):
        patches.wrap(f'{name}.{method} (measure)', getattr(sensor_mounts, name), method)
    # Every output class, whichever the node has: class attributes, so also
    # outputs that hold a bound method would be timed.
    for module in (outputs, sensor_outputs, tf_outputs):
        for name, cls in sorted(vars(module).items()):
            if (isinstance(cls, type) and cls.__module__ == module.__name__
                    and callable(cls.__dict__.get('publish'))):
                patches.wrap(f'{name}.publish (outputs)', cls, 'publish')
    patches.wrap('MessageTemplate.to_bytes', serialization.MessageTemplate, 'to_bytes')
    patches.wrap('StampSlot.set', serialization.StampSlot, 'set')
    patches.wrap('FieldSlot.set', serialization.FieldSlot, 'set')
    for publisher in node.publishers:
        patches.wrap(f'rclpy publish {publisher.topic_name}', publisher, 'publish')


def per_step_us(step, steps):
    """Return the CPU microseconds per call of ``step()`` over ``steps`` calls."""
    begin = time.thread_time()
    for _ in range(steps):
        step()
    return 1e6 * (time.thread_time() - begin) / steps


def breakdown(context, name, params, steps):
    """Time each part of a step inside advance(steps); return rows sorted by exclusive time."""
    node = make_sim_node(context, f'/profile_{name}', dict(params, real_time_factor=0.0))
    timers = Timers()
    patches = Patches(timers)
    try:
        node.advance(240)
        schedule = node.simulation.publish_schedule
        rounds = schedule.count
        instrument(node, patches)
        node.advance(steps)
        patches.restore()
        rounds = schedule.count - rounds
        raw_us = per_step_us(node.world.client.stepSimulation, steps)
    finally:
        patches.restore()
        node.destroy_node()
    rows = [{'function': label, 'calls_per_step': timers.calls[label] / steps,
             'inclusive_us': 1e6 * timers.inclusive[label] / steps,
             'exclusive_us': 1e6 * timers.exclusive[label] / steps}
            for label in timers.inclusive]
    rows.sort(key=lambda row: -row['exclusive_us'])
    advance_us = 1e6 * timers.inclusive[ADVANCE] / steps
    physics_us = 1e6 * timers.inclusive[PHYSICS] / steps
    return {'params': params, 'rows': rows, 'missing': patches.missing,
            'raw_step_us': raw_us, 'advance_us': advance_us, 'physics_us': physics_us,
            'bridge_us': advance_us - physics_us, 'publication_rounds': rounds,
            'round': publication_round(rows, rounds / steps)}


def publication_round(rows, rounds_per_step):
    """
    Sum an every-step breakdown into the microseconds of one publication round, by part.

    Each output counts with its inclusive time (patching, to_bytes and rclpy
    publish); ``of which`` splits those three out over all outputs. Empty
    unless every step publishes (elsewhere a step's parts are not a round's).
    """
    if rounds_per_step != 1.0:
        return {}
    exclusive = {row['function']: row['exclusive_us'] for row in rows}
    inclusive = {row['function']: row['inclusive_us'] for row in rows}

    def total(table, predicate):
        return sum(us for label, us in table.items() if predicate(label))
    parts = {
        'read joints and base': total(exclusive, lambda f: f.endswith('(read)')),
        'blow-up checks': total(exclusive, lambda f: 'blow-up' in f),
        'odometry': total(exclusive, lambda f: f.startswith('DriveController.update_odometry')),
        'reading glue (Robot.measure, read_frame)': total(
            exclusive, lambda f: f.startswith(('Robot.measure', 'Robot.read_frame'))),
        'publishing glue (SimNode._publish, RobotOutputs)': total(
            exclusive, lambda f: f.startswith(('SimNode._publish', 'RobotOutputs.publish'))),
    }
    # Each output with its inclusive time; RobotOutputs only dispatches (its own time above).
    parts.update((label.split('.')[0], us) for label, us in inclusive.items()
                 if label.endswith('.publish (outputs)') and not label.startswith('RobotOutputs'))
    parts['total'] = sum(parts.values())
    parts['of which: rclpy publish'] = total(exclusive, lambda f: f.startswith('rclpy publish'))
    parts['of which: MessageTemplate.to_bytes'] = exclusive.get('MessageTemplate.to_bytes', 0.0)
    parts['of which: slot sets'] = total(exclusive, lambda f: f.endswith('Slot.set'))
    return parts


def cprofile_top(context, params, steps, top):
    """Run advance(steps) under cProfile; return the top functions by tottime, per step."""
    node = make_sim_node(context, '/profile_cprofile', dict(params, real_time_factor=0.0))
    try:
        node.advance(240)
        profiler = cProfile.Profile()
        profiler.enable()
        node.advance(steps)
        profiler.disable()
    finally:
        node.destroy_node()
    rows = []
    stats = pstats.Stats(profiler).stats
    for (path, line, name), (_, calls, tottime, cumtime, _) in stats.items():
        where = f'{os.path.basename(path)}:{line}({name})' if line else name
        rows.append({'function': where, 'calls_per_step': calls / steps,
                     'tottime_us': 1e6 * tottime / steps, 'cumtime_us': 1e6 * cumtime / steps})
    rows.sort(key=lambda row: -row['tottime_us'])
    return rows[:top]


def print_breakdown(title, part, overhead_us):
    """Print one breakdown and its publication round."""
    print(f'\n{title}: advance {part["advance_us"]:.1f} us/step = physics '
          f'{part["physics_us"]:.1f} + bridge {part["bridge_us"]:.1f} (raw stepSimulation '
          f'{part["raw_step_us"]:.1f} us by CPU time, untimed)')
    print(f'   {"exclusive us":>12} {"inclusive us":>12} {"calls":>6}  function')
    for row in part['rows']:
        print(f'   {row["exclusive_us"]:12.2f} {row["inclusive_us"]:12.2f} '
              f'{row["calls_per_step"]:6.2f}  {row["function"]}')
    if part['missing']:
        print('   not found (renamed?): ' + ', '.join(part['missing']))
    if part['round']:
        print(f'   one publication round, us (timed calls add ~{overhead_us:.2f} us each): '
              + ', '.join(f'{kind} {us:.1f}' for kind, us in part['round'].items()))


def main(argv=None):
    """Run the breakdowns and cProfile; print them and write profile.json."""
    parser = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    parser.add_argument('--steps', type=int, default=3000, help='steps per measurement')
    parser.add_argument('--domain', type=int, default=95, help='ROS domain id (default 95)')
    parser.add_argument('--top', type=int, default=20, help='cProfile rows to show')
    parser.add_argument('--output', default=PROFILE_PATH, help='where to write the JSON')
    args = parser.parse_args(argv)

    import rclpy
    from rclpy.context import Context
    off = outputs_off()
    configurations = [('every_step', 'publishing every step', dict(off, publish_rate=0.0)),
                      ('publish_rate_10', 'publish_rate 10', dict(off, publish_rate=10.0))]
    if len(missing_parameters(('scan_rate', 'imu_rate', 'publish_tf'))) < 3:
        configurations.append(('default_outputs', 'default outputs', {}))
    overhead_us = timer_overhead_us()
    context = Context()
    init_ros(args.domain, context)
    try:
        parts = {name: breakdown(context, name, params, args.steps)
                 for name, _, params in configurations}
        top = cprofile_top(context, configurations[0][2], args.steps, args.top)
    finally:
        rclpy.try_shutdown(context=context)

    print(f'1. Breakdown inside SimNode.advance, rtf 0, {args.steps} steps, wall time; each '
          f'timed call adds ~{overhead_us:.2f} us to its caller\'s exclusive time')
    for name, title, _ in configurations:
        print_breakdown(title, parts[name], overhead_us)
    print(f'\n2. cProfile top {args.top} by tottime, publishing every step (us per step)')
    print(f'   {"tottime":>8} {"cumtime":>8} {"calls":>6}  function')
    for row in top:
        print(f'   {row["tottime_us"]:8.1f} {row["cumtime_us"]:8.1f} '
              f'{row["calls_per_step"]:6.1f}  {row["function"]}')
    write_json(args.output, {'date': local_date(), 'machine': machine_info(),
                             'steps': args.steps, 'timer_overhead_us': overhead_us,
                             'breakdowns': parts, 'cprofile_top': top})
    print(f'\nwrote {args.output}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
