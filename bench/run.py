#!/usr/bin/env python3
"""
Benchmark of the r2d2_sim node: real-time fidelity, throughput, sensor costs, latency, start-up.

Run from the repository root::

    .venv/bin/python bench/run.py [--quick] [--domain 90]

Prints a table (measurement / target / measured / pass-miss) and writes it,
with the raw numbers, the machine's CPU model, core count and the date, to
``bench/results.json``. Every ROS process runs with
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` on domains ``--domain`` .. +4.
The helper processes are in ``roles.py``, the shared helpers in ``common.py``.
"""

import argparse
import json
import math
import os
import re
import statistics
import sys
import tempfile
import time
from typing import NamedTuple

from common import (
    alternate, background_load, BENCH_DIR, existing_parameters, fit_line, init_ros, LoadMeter,
    local_date, log_tail, machine_info, make_sim_node, missing_parameters, outputs_off,
    percentile, PHYSICS_RATE_HZ, process_cpu_s, raw_stepper, read_json, start_role, start_sim,
    status, stop_process, take_every_topic, wait_process, write_json)
from r2d2_sim.client import wait_for  # noqa: I100 (after common put the repository on sys.path)

RESULTS_PATH = os.path.join(BENCH_DIR, 'results.json')
PHYSICS_PERIOD_MS = 1000.0 / PHYSICS_RATE_HZ

# Targets on a 2-core machine.
TARGET_RATE_ERROR = 0.005       # achieved physics rate within 0.5 % of 240 Hz
TARGET_JITTER_P99_MS = 0.3
TARGET_CPU_SHARE = 0.08         # of one core, at real time, every step, subscriber attached
TARGET_CPU_SHARE_50HZ = 0.10
TARGET_RATIO_EVERY = 0.85       # in-process, publishing every step / raw
TARGET_RATIO_50HZ = 0.95
TARGET_RATIO_SUBPROCESS = 0.65  # subprocess at rtf 0 with a subscriber process / raw
TARGET_BRIDGE_FIXED_US = 5.0
TARGET_BRIDGE_PER_ROUND_US = 20.0
TARGET_LATENCY_P99_MS = 7.0
TARGET_STARTUP_S = 1.0

# Publication rounds per step 1 (publish_rate 0: every step) down to 1/24.
PUBLISH_RATES_HZ = (0.0, 120.0, 60.0, 50.0, 30.0, 10.0)
CHAIN_JOINTS = (10, 20, 40)


class SensorCase(NamedTuple):
    """One sensor output measured on its own: the parameter that turns it on, its message."""

    name: str
    parameter: str
    value: object       # the parameter's value while measured
    message: str        # the published type whose publications are counted
    label: str


# High rates make the per-message cost a large, well-resolved part of a step.
SENSOR_CASES = (
    SensorCase('scan', 'scan_rate', 60.0, 'LaserScan', 'per scan'),
    SensorCase('imu', 'imu_rate', 240.0, 'Imu', 'per IMU message'),
    SensorCase('tf', 'publish_tf', True, 'TFMessage', 'per TF message'),
)
SENSOR_PARAMETERS = ('scan_rate', 'imu_rate', 'publish_tf', 'camera_rate')


def rate_name(rate):
    """Return the configuration name of a node at publish_rate ``rate`` (0: every step)."""
    return 'node@every' if not rate else f'node@{rate:g}'


def rounds_per_step(rate):
    """Return the publication rounds per physics step at publish_rate ``rate``."""
    return 1.0 if not rate else rate / PHYSICS_RATE_HZ


def chain_urdf(joints):
    """
    Return a URDF: a box base carrying a horizontal chain of ``joints`` revolute joints.

    The joints turn about the vertical axis, so gravity exerts no torque on
    them and the chain holds still; its light links have no collision shapes,
    so they add joints (and PyBullet's default joint motors) but no contacts.
    """
    inertia = '<inertia ixx="{0}" ixy="0" ixz="0" iyy="{0}" iyz="0" izz="{0}"/>'
    parts = ['<?xml version="1.0"?>', '<robot name="chain">',
             '<link name="base_link"><inertial><mass value="5.0"/>'
             + inertia.format(0.05) + '</inertial>'
             '<collision><geometry><box size="0.4 0.4 0.1"/></geometry></collision>'
             '</link>']
    parent = 'base_link'
    for i in range(joints):
        child = f'link_{i}'
        offset = '0 0 0.1' if i == 0 else '0.004 0 0'
        parts.append(f'<link name="{child}"><inertial><mass value="0.001"/>'
                     + inertia.format(1e-6) + '</inertial></link>')
        parts.append(f'<joint name="joint_{i}" type="revolute"><parent link="{parent}"/>'
                     f'<child link="{child}"/><origin xyz="{offset}"/><axis xyz="0 0 1"/>'
                     '<limit lower="-1.0" upper="1.0" effort="1.0" velocity="1.0"/></joint>')
        parent = child
    parts.append('</robot>')
    return '\n'.join(parts) + '\n'


# -- 1. real-time fidelity -------------------------------------------------------------

def measure_fidelity(work, domain_id, sim_seconds, publish_rate, params):
    """Real-time run: harness process (node) plus a subscriber process; return the summary."""
    tag = f'{publish_rate:g}'
    harness_out = os.path.join(work, f'harness_{tag}.json')
    subscriber_out = os.path.join(work, f'subscriber_{tag}.json')
    harness_log = os.path.join(work, f'harness_{tag}.log')
    subscriber_log = os.path.join(work, f'subscriber_{tag}.log')
    subscriber = harness = None
    try:
        subscriber = start_role('subscriber', domain_id, subscriber_log,
                                '--out', subscriber_out, '--timeout', sim_seconds + 60)
        harness = start_role('harness', domain_id, harness_log, '--out', harness_out,
                             '--sim-seconds', sim_seconds,
                             '--params', json.dumps(dict(params, publish_rate=publish_rate)))
        if not wait_process(harness, sim_seconds + 45.0):
            raise RuntimeError('the harness did not finish in time:\n' + log_tail(harness_log))
        time.sleep(0.2)  # let the last messages arrive
        stop_process(subscriber)
    finally:
        for process in (harness, subscriber):
            if process is not None:
                stop_process(process)
    node = read_json(harness_out, harness_log, 'the harness')
    received = read_json(subscriber_out, subscriber_log, 'the subscriber')

    period = node['period_s']
    starts, ends, deadlines = node['starts'], node['ends'], node['deadlines']
    # Step k+1 starts when wait k returns: its lateness against deadline k.
    lateness_ms = [(starts[k + 1] - deadlines[k]) * 1e3
                   for k in range(min(len(deadlines), len(starts) - 1))]
    node_rate = (len(starts) - 1) / (starts[-1] - starts[0])
    # Rate seen by the subscriber: slope of simulated time against arrival time.
    sim_s = [s / PHYSICS_RATE_HZ for s in received['joint_steps']]
    _, sub_rtf = fit_line(received['joint_arrivals'], sim_s)
    # Delivery: start of the step that published a message to its arrival.
    delivery_ms = [(arrival - starts[step - 1]) * 1e3
                   for step, arrival in zip(received['joint_steps'], received['joint_arrivals'])
                   if 1 <= step <= len(ends)]
    published = round(node['steps'] * rounds_per_step(publish_rate))
    cpu_share = node['cpu_s'] / node['wall_s']
    subscriber_share = received['cpu_s'] / node['wall_s']
    return {
        'publish_rate_hz': publish_rate,
        'sim_seconds': node['steps'] / PHYSICS_RATE_HZ,
        'node_rate_hz': node_rate,
        'node_rtf': node_rate * period,
        'subscriber_rtf': sub_rtf,
        'jitter_mean_ms': statistics.fmean(lateness_ms),
        'jitter_p50_ms': percentile(lateness_ms, 50),
        'jitter_p99_ms': percentile(lateness_ms, 99),
        'jitter_max_ms': max(lateness_ms),
        'late_over_1ms': sum(1 for v in lateness_ms if v > 1.0),
        'step_cost_p50_ms': percentile([(e - s) * 1e3 for s, e in zip(starts, ends)], 50),
        'physics_cost_p50_ms': percentile([v * 1e3 for v in node['physics']], 50),
        'cpu_share': cpu_share,
        'involuntary_switches': node['involuntary_switches'],
        'received': received['counts'],
        'published': published,
        'delivery_p50_ms': percentile(delivery_ms, 50),
        'delivery_p99_ms': percentile(delivery_ms, 99),
        'subscriber_cpu_share': subscriber_share,
        'system_busy_cores': node['load']['busy_cores'],
        'steal_cores': node['load']['steal_cores'],
        # Cores other processes on the machine kept busy during the run.
        'other_load_cores': max(0.0, node['load']['busy_cores'] - cpu_share - subscriber_share),
    }


# -- 2. throughput at rtf 0, against raw PyBullet ----------------------------------------

def count_publications(node, message, counter):
    """Count the node's publications of type ``message`` (not on /tf_static) in ``counter``."""
    for publisher in node.publishers:
        if (publisher.msg_type.__name__ != message
                or publisher.topic_name.endswith('tf_static')):
            continue
        publish = publisher.publish

        def counted(msg, publish=publish):
            counter[message] = counter.get(message, 0) + 1
            publish(msg)
        publisher.publish = counted


def time_output_calls(node, message, steps):
    """
    Advance ``node`` ``steps`` steps; return the wall us each ``message`` cost, measured and sent.

    The sensors' measuring methods (scan, IMU read, render) and every output
    class's ``publish`` (``r2d2_sim.ros.outputs``, ``r2d2_sim.ros.tf_outputs``) are
    timed (put back afterwards). Per step, the time of the measurement that
    produces ``message`` and of the output call that published it through
    one of the node's publishers are added up. The median of these resists
    preemption by other processes better than a difference of two
    throughputs does.
    """
    from r2d2_sim.ros import outputs
    from r2d2_sim.sim.robots import sensors as sensor_mounts
    from r2d2_sim.ros import sensor_outputs
    from r2d2_sim.ros import tf_outputs
    perf_counter = time.perf_counter
    published, spent, saved = [], [0.0], []
    for publisher in node.publishers:
        if publisher.msg_type.__name__ == message:
            publish = publisher.publish

            def noted(msg, publish=publish):
                published.append(True)
                publish(msg)
            publisher.publish = noted

    def wrap(cls, name, produces=None):
        original = cls.__dict__[name]

        def timed(self, *args, **kwargs):
            published.clear()
            begin = perf_counter()
            result = original(self, *args, **kwargs)
            if produces == message or (produces is None and published):
                spent[0] += perf_counter() - begin
            return result
        saved.append((cls, name, original))
        setattr(cls, name, timed)
    for module in (outputs, sensor_outputs, tf_outputs):
        for cls in vars(module).values():
            if (isinstance(cls, type) and cls.__module__ == module.__name__
                    and callable(cls.__dict__.get('publish'))):
                wrap(cls, 'publish')
    for cls, name, produces in ((sensor_mounts.LaserScanner, 'scan', 'LaserScan'),
                                (sensor_mounts.ImuSensor, 'read', 'Imu'),
                                (sensor_mounts.HeadCamera, 'render', 'Image')):
        wrap(cls, name, produces)
    durations_us = []
    try:
        for _ in range(steps):
            spent[0] = 0.0
            node.advance(1)
            if spent[0]:
                durations_us.append(1e6 * spent[0])
    finally:
        for cls, name, original in reversed(saved):
            setattr(cls, name, original)
    return durations_us


class SubprocessSim:
    """
    ``python -m r2d2_sim`` at rtf 0 with a subscriber process, run in measured windows.

    The node starts paused; each :meth:`window` un-pauses it through
    ``~/pause``, lets it settle, measures, and pauses it again, so the
    in-process measurements between windows have the cores to themselves.
    Steps/s come from the ``/clock`` stamps the subscriber received during the
    window (both processes read the same monotonic clock), CPU shares from
    ``/proc``.
    """

    def __init__(self, work, domain_id, params):
        from r2d2_sim.testing import SimProcess
        self.subscriber_log = os.path.join(work, 'subscriber_rtf0.log')
        self.subscriber_out = os.path.join(work, 'subscriber_rtf0.json')
        self.windows = []
        self.subscriber = None
        # The public process harness, without subscriptions of its own: the
        # subscriber process is the only one the node publishes to.
        self.sim = SimProcess(domain_id=domain_id, use_env_domain=False, start_paused=True,
                              state_subscriptions=False,
                              **existing_parameters(dict(params, real_time_factor=0.0)))
        try:
            self.subscriber = start_role('subscriber', domain_id, self.subscriber_log,
                                         '--out', self.subscriber_out, '--timeout', 1800)
            node, deadline = self.sim.probe.node, time.monotonic() + 30.0
            topics = ('/joint_states', '/odom', '/ground_truth', '/clock')
            while min(node.count_subscribers(t) for t in topics) < 1:
                if time.monotonic() > deadline or self.subscriber.exited():
                    raise RuntimeError('the subscriber did not appear:\n'
                                       + log_tail(self.subscriber_log))
                self.sim.probe.spin_until(lambda: False, 0.05)
        except BaseException:
            self.close()
            raise

    def pause(self, paused):
        """Call ``~/pause``; return the step its reply names."""
        return self.sim.pause(paused)['step']

    def window(self, settle_s, window_s, record=True):
        """Run the node for ``settle_s`` + ``window_s`` wall seconds, measuring the window."""
        perf_counter = time.perf_counter
        step0, wall0 = self.pause(False), perf_counter()
        time.sleep(settle_s)
        t0 = perf_counter()
        pid = self.sim.process.pid
        node0, sub0 = process_cpu_s(pid), process_cpu_s(self.subscriber.pid)
        time.sleep(window_s)
        t1 = perf_counter()
        node1, sub1 = process_cpu_s(pid), process_cpu_s(self.subscriber.pid)
        step1 = self.pause(True)
        wall1 = perf_counter()
        if record:
            self.windows.append({
                't0': t0, 't1': t1, 'node_cpu_share': (node1 - node0) / (t1 - t0),
                'subscriber_cpu_share': (sub1 - sub0) / (t1 - t0),
                # Cross-check: steps between the two replies, over the time between them.
                'reply_steps_per_s': (step1 - step0) / (wall1 - wall0)})

    def close(self):
        """Stop both processes; return the summary of the windows."""
        if self.subscriber is not None:
            stop_process(self.subscriber)
        self.sim.stop(timeout_s=5.0)
        if not self.windows:
            return None
        received = read_json(self.subscriber_out, self.subscriber_log, 'the rtf-0 subscriber')
        steps, arrivals = received['clock_steps'], received['clock_arrivals']
        for window in self.windows:
            inside = [(a, s) for a, s in zip(arrivals, steps) if window['t0'] <= a <= window['t1']]
            window['clock_received'] = len(inside)
            if len(inside) >= 20:
                _, slope = fit_line([a for a, _ in inside], [s for _, s in inside])
                window['steps_per_s'] = slope
                span = inside[-1][1] - inside[0][1]
                window['received_fraction'] = (len(inside) - 1) / span if span else math.nan
            else:  # the subscriber got (almost) nothing: fall back on the replies
                window['steps_per_s'] = window['reply_steps_per_s']
                window['received_fraction'] = math.nan

        for window in self.windows:
            window['steps_per_node_cpu_s'] = window['steps_per_s'] / window['node_cpu_share']
        # The fastest window is the one other processes disturbed least.
        best = max(self.windows, key=lambda w: w['steps_per_s'])
        summary = {key: best[key] for key in (
            'steps_per_s', 'steps_per_node_cpu_s', 'reply_steps_per_s', 'node_cpu_share',
            'subscriber_cpu_share', 'received_fraction')}
        summary['median_steps_per_s'] = statistics.median(w['steps_per_s'] for w in self.windows)
        summary['windows'] = self.windows
        return summary


def measure_throughput(work, domain_id, subprocess_domain, plan, params):
    """
    Steps/s of every configuration against raw stepping of the same world, interleaved.

    In-process nodes (own context, rtf 0, ``advance`` without executor) for
    each publish rate, each sensor output on its own, the default outputs,
    and chains of joints; a ``...:raw`` configuration steps that node's world
    with ``stepSimulation`` alone ('raw': the every-step node's world). The
    configurations compared with each other form a group, whose members take
    turns chunk by chunk (:func:`alternate`). One round measures every group
    once, then runs one window of the subprocess node (:class:`SubprocessSim`).
    """
    import rclpy
    from rclpy.context import Context
    from r2d2_sim.ros.node import StartupError
    from r2d2_sim.sim.settings.table import PARAMETERS_BY_NAME

    context = Context()
    init_ros(domain_id, context)
    nodes, advances, counters, sensors = {}, {}, {}, {}
    groups = {'rates': ['node@every', 'raw'] + [rate_name(r) for r in PUBLISH_RATES_HZ if r]}
    sub = takers = None

    def add(name, node_params, raw=None):
        node = make_sim_node(context, '/bench_' + re.sub(r'\W', '_', name),
                             dict(node_params, real_time_factor=0.0))
        nodes[name], advances[name] = node, node.advance
        if raw is not None:
            nodes[raw], advances[raw] = node, raw_stepper(node.world)
        return node

    try:
        for rate in PUBLISH_RATES_HZ:
            add(rate_name(rate), dict(params, publish_rate=rate), None if rate else 'raw')
        for case in SENSOR_CASES:
            spec = PARAMETERS_BY_NAME.get(case.parameter)
            if spec is None:
                sensors[case.name] = {'missing': 'parameter missing'}
                continue
            value = case.value
            if spec.bounds is not None and isinstance(value, float):
                value = min(max(value, spec.bounds.low), spec.bounds.high)
            setting = existing_parameters({case.parameter: value})
            try:
                node = add(case.name, dict(params, **setting), f'{case.name}:raw')
            except StartupError as exc:
                sensors[case.name] = {'missing': f'node refused {setting}: {exc}'}
                continue
            sensors[case.name] = {'setting': setting}
            counters[case.name] = {}
            count_publications(node, case.message, counters[case.name])
            groups[case.name] = [case.name, f'{case.name}:raw', 'node@every', 'raw']
        defaults = add('defaults', {}, 'defaults:raw')
        counters['defaults'] = {}
        for case in SENSOR_CASES:
            count_publications(defaults, case.message, counters['defaults'])
        groups['defaults'] = ['defaults', 'defaults:raw']
        for joints in CHAIN_JOINTS:
            path = os.path.join(work, f'chain{joints}.urdf')
            with open(path, 'w', encoding='utf-8') as urdf:
                urdf.write(chain_urdf(joints))
            add(f'chain{joints}:node', dict(params, urdf=path), f'chain{joints}:raw')
            groups[f'chain{joints}'] = [f'chain{joints}:node', f'chain{joints}:raw']
        joints_published = {name: len(node.simulation.robot.movable)
                            for name, node in nodes.items()}
        # Someone takes every message (the outputs skip what nobody takes).
        takers = take_every_topic(context, {id(n): n for n in nodes.values()}.values())
        sub = SubprocessSim(work, subprocess_domain, params)
        for advance in advances.values():  # warm-up: the robots settle, code paths get hot
            advance(240)
        sub.window(plan['rtf0_settle_s'], plan['rtf0_window_s'], record=False)
        for counter in counters.values():
            counter.clear()
        start_steps = {name: node.step_count for name, node in nodes.items()}
        samples = {group: {name: [] for name in members} for group, members in groups.items()}
        wall_samples = {group: {name: [] for name in members}
                        for group, members in groups.items()}
        for _ in range(plan['throughput_rounds']):
            for group, members in groups.items():
                cpu_rates, wall_rates = alternate([advances[name] for name in members],
                                                  plan['inprocess_min_s'])
                for name, cpu_rate, wall_rate in zip(members, cpu_rates, wall_rates):
                    samples[group][name].append(cpu_rate)
                    wall_samples[group][name].append(wall_rate)
            sub.window(plan['rtf0_settle_s'], plan['rtf0_window_s'])
        stepped = {name: node.step_count - start_steps[name] for name, node in nodes.items()}
        publications = {name: {message: count / stepped[name]
                               for message, count in counter.items()}
                        for name, counter in counters.items()}
        for case in SENSOR_CASES:
            if case.name in nodes:
                calls = time_output_calls(nodes[case.name], case.message, plan['call_steps'])
                sensors[case.name]['calls_timed'] = len(calls)
                sensors[case.name]['call_us_median'] = statistics.median(calls or [math.nan])
    finally:
        subprocess_result = sub.close() if sub is not None else None
        if takers is not None:
            takers.destroy_node()
        for node in {id(node): node for node in nodes.values()}.values():
            node.destroy_node()
        rclpy.try_shutdown(context=context)

    def over_rounds(table, function):
        return {group: {name: function(v) for name, v in rates.items()}
                for group, rates in table.items()}
    return {'rounds': plan['throughput_rounds'], 'groups': groups,
            'best_steps_per_s': over_rounds(samples, max),
            'best_wall_steps_per_s': over_rounds(wall_samples, max),
            'median_steps_per_s': over_rounds(samples, statistics.median),
            'median_wall_steps_per_s': over_rounds(wall_samples, statistics.median),
            'samples_steps_per_s': samples, 'samples_wall_steps_per_s': wall_samples,
            'joints_published': joints_published, 'publications_per_step': publications,
            'sensor_settings': sensors, 'subprocess': subprocess_result}


def extra_us(best, name, reference, base=None, base_reference=None):
    """
    Return the us per step ``name`` takes beyond ``reference``, from one group's best rounds.

    With ``base`` and ``base_reference``, their difference is subtracted: the
    cost of what ``name`` has and ``base`` has not. Each configuration's
    fastest round is the one other processes disturbed least (as ``timeit``
    takes the minimum), so the differences of those are the code's own costs.
    """
    extra = 1e6 / best[name] - 1e6 / best[reference]
    if base is not None:
        extra -= 1e6 / best[base] - 1e6 / best[base_reference]
    return extra


def throughput_summary(throughput):
    """Fit the bridge cost against publication rounds per step and against joints; sensors."""
    best = throughput['best_steps_per_s']
    extra = [extra_us(best['rates'], rate_name(rate), 'raw') for rate in PUBLISH_RATES_HZ]
    fixed, per_round = fit_line([rounds_per_step(rate) for rate in PUBLISH_RATES_HZ], extra)
    joint_extra = [extra_us(best[f'chain{j}'], f'chain{j}:node', f'chain{j}:raw')
                   for j in CHAIN_JOINTS]
    joint_fixed, per_joint = fit_line(list(CHAIN_JOINTS), joint_extra)
    sensors = {}
    for case in SENSOR_CASES:
        entry = dict(throughput['sensor_settings'][case.name])
        if 'missing' not in entry:
            per_step = throughput['publications_per_step'][case.name].get(case.message, 0.0)
            entry['messages_per_step'] = per_step
            entry['extra_us_per_step'] = extra_us(
                best[case.name], case.name, f'{case.name}:raw', 'node@every', 'raw')
            entry['us_per_message'] = (entry['extra_us_per_step'] / per_step
                                       if per_step else math.nan)
        sensors[case.name] = entry
    return {'rate_fixed_us': fixed, 'per_publication_round_us': per_round,
            'bridge_us_by_rate': dict(zip([f'{r:g}' for r in PUBLISH_RATES_HZ], extra)),
            'joint_fixed_us': joint_fixed, 'per_joint_us': per_joint,
            'bridge_us_by_chain_joints': dict(zip(map(str, CHAIN_JOINTS), joint_extra)),
            'r2d2_joints': throughput['joints_published']['node@every'],
            'defaults_extra_us': extra_us(best['defaults'], 'defaults', 'defaults:raw'),
            'sensors': sensors}


# -- 3. command latency -------------------------------------------------------------------

def measure_latency(work, domain_id, duration_s, period_s, speed, params):
    """Command latency against the node as a subprocess at real time."""
    out = os.path.join(work, 'latency.json')
    log = os.path.join(work, 'latency.log')
    sim_log = os.path.join(work, 'sim_latency.log')
    sim = probe = None
    try:
        # Without the acceleration ramp: this measures the bridge, not how long the
        # wheels take to reverse at 1 m/s^2 (2 x 0.2 m/s / 1 m/s^2 = 0.4 s by design).
        sim = start_sim(domain_id, sim_log, real_time_factor=1.0,
                        max_linear_acceleration=0.0, max_angular_acceleration=0.0, **params)
        probe = start_role('latency', domain_id, log, '--out', out, '--duration', duration_s,
                           '--period', period_s, '--speed', speed, '--node-pid', sim.pid)
        if not wait_process(probe, duration_s + 45.0):
            raise RuntimeError('the latency probe did not finish:\n' + log_tail(log)
                               + log_tail(sim_log))
    finally:
        for process in (probe, sim):
            if process is not None:
                stop_process(process)
    data = read_json(out, log, 'the latency probe')
    latencies_ms = [v * 1e3 for v in data['latencies_s']]
    sim_s = [s / PHYSICS_RATE_HZ for s in data['steps']]
    _, rtf = fit_line(data['arrivals'], sim_s) if len(sim_s) > 1 else (0.0, math.nan)
    return {
        'commands': len(latencies_ms) + data['missed'],
        'missed': data['missed'],
        'min_ms': min(latencies_ms) if latencies_ms else math.nan,
        'p50_ms': percentile(latencies_ms, 50),
        'p99_ms': percentile(latencies_ms, 99),
        'max_ms': max(latencies_ms) if latencies_ms else math.nan,
        'physics_period_ms': PHYSICS_PERIOD_MS,
        'subprocess_cpu_share': data['node_cpu_share'],
        'subprocess_rtf': rtf,
    }


# -- 4. start-up ---------------------------------------------------------------------------

class ArrivalSubscriber:
    """A joint_states subscriber on the testing API's RosHarness that records arrival times."""

    def __init__(self, domain_id, name):
        from sensor_msgs.msg import JointState
        from r2d2_sim.testing import RosHarness
        self.harness = RosHarness(domain_id=domain_id)
        self.received = []
        self.harness.create_node(name, use_sim_time=False).create_subscription(
            JointState, 'joint_states', lambda msg: self.received.append(time.perf_counter()),
            10)

    def close(self):
        """Stop spinning, destroy the node, shut the context down (in that order)."""
        self.harness.close()


def startup_once(work, domain_id, tag, subscriber=None):
    """
    Return the seconds from Popen of the simulator to the first joint_states received.

    ``subscriber`` is an :class:`ArrivalSubscriber` kept across runs; by
    default a fresh one is made just before the Popen.
    """
    own = subscriber is None
    if own:
        subscriber = ArrivalSubscriber(domain_id, 'bench_startup')
    received = subscriber.received
    received.clear()
    log = os.path.join(work, f'sim_startup_{tag}.log')
    sim = None
    try:
        start = time.perf_counter()
        sim = start_sim(domain_id, log)
        if not wait_for(lambda: received, 20.0, interval_s=0.001):
            raise RuntimeError('no joint_states from the simulator:\n' + log_tail(log))
        return received[0] - start
    finally:
        if sim is not None:
            stop_process(sim)
        if own:
            subscriber.close()


def measure_startup(work, domain_id, runs, restarts):
    """
    Measure start-up ``runs`` times with fresh subscribers, then ``restarts`` restarts.

    A restart stops and starts the simulator again while one subscriber stays
    up throughout, as a running rviz or controller would.
    """
    times = [startup_once(work, domain_id, f'fresh{i}') for i in range(runs)]
    restart_times = []
    if restarts:
        subscriber = ArrivalSubscriber(domain_id, 'bench_startup_kept')
        try:
            for i in range(restarts + 1):
                elapsed = startup_once(work, domain_id, f'kept{i}', subscriber)
                if i:  # the first start is not a restart
                    restart_times.append(elapsed)
                # Messages still queued from this run arrive before the next one starts.
                time.sleep(0.3)
        finally:
            subscriber.close()
    return {'runs_s': times, 'median_s': statistics.median(times),
            'restarts_s': restart_times}


# -- report ---------------------------------------------------------------------------------

class Row(NamedTuple):
    """One line of the table."""

    section: str
    measurement: str
    target: str = ''
    measured: str = ''
    status: str = ''


def measure_raw_paced_cpu(seconds):
    """
    CPU share of raw PyBullet stepping the same world at 240 Hz with the node's pacer.

    The floor under the node's CPU at real time: no ROS, no readout, just
    stepSimulation and an absolute-deadline sleep per tick (caches go cold
    in every sleep, so a step costs more than at rtf 0).
    """
    import resource
    from r2d2_sim.model.timing import DeadlinePacer
    from r2d2_sim.physics.world import SimWorld
    world = SimWorld()
    try:
        pacer = DeadlinePacer(1.0 / PHYSICS_RATE_HZ)
        usage = resource.getrusage(resource.RUSAGE_SELF)
        cpu0 = usage.ru_utime + usage.ru_stime
        start = time.monotonic()
        ticks = 0
        while time.monotonic() - start < seconds:
            world.step(1)
            pacer.wait()
            ticks += 1
        wall = time.monotonic() - start
        usage = resource.getrusage(resource.RUSAGE_SELF)
        return {'seconds': wall, 'rate_hz': ticks / wall,
                'cpu_share': (usage.ru_utime + usage.ru_stime - cpu0) / wall}
    finally:
        world.close()


def fidelity_rows(fid, fid50, raw_paced=None):
    """Rows of the real-time runs."""
    section = (f'1. real time (rtf 1, {fid["sim_seconds"]:g} s simulated, publishing every '
               'step, one subscriber process on joint_states, odom, ground_truth, /clock)')
    received = fid['received']
    rows = [
        Row(section, 'physics rate, node clock', 'within 0.5 % of 240 Hz',
            f'{fid["node_rate_hz"]:.2f} Hz (rtf {fid["node_rtf"]:.5f})',
            status(abs(fid['node_rtf'] - 1.0) <= TARGET_RATE_ERROR)),
        Row(section, 'physics rate, subscriber (stamps vs arrival)', 'within 0.5 %',
            f'rtf {fid["subscriber_rtf"]:.5f}',
            status(abs(fid['subscriber_rtf'] - 1.0) <= TARGET_RATE_ERROR)),
        Row(section, 'tick jitter (wake - deadline) mean / p50 / p99', 'p99 < 0.3 ms',
            f'{fid["jitter_mean_ms"]:.3f} / {fid["jitter_p50_ms"]:.3f} / '
            f'{fid["jitter_p99_ms"]:.3f} ms', status(fid['jitter_p99_ms'] < TARGET_JITTER_P99_MS)),
        Row(section, 'tick jitter max', '',
            f'{fid["jitter_max_ms"]:.3f} ms ({fid["late_over_1ms"]} ticks > 1 ms)'),
        Row(section, 'CPU of the node at real time, publishing every step, subscriber attached',
            f'<= {100 * TARGET_CPU_SHARE:g} % of a core', f'{100 * fid["cpu_share"]:.1f} %',
            status(fid['cpu_share'] <= TARGET_CPU_SHARE)),
        Row(section, 'raw PyBullet, same world and pacer, no ROS: CPU (the floor)', '',
            '' if raw_paced is None else
            f'{100 * raw_paced["cpu_share"]:.1f} % at {raw_paced["rate_hz"]:.1f} Hz'),
        Row(section, 'tick cost p50 in the paced loop: advance / physics alone', '',
            f'{1e3 * fid["step_cost_p50_ms"]:.0f} / {1e3 * fid["physics_cost_p50_ms"]:.0f} us'),
        Row(section, 'subscriber CPU; other processes; steal (cores)', 'quiet machine: ~0',
            f'{100 * fid["subscriber_cpu_share"]:.1f} %; {fid["other_load_cores"]:.2f}; '
            f'{fid["steal_cores"]:.2f}'),
        Row(section, 'received of published: joint_states / odom / ground_truth / /clock', '',
            ' / '.join(str(received[t]) for t in ('joint_states', 'odom', 'ground_truth',
                                                  '/clock')) + f' of {fid["published"]}'),
        Row(section, 'delivery step start -> subscriber p50 / p99', '',
            f'{fid["delivery_p50_ms"]:.3f} / {fid["delivery_p99_ms"]:.3f} ms'),
    ]
    if fid50:
        rows += [
            Row(section, f'at publish_rate 50 ({fid50["sim_seconds"]:g} s): rate / jitter p99',
                '0.5 % / < 0.3 ms',
                f'rtf {fid50["node_rtf"]:.5f} / {fid50["jitter_p99_ms"]:.3f} ms',
                status(abs(fid50['node_rtf'] - 1.0) <= TARGET_RATE_ERROR
                       and fid50['jitter_p99_ms'] < TARGET_JITTER_P99_MS)),
            Row(section, 'at publish_rate 50: CPU of the node',
                f'<= {100 * TARGET_CPU_SHARE_50HZ:g} % of a core',
                f'{100 * fid50["cpu_share"]:.1f} %',
                status(fid50['cpu_share'] <= TARGET_CPU_SHARE_50HZ)),
        ]
    return rows


def throughput_rows(throughput, summary):
    """Rows of the interleaved throughput measurement and of the sensor outputs."""
    section = (f'2. throughput at rtf 0 against raw PyBullet stepping of the same world '
               f'(interleaved, fastest of {throughput["rounds"]} rounds; in-process by thread '
               'CPU time; the subscriber takes joint_states, odom, ground_truth, /clock)')
    best, medians = throughput['best_steps_per_s'], throughput['median_steps_per_s']
    sps, wall = best['rates'], throughput['best_wall_steps_per_s']['rates']
    raw, raw_wall = sps['raw'], wall['raw']

    def ratio_row(name, label, target):
        ratio = sps[name] / raw
        median = medians['rates'][name] / medians['rates']['raw']
        return Row(section, label, f'>= {target:g}',
                   f'{sps[name]:,.0f} / {raw:,.0f} = {ratio:.3f} '
                   f'(median {median:.3f}, wall {wall[name] / raw_wall:.3f})',
                   status(ratio >= target))

    rows = [
        Row(section, 'raw PyBullet steps/s (CPU time; wall)', '', f'{raw:,.0f}; {raw_wall:,.0f}'),
        ratio_row('node@every', 'in-process, publishing every step / raw', TARGET_RATIO_EVERY),
        ratio_row('node@50', 'in-process, publish_rate 50 / raw', TARGET_RATIO_50HZ),
    ]
    sub = throughput['subprocess']
    if sub:
        ratio = sub['steps_per_s'] / raw_wall
        median = (sub['median_steps_per_s']
                  / throughput['median_wall_steps_per_s']['rates']['raw'])
        rows.append(Row(
            section, 'subprocess at rtf 0, every step, one subscriber process / raw (wall)',
            f'>= {TARGET_RATIO_SUBPROCESS:g}',
            f'{sub["steps_per_s"]:,.0f} / {raw_wall:,.0f} = {ratio:.3f} (median {median:.3f}); '
            f'subscriber CPU {100 * sub["subscriber_cpu_share"]:.0f} %',
            status(ratio >= TARGET_RATIO_SUBPROCESS)))
        rows.append(Row(
            section, 'the same: node CPU; steps per node CPU s / raw (CPU)', '',
            f'{100 * sub["node_cpu_share"]:.0f} %; {sub["steps_per_node_cpu_s"]:,.0f} / '
            f'{raw:,.0f} = {sub["steps_per_node_cpu_s"] / raw:.3f}'))
        rows.append(Row(
            section, 'the same: /clock received by the subscriber; steps/s by ~/pause replies',
            '', f'{100 * sub["received_fraction"]:.0f} %; {sub["reply_steps_per_s"]:,.0f}'))
    fixed, per_round = summary['rate_fixed_us'], summary['per_publication_round_us']
    rows.append(Row(section, 'bridge cost per step = fixed + per publication round '
                    '(fit over publish rates)',
                    f'<= {TARGET_BRIDGE_FIXED_US:g} + {TARGET_BRIDGE_PER_ROUND_US:g} us',
                    f'{fixed:.1f} + {per_round:.1f} us',
                    status(fixed <= TARGET_BRIDGE_FIXED_US
                           and per_round <= TARGET_BRIDGE_PER_ROUND_US)))
    for rate in PUBLISH_RATES_HZ:
        name = rate_name(rate)
        label = 'every step' if not rate else f'publish_rate {rate:g}'
        rows.append(Row(section, f'{label}: node / raw us per step (+bridge)', '',
                        f'{1e6 / sps[name]:.0f} / {1e6 / raw:.0f} '
                        f'(+{summary["bridge_us_by_rate"][f"{rate:g}"]:.1f})'))
    for joints in CHAIN_JOINTS:
        chain = best[f'chain{joints}']
        node_us, raw_us = 1e6 / chain[f'chain{joints}:node'], 1e6 / chain[f'chain{joints}:raw']
        rows.append(Row(section, f'chain of {joints} joints: node / raw us per step', '',
                        f'{node_us:.0f} / {raw_us:.0f} '
                        f'(+{summary["bridge_us_by_chain_joints"][str(joints)]:.1f})'))
    rows.append(Row(section, 'bridge cost vs joints (chains, every step)', '',
                    f'{summary["joint_fixed_us"]:.1f} + {summary["per_joint_us"]:.2f} us '
                    'x joints'))

    section = ('3. sensor outputs (in-process, rtf 0, publishing every step, one sensor on: '
               'its bridge minus the bridge without it, per message; and the median wall '
               'time of the output call that publishes it)')
    for case in SENSOR_CASES:
        entry = summary['sensors'][case.name]
        if 'missing' in entry:
            rows.append(Row(section, f'{case.label} ({case.parameter})', '',
                            f'n/a: {entry["missing"]}'))
            continue
        setting = ', '.join(f'{k}:={v}' for k, v in entry['setting'].items())
        if entry['messages_per_step']:
            measured = (f'{entry["us_per_message"]:.1f} us ({entry["messages_per_step"]:.3f} '
                        f'per step); its publish call {entry["call_us_median"]:.1f} us')
        else:
            measured = f'n/a: no {case.message} published'
        rows.append(Row(section, f'{case.label} ({setting})', '', measured))
    defaults, defaults_raw = best['defaults']['defaults'], best['defaults']['defaults:raw']
    published = throughput['publications_per_step']['defaults']
    outputs = ', '.join(f'{message} {per_step:.3f}' for message, per_step in published.items())
    rows.append(Row(section, 'in-process, default outputs / raw', '',
                    f'{defaults:,.0f} / {defaults_raw:,.0f} = {defaults / defaults_raw:.3f} '
                    f'(+{summary["defaults_extra_us"]:.1f} us per step)'))
    rows.append(Row(section, 'the same: sensor messages per step', '', outputs or 'none'))
    return rows


def build_table(results):
    """Turn the measurements into table rows."""
    rows = fidelity_rows(results['fidelity'], results.get('fidelity_50hz'),
                         results.get('raw_paced'))
    rows += throughput_rows(results['throughput'], results['throughput_summary'])
    lat = results['latency']
    section = '4. command latency (node subprocess at rtf 1, no acceleration ramp)'
    rows += [
        Row(section, f'cmd_vel -> joint_states min / p50 ({lat["commands"]} commands, '
            f'{lat["missed"]} missed)', '', f'{lat["min_ms"]:.2f} / {lat["p50_ms"]:.2f} ms'),
        Row(section, 'cmd_vel -> joint_states p99 / max',
            f'p99 < {TARGET_LATENCY_P99_MS:g} ms (physics period {PHYSICS_PERIOD_MS:.2f} ms)',
            f'{lat["p99_ms"]:.2f} / {lat["max_ms"]:.2f} ms',
            status(lat['p99_ms'] < TARGET_LATENCY_P99_MS and not lat['missed'])),
        Row(section, 'node subprocess during it: CPU, rtf', '',
            f'{100 * lat["subprocess_cpu_share"]:.1f} %, {lat["subprocess_rtf"]:.4f}'),
    ]
    start = results['startup']
    section = '5. start-up (default parameters)'
    rows.append(Row(section, f'Popen -> first joint_states (fresh subscriber), median of '
                    f'{len(start["runs_s"])}', f'< {TARGET_STARTUP_S:g} s',
                    f'{start["median_s"]:.3f} s ('
                    + ', '.join(f'{t:.3f}' for t in start['runs_s']) + ')',
                    status(start['median_s'] < TARGET_STARTUP_S)))
    if start['restarts_s']:
        rows.append(Row(section, 'restart while a subscriber stays up (Fast DDS re-discovery)',
                        '', ', '.join(f'{t:.3f}' for t in start['restarts_s']) + ' s'))
    return rows


def print_table(rows, header):
    """Print the rows under ``header`` lines, one block per section."""
    columns = ('measurement', 'target', 'measured', 'pass/miss')
    cells = [(r.measurement, r.target, r.measured, r.status) for r in rows]
    widths = [max(len(c[i]) for c in cells + [columns]) for i in range(3)]
    print('\n'.join(header))
    line = '  '.join(title.ljust(w) for title, w in zip(columns, widths + [0])).rstrip()
    print(line)
    print('-' * len(line))
    section = None
    for row, cell in zip(rows, cells):
        if row.section != section:
            section = row.section
            print(f'\n{section}')
        print('  '.join(c.ljust(w) for c, w in zip(cell, widths + [0])).rstrip())


# -- the run ---------------------------------------------------------------------------------

def make_plan(quick):
    """Return the durations and repetitions of a quick or a full run."""
    return {
        'fidelity_sim_s': 10.0 if quick else 60.0,
        'fidelity_50hz_sim_s': 0.0 if quick else 10.0,
        'raw_paced_s': 4.0 if quick else 10.0,
        'latency_s': 5.0 if quick else 10.0,
        'latency_period_s': 0.25, 'latency_speed_m_s': 0.2,
        'startup_runs': 3,
        'startup_restarts': 0 if quick else 2,
        'throughput_rounds': 5 if quick else 9,
        'inprocess_min_s': 0.08 if quick else 0.2,
        'rtf0_settle_s': 0.3,
        'rtf0_window_s': 0.8 if quick else 1.5,
        'call_steps': 1000 if quick else 2400,
    }


def run_bench(args):
    """Measure everything once, print the table and write bench/results.json."""
    quick = args.quick
    plan = make_plan(quick)
    base = args.domain
    params = outputs_off()
    results = {'outputs_off': params,
               'sensor_parameters_missing': missing_parameters(SENSOR_PARAMETERS),
               'background_load_before': background_load()}
    quiet_deadline = time.monotonic() + args.wait_quiet
    while (results['background_load_before']['busy_cores'] >= 0.25
           and time.monotonic() < quiet_deadline):
        print(f'waiting for a quiet machine: other processes keep '
              f'{results["background_load_before"]["busy_cores"]:.2f} cores busy', flush=True)
        results['background_load_before'] = background_load(2.0)
    began = time.monotonic()
    loads = results['system_busy_cores_by_phase'] = {}
    with tempfile.TemporaryDirectory(prefix='r2d2_bench_') as work:
        meter, current = LoadMeter(), []

        def phase(name):
            """Close the load window of the previous phase, announce and open the next."""
            if current:
                loads[current.pop()] = meter.stop()['busy_cores']
            current.append(name)
            meter.start()
            print(f'[{time.monotonic() - began:6.1f} s] {name}', flush=True)

        phase(f'1. real time, {plan["fidelity_sim_s"]:g} s simulated')
        results['fidelity'] = measure_fidelity(work, base, plan['fidelity_sim_s'], 0.0, params)
        if plan['fidelity_50hz_sim_s']:
            phase(f'1b. real time at publish_rate 50, {plan["fidelity_50hz_sim_s"]:g} s simulated')
            results['fidelity_50hz'] = measure_fidelity(
                work, base, plan['fidelity_50hz_sim_s'], 50.0, params)
        phase('1c. raw PyBullet paced at 240 Hz')
        results['raw_paced'] = measure_raw_paced_cpu(plan['raw_paced_s'])
        phase('4. command latency')
        results['latency'] = measure_latency(work, base + 1, plan['latency_s'],
                                             plan['latency_period_s'],
                                             plan['latency_speed_m_s'], params)
        phase('5. start-up')
        results['startup'] = measure_startup(work, base + 2, plan['startup_runs'],
                                             plan['startup_restarts'])
        phase('2+3. throughput and sensor outputs, interleaved')
        results['throughput'] = measure_throughput(work, base + 4, base + 3, plan, params)
        results['throughput_summary'] = throughput_summary(results['throughput'])
        phase('done')
    elapsed = time.monotonic() - began
    machine = machine_info()
    date = local_date()
    rows = build_table(results)
    off = ', '.join(f'{k}:={v}' for k, v in params.items()) or 'none exist'
    missing = results['sensor_parameters_missing']
    header = [f'r2d2_sim benchmark ({"quick" if quick else "full"}), {date}',
              f'{machine["cpu_model"]}, {machine["cores"]} cores, Python {machine["python"]}, '
              f'run took {elapsed:.0f} s; other processes kept '
              f'{results["background_load_before"]["busy_cores"]:.2f} cores busy before it '
              f'and {results["fidelity"]["other_load_cores"]:.2f} during the real-time run',
              'cores busy per phase, the bench included: ' + ', '.join(
                  f'{name.split(".")[0]}: {busy:.2f}' for name, busy in loads.items()),
              f'sensor outputs off except in 3. and 5.: {off}'
              + (f' (not declared: {", ".join(missing)})' if missing else ''), '']
    print()
    print_table(rows, header)
    write_json(args.output, {
        'date': date, 'mode': 'quick' if quick else 'full', 'machine': machine,
        'elapsed_s': elapsed, 'plan': plan, 'table': [row._asdict() for row in rows],
        'results': results})
    print(f'\nwrote {args.output}')
    return 0


def main(argv=None):
    """Parse the arguments and run the benchmark."""
    parser = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    parser.add_argument('--quick', action='store_true',
                        help='shorter runs (10 s real time instead of 60 s, fewer rounds)')
    parser.add_argument('--domain', type=int, default=90,
                        help='first of the 5 ROS domain ids the bench uses (default 90)')
    parser.add_argument('--output', default=RESULTS_PATH, help='where to write the JSON')
    parser.add_argument('--wait-quiet', type=float, default=0.0, metavar='SECONDS',
                        help='first wait up to SECONDS for other processes to use < 0.25 cores')
    return run_bench(parser.parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
