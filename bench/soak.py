#!/usr/bin/env python3
"""
Soak run of the r2d2_sim node: one simulated hour as fast as possible.

Run from the repository root::

    .venv/bin/python bench/soak.py [--sim-seconds 3600] [--domain 222]

The node runs as a subprocess at ``real_time_factor`` 0 (publishing every
physics step), its output going to a log file. A driver in this process, in
an rclpy context of its own, subscribes ``/clock``, ``joint_states`` and
``odom`` and, every simulated second judged from ``/clock``, publishes a
``cmd_vel`` from a cycle of forward, turn, stop, backward, turn back, stop.
Measured: the node's resident memory over simulated time (growth after
warm-up), every received stamp against the exact step grid ``k * 10**9 // 240``
ns, the simulated time the pause service reports against the last ``/clock``,
single steps through the step service, commands sent against the commands the
node counted, warnings and errors in the node's log, and its exit status after
SIGINT. Prints a summary and writes it, with the samples, to ``bench/soak.json``.
"""

import argparse
import datetime
import json
import os
import re
import resource
import sys
import tempfile
import threading
import time

# Importing common puts the repository on sys.path and keeps discovery on this host.
from common import (
    BENCH_DIR, cpu_model, fit_line, LoadMeter, log_tail, PHYSICS_RATE_HZ,
    process_cpu_s, start_sim, status, stop_process, write_json)
from r2d2_sim.client import stamp_ns  # noqa: E402,I100 (after common set sys.path)

SOAK_PATH = os.path.join(BENCH_DIR, 'soak.json')
RATE = int(PHYSICS_RATE_HZ)     # steps per simulated second; step k is at k * 10**9 // RATE ns
# (linear m/s, angular rad/s), one per simulated second, in turn.
COMMANDS = ((0.3, 0.0), (0.0, 0.5), (0.0, 0.0), (-0.3, 0.0), (0.0, -0.5), (0.0, 0.0))
TARGET_RSS_GROWTH_MB = 5.0      # after warm-up, to the end
# The tests take domains 1..100 (conftest), run.py and profile_step.py 90..95: a
# soak there met a simulator of a concurrent test run. 215..231 are valid Fast DDS
# domains on Linux whose ports lie above the ephemeral range.
DEFAULT_DOMAIN = 222
# Log lines that count as problems, by kind (case-insensitive).
LOG_PROBLEMS = {'warning': re.compile(r'\bwarn', re.I),
                'error': re.compile(r'error|fatal', re.I),
                'traceback': re.compile(r'traceback|exception', re.I)}


def step_of_ns(ns):
    """Return the step k whose exact time k * 10**9 // RATE is nearest to ``ns``."""
    return (ns * RATE + 10**9 // 2) // 10**9


def grid_error_ns(ns):
    """Return ``ns`` minus the exact time of its nearest step (0 when on the grid)."""
    return ns - step_of_ns(ns) * 10**9 // RATE


def parse_reply(text):
    """Return the JSON facts of a ~/pause or ~/step reply (None if absent or unreadable)."""
    try:
        return json.loads(text) if text else None
    except ValueError:
        return None


def proc_status(pid):
    """Return VmRSS and VmHWM (kB), threads and open file descriptors of process ``pid``."""
    values = {}
    with open(f'/proc/{pid}/status', encoding='utf-8') as proc:
        for line in proc:
            key, _, rest = line.partition(':')
            if key in ('VmRSS', 'VmHWM', 'Threads'):
                values[key] = int(rest.split()[0])
    values['fds'] = len(os.listdir(f'/proc/{pid}/fd'))
    return values


def scan_log(path, keep=20):
    """Count the problem lines of the node's log by kind; return the counts and the first few."""
    counts = {kind: 0 for kind in LOG_PROBLEMS}
    lines, first = 0, []
    with open(path, encoding='utf-8', errors='replace') as log:
        for line in log:
            lines += 1
            kinds = [kind for kind, pattern in LOG_PROBLEMS.items() if pattern.search(line)]
            for kind in kinds:
                counts[kind] += 1
            if kinds and len(first) < keep:
                first.append(line.rstrip('\n'))
    return {'lines': lines, 'counts': counts, 'problem_lines': first}


class StampCheck:
    """Count the stamps of one topic and how many are off the step grid or go backwards."""

    def __init__(self):
        self.received = 0
        self.off_grid = 0
        self.max_grid_error_ns = 0
        self.backwards = 0
        self.repeated = 0
        self.last_ns = None
        self.first_off = []
        self.first_backwards = []

    def add(self, ns):
        """Check one stamp in nanoseconds."""
        self.received += 1
        error = grid_error_ns(ns)
        if error:
            self.off_grid += 1
            self.max_grid_error_ns = max(self.max_grid_error_ns, abs(error))
            if len(self.first_off) < 10:
                self.first_off.append(ns)
        if self.last_ns is not None:
            if ns < self.last_ns:
                self.backwards += 1
                if len(self.first_backwards) < 20:
                    self.first_backwards.append({'received': self.received,
                                                 'wall': time.perf_counter(),
                                                 'from_ns': self.last_ns, 'to_ns': ns})
            elif ns == self.last_ns:
                self.repeated += 1
        self.last_ns = ns

    def summary(self):
        """Return the counts as a dict."""
        return {'received': self.received, 'off_grid': self.off_grid,
                'max_grid_error_ns': self.max_grid_error_ns, 'backwards': self.backwards,
                'repeated': self.repeated, 'first_off_grid_ns': self.first_off,
                'first_backwards': self.first_backwards,
                'last_ns': self.last_ns}


class Driver:
    """
    The subscriber and commander, on the testing API's RosHarness (``domain_id``, leased).

    The harness spins its executor in a thread; the callbacks check every
    stamp, send a command at each new simulated second and sample the node's
    /proc entry every ``sample_every_s`` simulated seconds, and set ``done``
    once /clock reaches ``end_s``. Closing stops the spinning thread before
    the executor shuts down, the order rclpy 7.1 needs.
    """

    def __init__(self, domain_id, end_s, sample_every_s):
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import JointState
        from std_srvs.srv import SetBool, Trigger
        from r2d2_sim.testing import RosHarness

        self.harness = RosHarness(domain_id=domain_id)
        self.node = self.harness.create_node('soak_driver', use_sim_time=False)
        self.twist_type = Twist
        self.cmd_pub = self.node.create_publisher(Twist, 'cmd_vel', 10)
        self.node.create_subscription(Clock, '/clock', self._on_clock, 10)
        self.node.create_subscription(JointState, 'joint_states', self._on_joint_states, 10)
        self.node.create_subscription(Odometry, 'odom', self._on_odom, 10)
        self.pause_client = self.node.create_client(SetBool, '/r2d2_sim/pause')
        self.pause_type = SetBool
        self.step_client = self.node.create_client(Trigger, '/r2d2_sim/step')
        self.step_type = Trigger

        self.end_k = round(end_s * RATE)
        self.sample_every_k = max(1, round(sample_every_s * RATE))
        self.pid = None
        self.done = threading.Event()
        self.clock = StampCheck()
        self.joint_states = StampCheck()
        self.odom = StampCheck()
        self.clock_gaps = 0             # steps between received /clock messages never seen
        self.first = None               # (step, wall) of the first /clock
        self.end = None                 # (step, wall) of the first /clock at or past the end
        self.commands_sent = 0
        self.seconds_skipped = 0
        self.last_second = None
        self.next_sample_k = 0
        self.samples = []
        self.odom_path_m = 0.0
        self.odom_pose = None
        self.errors = []
        self.foreign_nodes = set()
        self.max_clock_publishers = 0

    def _on_clock(self, msg):
        ns = stamp_ns(msg.clock)
        last_ns = self.clock.last_ns
        self.clock.add(ns)
        k = step_of_ns(ns)
        now = time.perf_counter()
        if self.first is None:
            self.first = (k, now)
            self.last_second = k // RATE
        elif last_ns is not None and k > step_of_ns(last_ns) + 1:
            self.clock_gaps += k - step_of_ns(last_ns) - 1
        if self.end is None and k >= self.end_k:
            self.end = (k, now)
            self.done.set()
        if self.end is None:
            second = k // RATE
            if second > self.last_second:
                self.seconds_skipped += second - self.last_second - 1
                self.last_second = second
                linear, angular = COMMANDS[second % len(COMMANDS)]
                command = self.twist_type()
                command.linear.x, command.angular.z = linear, angular
                self.cmd_pub.publish(command)
                self.commands_sent += 1
        if k >= self.next_sample_k and self.pid is not None:
            self.next_sample_k = (k // self.sample_every_k + 1) * self.sample_every_k
            self.sample(k, now)

    def _on_joint_states(self, msg):
        self.joint_states.add(stamp_ns(msg.header.stamp))

    def _on_odom(self, msg):
        from r2d2_sim.client import pose_from_odometry
        self.odom.add(stamp_ns(msg.header.stamp))
        pose = pose_from_odometry(msg)
        if self.odom_pose is not None:
            self.odom_path_m += ((pose.x_m - self.odom_pose.x_m) ** 2
                                 + (pose.y_m - self.odom_pose.y_m) ** 2) ** 0.5
        self.odom_pose = pose

    def sample(self, k, wall):
        """Record the node's memory, threads, descriptors and CPU time at step ``k``."""
        try:
            entry = proc_status(self.pid)
            entry['cpu_s'] = process_cpu_s(self.pid)
        except OSError as exc:
            self.errors.append(f'sampling /proc/{self.pid}: {exc}')
            return
        entry.update(sim_s=k / RATE, wall=wall)
        self.samples.append(entry)
        self.check_graph()

    def check_graph(self):
        """Record ROS nodes other than the driver and the simulator seen on the domain."""
        names = self.node.get_node_names_and_namespaces()
        for own in (('soak_driver', '/'), ('r2d2_sim', '/')):
            if own in names:  # one of each is ours, a second one is not
                names.remove(own)
        self.foreign_nodes.update(namespace.rstrip('/') + '/' + name for name, namespace in names)
        self.max_clock_publishers = max(self.max_clock_publishers,
                                        self.node.count_publishers('/clock'))

    def start(self, pid):
        """Sample process ``pid`` from now on."""
        self.pid = pid

    def call(self, client, request, timeout_s=10.0):
        """Call a service while the executor spins in its thread; None on timeout."""
        if not client.wait_for_service(timeout_sec=timeout_s):
            return None
        return client.call(request, timeout_sec=timeout_s)

    def pause(self, paused=True):
        """Call /r2d2_sim/pause; return the reply message (None on timeout)."""
        response = self.call(self.pause_client, self.pause_type.Request(data=paused))
        return None if response is None else response.message

    def step(self):
        """Call /r2d2_sim/step; return the reply message (None on timeout)."""
        response = self.call(self.step_client, self.step_type.Request())
        return None if response is None else response.message

    def wait_clock_quiet(self, quiet_s=0.5, timeout_s=10.0):
        """Wait until no /clock has arrived for ``quiet_s``; return the last /clock ns."""
        deadline = time.monotonic() + timeout_s
        seen, since = self.clock.received, time.monotonic()
        while time.monotonic() < deadline:
            time.sleep(0.05)
            if self.clock.received != seen:
                seen, since = self.clock.received, time.monotonic()
            elif time.monotonic() - since >= quiet_s:
                break
        return self.clock.last_ns

    def close(self):
        """Stop spinning, shut the executor down, destroy the node and the context."""
        self.harness.close()


def check_pause_and_steps(driver, steps=5):
    """
    Pause the node, compare the reported time with /clock, then take single steps.

    The first pause reply must name the step physics stopped at (no step may
    follow it); a second pause request (the node is paused by then) must agree.
    Each step request must advance exactly one step, and /clock must follow it.
    """
    result = {'first_reply': driver.pause(True)}
    last_ns = driver.wait_clock_quiet()
    result['second_reply'] = second = driver.pause(True)
    result['last_clock_ns'] = last_ns
    reply = parse_reply(second)
    if reply is None or last_ns is None:
        result['error'] = 'no usable pause reply or no /clock'
        return result
    result['reported_step'] = reply['step']
    result['cmd_vel_received'] = reply['commands_received']
    result['reported_minus_clock_steps'] = reply['step'] - step_of_ns(last_ns)
    result['reported_minus_clock_ns'] = reply['sim_time_ns'] - last_ns
    first = parse_reply(result['first_reply'])
    result['first_reply_minus_clock_steps'] = (
        None if first is None else first['step'] - step_of_ns(last_ns))

    step_results = []
    previous_k = step_of_ns(last_ns)
    for _ in range(steps):
        text = driver.step()
        reply = parse_reply(text)
        clock_ns = driver.wait_clock_quiet(quiet_s=0.2)
        if reply is None:
            step_results.append({'reply': text, 'ok': False})
            continue
        advanced, k = reply['steps'], reply['step']
        step_results.append({'reply': text, 'advanced': advanced, 'step': k,
                             'clock_ns': clock_ns,
                             'ok': (advanced == 1 and k == previous_k + 1
                                    and clock_ns == k * 10**9 // RATE
                                    and reply['sim_time_ns'] == clock_ns)})
        previous_k = k
    result['steps'] = step_results
    result['steps_ok'] = all(s['ok'] for s in step_results) and len(step_results) == steps
    return result


def memory_summary(samples, warm_up_s):
    """RSS after warm-up, at the end, growth, max, and the slope fitted after warm-up."""
    running = [s for s in samples if s.get('phase') != 'paused']
    after = [s for s in running if s['sim_s'] >= warm_up_s] or running[-1:]
    if not after:
        return {}
    warm, end = after[0], running[-1]
    xs = [s['sim_s'] / 3600.0 for s in after]
    ys = [s['VmRSS'] / 1024.0 for s in after]
    _, slope = fit_line(xs, ys) if len(after) > 1 else (0.0, 0.0)
    first = running[0]
    return {
        'first_sample_sim_s': first['sim_s'], 'first_rss_mb': first['VmRSS'] / 1024.0,
        'warm_up_sim_s': warm['sim_s'], 'rss_after_warm_up_mb': warm['VmRSS'] / 1024.0,
        'end_sim_s': end['sim_s'], 'rss_end_mb': end['VmRSS'] / 1024.0,
        'rss_growth_mb': (end['VmRSS'] - warm['VmRSS']) / 1024.0,
        'rss_max_after_warm_up_mb': max(ys), 'rss_min_after_warm_up_mb': min(ys),
        'rss_slope_mb_per_sim_hour': slope,
        'peak_rss_hwm_mb': max(s['VmHWM'] for s in samples) / 1024.0,
        'threads_first_end': [first['Threads'], end['Threads']],
        'fds_first_end': [first['fds'], end['fds']],
    }


def cpu_share(samples):
    """Return the node's CPU seconds per wall second between its first and last running sample."""
    running = [s for s in samples if s.get('phase') != 'paused']
    if len(running) < 2:
        return float('nan')
    first, last = running[0], running[-1]
    return (last['cpu_s'] - first['cpu_s']) / (last['wall'] - first['wall'])


def wait_for_end(driver, sim, log_path, timeout_s):
    """Wait until the driver has seen the end time; raise if the node dies or stalls."""
    deadline = time.monotonic() + timeout_s
    start_deadline = time.monotonic() + 30.0
    while not driver.done.wait(0.5):
        if sim.poll() is not None:
            raise RuntimeError(f'the node exited with {sim.returncode}:\n' + log_tail(log_path))
        now = time.monotonic()
        if driver.first is None and now > start_deadline:
            raise RuntimeError('no /clock from the node:\n' + log_tail(log_path))
        if now > deadline:
            raise RuntimeError(f'the node did not reach the end in {timeout_s:g} s wall '
                               f'(last /clock {driver.clock.last_ns} ns)')


def run_soak(args, work):
    """Run the node and the driver; return the results dict."""
    log_path = args.log or os.path.join(work, 'sim.log')
    warm_up_s = args.warm_up if args.warm_up is not None else min(60.0, args.sim_seconds / 10)
    driver = Driver(args.domain, args.sim_seconds, args.sample_every)
    sim = None
    results = {}
    try:
        meter = LoadMeter().start()
        own_cpu0 = resource.getrusage(resource.RUSAGE_SELF)
        sim = start_sim(args.domain, log_path, real_time_factor=0.0)
        driver.start(sim.pid)
        wait_for_end(driver, sim, log_path, args.timeout)
        load = meter.stop()
        own_cpu1 = resource.getrusage(resource.RUSAGE_SELF)
        first_k, first_wall = driver.first
        end_k, end_wall = driver.end
        node_cpu_s = process_cpu_s(sim.pid)
        pause = check_pause_and_steps(driver)
        driver.sample(step_of_ns(driver.clock.last_ns or 0), time.perf_counter())
        if driver.samples:
            driver.samples[-1]['phase'] = 'paused'
        exit_code = stop_process(sim, timeout_s=10.0)
    finally:
        if sim is not None:
            stop_process(sim)
        driver.close()
    wall_s = end_wall - first_wall
    own_cpu_s = ((own_cpu1.ru_utime + own_cpu1.ru_stime)
                 - (own_cpu0.ru_utime + own_cpu0.ru_stime))
    results.update({
        'sim_seconds': args.sim_seconds,
        'warm_up_sim_s': warm_up_s,
        'wall_s': wall_s,
        'sim_s_measured': (end_k - first_k) / RATE,
        'steps_per_s': (end_k - first_k) / wall_s,
        'real_time_factor': (end_k - first_k) / RATE / wall_s,
        'node_cpu_s': node_cpu_s,
        'node_cpu_share': cpu_share(driver.samples),
        'driver_cpu_share': own_cpu_s / wall_s,
        'system_busy_cores': load['busy_cores'],
        'steal_cores': load['steal_cores'],
        'memory': memory_summary(driver.samples, warm_up_s),
        'clock': dict(driver.clock.summary(), unseen_steps=driver.clock_gaps),
        'joint_states': driver.joint_states.summary(),
        'odom': driver.odom.summary(),
        'commands_sent': driver.commands_sent,
        'seconds_without_command': driver.seconds_skipped,
        'cmd_vel_received': pause.get('cmd_vel_received'),
        'odom_final_pose': driver.odom_pose._asdict() if driver.odom_pose else None,
        'odom_path_m': driver.odom_path_m,
        'pause': pause,
        'exit_code': exit_code,
        'log': scan_log(log_path),
        'driver_errors': driver.errors,
        'foreign_nodes': sorted(driver.foreign_nodes),
        'max_clock_publishers': driver.max_clock_publishers,
        'driver_max_rss_mb': resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        'samples': driver.samples,
    })
    return results


def build_checks(results):
    """Return rows (check, value, target, status) of the soak's pass criteria."""
    mem, clock, pause = results['memory'], results['clock'], results['pause']
    topics = (clock, results['joint_states'], results['odom'])
    off_grid = sum(t['off_grid'] for t in topics)
    backwards = sum(t['backwards'] for t in topics)
    log_counts = results['log']['counts']
    problems = sum(log_counts.values())
    foreign = results['foreign_nodes']
    return [
        ('other ROS nodes on the domain (results void if any)',
         f'{len(foreign)}{": " + ", ".join(foreign[:5]) if foreign else ""}; '
         f'max /clock publishers {results["max_clock_publishers"]}', '0; 1',
         status(not foreign and results['max_clock_publishers'] == 1)),
        ('RSS growth after warm-up',
         f'{mem["rss_after_warm_up_mb"]:.1f} -> {mem["rss_end_mb"]:.1f} MB '
         f'({mem["rss_growth_mb"]:+.2f} MB; max {mem["rss_max_after_warm_up_mb"]:.1f}, '
         f'slope {mem["rss_slope_mb_per_sim_hour"]:+.2f} MB per sim h)',
         f'<= {TARGET_RSS_GROWTH_MB:g} MB', status(mem['rss_growth_mb'] <= TARGET_RSS_GROWTH_MB)),
        ('stamps off the k*10^9//240 grid / backwards',
         f'{off_grid} / {backwards} (max grid error {clock["max_grid_error_ns"]} ns)',
         '0 / 0', status(off_grid == 0 and backwards == 0)),
        ('pause reply t vs last /clock',
         f'{pause.get("reported_minus_clock_steps")} steps, '
         f'{pause.get("reported_minus_clock_ns")} ns',
         '0 steps, 0 ns', status(pause.get('reported_minus_clock_steps') == 0
                                 and pause.get('reported_minus_clock_ns') == 0)),
        ('first pause reply vs last /clock',
         f'{pause.get("first_reply_minus_clock_steps")} steps', '0 steps',
         status(pause.get('first_reply_minus_clock_steps') == 0)),
        ('single steps while paused',
         ', '.join(str(s.get('advanced')) for s in pause.get('steps', [])) + ' step(s)',
         '1 each, /clock follows', status(pause.get('steps_ok'))),
        ('cmd_vel sent / received by the node',
         f'{results["commands_sent"]} / {results["cmd_vel_received"]}', 'equal',
         status(results['commands_sent'] == results['cmd_vel_received'])),
        ('node log: warnings / errors / tracebacks',
         f'{log_counts["warning"]} / {log_counts["error"]} / {log_counts["traceback"]} '
         f'(of {results["log"]["lines"]} lines)', '0', status(problems == 0)),
        ('node exit status after SIGINT', str(results['exit_code']), '0',
         status(results['exit_code'] == 0)),
    ]


def print_summary(results, checks, header):
    """Print the run's numbers and the checks."""
    mem = results['memory']
    print('\n'.join(header))
    info = [
        ('wall time to the end', f'{results["wall_s"]:.1f} s for '
         f'{results["sim_s_measured"]:.0f} s simulated'),
        ('steps/s (real time factor)', f'{results["steps_per_s"]:,.0f} '
         f'({results["real_time_factor"]:.1f}x)'),
        ('node CPU; driver CPU; all cores busy (cores)', f'{results["node_cpu_share"]:.2f}; '
         f'{results["driver_cpu_share"]:.2f}; {results["system_busy_cores"]:.2f}'),
        ('node RSS first sample / peak (HWM)', f'{mem["first_rss_mb"]:.1f} MB at '
         f'{mem["first_sample_sim_s"]:g} s / {mem["peak_rss_hwm_mb"]:.1f} MB'),
        ('node threads, fds (first -> end)', f'{mem["threads_first_end"][0]} -> '
         f'{mem["threads_first_end"][1]}, {mem["fds_first_end"][0]} -> '
         f'{mem["fds_first_end"][1]}'),
        ('received /clock, joint_states, odom', ', '.join(
            f'{results[t]["received"]:,}' for t in ('clock', 'joint_states', 'odom'))
         + f' of {round(results["sim_s_measured"] * RATE):,} steps each'),
        ('odom at the end', '({x_m:.2f}, {y_m:.2f}) m, yaw {yaw_rad:.2f} rad'.format(
            **results['odom_final_pose']) + f'; path {results["odom_path_m"]:.1f} m'
         if results['odom_final_pose'] else 'none'),
    ]
    width = max(len(row[0]) for row in info + checks)
    for name, value in info:
        print(f'{name.ljust(width)}  {value}')
    print()
    for name, value, target, verdict in checks:
        print(f'{name.ljust(width)}  {verdict:4}  {value}  (target {target})')


def main(argv=None):
    """Parse arguments, run the soak, print and write the results; 0 if every check passes."""
    from r2d2_sim.apps.cli import positive_number
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--sim-seconds', type=positive_number, default=3600.0,
                        help='simulated seconds to run (default 3600)')
    parser.add_argument('--domain', type=int, default=DEFAULT_DOMAIN,
                        help=f'ROS domain id (default {DEFAULT_DOMAIN})')
    parser.add_argument('--warm-up', type=float, default=None, metavar='SIM_SECONDS',
                        help='memory growth is measured from here (default: 10%% of the run, '
                        'at most 60 s)')
    parser.add_argument('--sample-every', type=positive_number, default=10.0,
                        metavar='SIM_SECONDS', help='node /proc sample period (default 10)')
    parser.add_argument('--timeout', type=positive_number, default=None, metavar='SECONDS',
                        help='wall-time limit (default 60 s + 1 ms per step)')
    parser.add_argument('--output', default=SOAK_PATH, help='where to write the JSON')
    parser.add_argument('--log', help='keep the node log at this path')
    args = parser.parse_args(argv)
    if args.timeout is None:
        args.timeout = 60.0 + args.sim_seconds * RATE / 1000.0
    date = datetime.datetime.now().astimezone().isoformat(timespec='seconds')
    began = time.monotonic()
    print(f'soak: {args.sim_seconds:g} s simulated at real_time_factor 0 on domain '
          f'{args.domain}', flush=True)
    with tempfile.TemporaryDirectory(prefix='r2d2_soak_') as work:
        results = run_soak(args, work)
    machine = {'cpu_model': cpu_model(), 'cores': os.cpu_count(),
               'python': sys.version.split()[0]}
    checks = build_checks(results)
    header = [f'r2d2_sim soak, {date}',
              f'{machine["cpu_model"]}, {machine["cores"]} cores, Python {machine["python"]}, '
              f'run took {time.monotonic() - began:.0f} s', '']
    print()
    print_summary(results, checks, header)
    write_json(args.output, {
        'date': date, 'machine': machine, 'command': ' '.join(sys.argv),
        'checks': [dict(zip(('check', 'value', 'target', 'status'), row)) for row in checks],
        'results': results})
    print(f'\nwrote {args.output}')
    return 0 if all(row[3] == 'PASS' for row in checks) else 1


if __name__ == '__main__':
    sys.exit(main())
