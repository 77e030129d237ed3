#!/usr/bin/env python3
"""
Benchmark of the r2d2_sim node: real-time fidelity, bridge overhead, latency, scaling, start-up.

Run from the repository root::

    .venv/bin/python bench/run.py [--quick] [--domain 90]

Prints a table and writes it, with the raw numbers, the machine's CPU model,
core count and the date, to ``bench/results.json``. Every ROS process runs with
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` on domains ``--domain`` .. +4.

The same file also holds the roles of the helper processes it starts
(``--role harness|subscriber|latency``); they are not meant to be run by hand.
"""

import argparse
import datetime
import json
import math
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time

BENCH_DIR = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(BENCH_DIR)
if REPO not in sys.path:
    sys.path.insert(0, REPO)
# Discovery must stay on this host; set before rclpy is imported anywhere.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

from r2d2_sim.stdio import silenced_stdout  # noqa: E402 (after the sys.path set-up)

PHYSICS_RATE_HZ = 240.0
PHYSICS_PERIOD_MS = 1000.0 / PHYSICS_RATE_HZ
WHEEL_RADIUS_M = 0.035          # the package URDF's wheels (a command's wheel target is v / r)
LEFT_WHEEL = 'left_front_wheel_joint'
RESULTS_PATH = os.path.join(BENCH_DIR, 'results.json')

# Targets on a 2-core machine.
TARGET_RATE_ERROR = 0.005       # achieved physics rate within 0.5 % of 240 Hz
TARGET_JITTER_P99_MS = 0.3
TARGET_CPU_SHARE = 0.10         # of one core
TARGET_RATIO_EVERY = 0.80
TARGET_RATIO_50HZ = 0.95
TARGET_LATENCY_P99_MS = 7.0
TARGET_STARTUP_S = 1.0

PUBLISH_RATES_HZ = (240.0, 120.0, 60.0, 50.0, 30.0, 10.0)
CHAIN_JOINTS = (10, 20, 40)


# -- small helpers --------------------------------------------------------------

def percentile(values, q):
    """Interpolate linearly the value below which q % (0..100) of ``values`` fall."""
    ordered = sorted(values)
    if not ordered:
        return math.nan
    position = (len(ordered) - 1) * q / 100.0
    low = math.floor(position)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (position - low)


def fit_line(xs, ys):
    """Least-squares line through (xs, ys): return (intercept, slope)."""
    n = len(xs)
    mean_x, mean_y = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mean_x) ** 2 for x in xs)
    sxy = sum((x - mean_x) * (y - mean_y) for x, y in zip(xs, ys))
    slope = sxy / sxx if sxx else math.nan
    return mean_y - slope * mean_x, slope


def cpu_model():
    """Return the CPU model name from /proc/cpuinfo."""
    try:
        with open('/proc/cpuinfo', encoding='utf-8') as cpuinfo:
            for line in cpuinfo:
                if line.startswith('model name'):
                    return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return 'unknown'


def process_cpu_s(pid):
    """Return user + system CPU seconds of process ``pid`` from /proc/<pid>/stat."""
    with open(f'/proc/{pid}/stat', encoding='utf-8') as stat:
        fields = stat.read().rsplit(')', 1)[1].split()
    # fields[0] is field 3 (state); utime and stime are fields 14 and 15.
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def system_cpu_ticks():
    """Return (busy, steal, total) jiffies summed over all CPUs, from /proc/stat."""
    with open('/proc/stat', encoding='utf-8') as stat:
        values = [int(v) for v in stat.readline().split()[1:]]
    idle = values[3] + values[4]           # idle + iowait
    steal = values[7] if len(values) > 7 else 0
    total = sum(values[:8])
    return total - idle - steal, steal, total


class LoadMeter:
    """Measure how many cores were busy (and stolen) between start() and stop()."""

    def start(self):
        """Begin a measurement window."""
        self._begin = system_cpu_ticks()
        return self

    def stop(self):
        """End the window: return {'busy_cores', 'steal_cores'} averaged over it."""
        busy1, steal1, total1 = system_cpu_ticks()
        busy0, steal0, total0 = self._begin
        cores = os.cpu_count() or 1
        span = max(total1 - total0, 1)
        return {'busy_cores': cores * (busy1 - busy0) / span,
                'steal_cores': cores * (steal1 - steal0) / span}


def background_load(seconds=1.0):
    """Return the cores kept busy by other processes while this one sleeps."""
    meter = LoadMeter().start()
    time.sleep(seconds)
    return meter.stop()


def start_process(args, domain_id, log_path):
    """Start ``args`` on ``domain_id`` with stdout and stderr going to ``log_path``."""
    from r2d2_sim.testing import ros_child_env
    log = open(log_path, 'w', encoding='utf-8')
    try:
        return subprocess.Popen(args, env=ros_child_env(domain_id), cwd=REPO,
                                stdout=log, stderr=subprocess.STDOUT)
    finally:
        log.close()


def start_sim(domain_id, log_path, **params):
    """Start ``python -m r2d2_sim`` with ``params`` as ROS parameters."""
    args = [sys.executable, '-m', 'r2d2_sim', '--ros-args']
    for name, value in params.items():
        args += ['-p', f'{name}:={value}']
    return start_process(args, domain_id, log_path)


def start_role(role, domain_id, log_path, *extra):
    """Start this script in a helper role."""
    args = [sys.executable, os.path.abspath(__file__), '--role', role,
            '--domain', str(domain_id), *map(str, extra)]
    return start_process(args, domain_id, log_path)


def stop_process(process, timeout_s=5.0):
    """SIGINT ``process``, wait for it, kill it as a last resort; return its exit code."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
    try:
        return process.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        process.kill()
        return process.wait()


def wait_process(process, timeout_s):
    """Wait up to ``timeout_s`` for ``process`` to exit by itself; True if it did."""
    try:
        process.wait(timeout=timeout_s)
        return True
    except subprocess.TimeoutExpired:
        return False


def log_tail(path, lines=15):
    """Return the last lines of a log file (for error messages)."""
    try:
        with open(path, encoding='utf-8', errors='replace') as log:
            return ''.join(log.readlines()[-lines:])
    except OSError:
        return ''


def read_json(path, log_path, what):
    """Load a helper's JSON output or raise with its log tail."""
    try:
        with open(path, encoding='utf-8') as result:
            return json.load(result)
    except (OSError, ValueError) as exc:
        raise RuntimeError(f'{what} produced no result ({exc}); its log ends:\n'
                           + log_tail(log_path)) from None


def write_json(path, data):
    """Write ``data`` as JSON to ``path`` atomically."""
    tmp = path + '.tmp'
    with open(tmp, 'w', encoding='utf-8') as out:
        json.dump(data, out, indent=1)
    os.replace(tmp, path)


def stop_flag():
    """Return an Event set by SIGINT or SIGTERM (the node's own handlers)."""
    from r2d2_sim.sim_node import stop_on_signals
    return stop_on_signals()


def init_ros(domain_id, context=None):
    """Initialise rclpy on ``domain_id`` without its signal handlers."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)


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


# -- helper process roles ----------------------------------------------------------

def role_harness(args):
    """
    Run SimNode in this process as ``main()`` does, recording each step's wall time.

    The executor spins in a thread; ``run_paced`` paces the node in the main
    thread with a DeadlinePacer subclass that records every deadline, and the
    node's ``advance`` is wrapped to record ``perf_counter`` before and after
    each step. Waits for a subscriber on joint_states and odom first.
    """
    import resource
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from r2d2_sim import node as sim_node
    from r2d2_sim.timing import DeadlinePacer

    deadlines, starts, ends, physics = [], [], [], []
    perf_counter = time.perf_counter

    class RecordingPacer(DeadlinePacer):
        """A DeadlinePacer that records the deadline each wait() aims at."""

        def wait(self):
            deadlines.append(self._next)
            super().wait()

    stop = stop_flag()
    sim_node.DeadlinePacer = RecordingPacer
    init_ros(args.domain)
    executor = SingleThreadedExecutor()
    with silenced_stdout():
        node = sim_node.SimNode(parameter_overrides=[
            Parameter('real_time_factor', value=1.0),
            Parameter('publish_rate', value=args.publish_rate)])
    executor.add_node(node)
    spinner = threading.Thread(target=sim_node._spin, args=(executor, stop), daemon=True)
    spinner.start()
    try:
        deadline = time.monotonic() + 30.0
        while (node.count_subscribers('joint_states') < 1
               or node.count_subscribers('odom') < 1):
            if time.monotonic() > deadline or stop.is_set():
                raise SystemExit('harness: no subscriber on joint_states and odom')
            time.sleep(0.01)
        time.sleep(0.2)  # let the matching settle on both sides
        end_step = round(args.sim_seconds * PHYSICS_RATE_HZ)
        original_advance = node.advance

        def recording_advance(steps=1):
            starts.append(perf_counter())
            original_advance(steps)
            ends.append(perf_counter())
            if node.step_count >= end_step:
                stop.set()
        node.advance = recording_advance
        world_step = node.world.step

        def recording_step(steps=1):
            begin = perf_counter()
            world_step(steps)
            physics.append(perf_counter() - begin)
        node.world.step = recording_step
        meter = LoadMeter().start()
        usage0, wall0 = resource.getrusage(resource.RUSAGE_SELF), perf_counter()
        sim_node.run_paced(node, stop)
        usage1, wall1 = resource.getrusage(resource.RUSAGE_SELF), perf_counter()
        load = meter.stop()
        cpu = (usage1.ru_utime + usage1.ru_stime) - (usage0.ru_utime + usage0.ru_stime)
        write_json(args.out, {
            'steps': node.step_count, 'wall_s': wall1 - wall0, 'cpu_s': cpu,
            'period_s': 1.0 / PHYSICS_RATE_HZ, 'deadlines': deadlines,
            'starts': starts, 'ends': ends, 'physics': physics,
            'involuntary_switches': usage1.ru_nivcsw - usage0.ru_nivcsw, 'load': load})
    finally:
        stop.set()
        executor.shutdown(timeout_sec=1.0)
        spinner.join(timeout=1.0)
        node.destroy_node()
        rclpy.try_shutdown()


def role_subscriber(args):
    """Receive joint_states and odom until SIGINT; record each message's step and arrival."""
    import resource
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import JointState

    stop = stop_flag()
    init_ros(args.domain)
    node = rclpy.create_node('bench_subscriber', namespace=args.namespace)
    perf_counter = time.perf_counter
    joint_steps, joint_arrivals, odom_steps = [], [], []

    def step_of(stamp):
        return round((stamp.sec * 10**9 + stamp.nanosec) * PHYSICS_RATE_HZ / 1e9)

    first_cpu = []

    def on_joint_states(msg):
        joint_arrivals.append(perf_counter())
        joint_steps.append(step_of(msg.header.stamp))
        if not first_cpu:
            usage = resource.getrusage(resource.RUSAGE_SELF)
            first_cpu.append(usage.ru_utime + usage.ru_stime)

    def on_odom(msg):
        odom_steps.append(step_of(msg.header.stamp))

    node.create_subscription(JointState, 'joint_states', on_joint_states, 10)
    node.create_subscription(Odometry, 'odom', on_odom, 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    deadline = time.monotonic() + args.timeout
    try:
        while not stop.is_set() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        usage = resource.getrusage(resource.RUSAGE_SELF)
        write_json(args.out, {'joint_steps': joint_steps, 'joint_arrivals': joint_arrivals,
                              'odom_steps': odom_steps,
                              'cpu_s': usage.ru_utime + usage.ru_stime
                              - (first_cpu[0] if first_cpu else 0.0)})
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()


def role_latency(args):
    """
    Publish alternating cmd_vel and time each until joint_states shows the wheel follow.

    Every ``args.period`` s a new command of +/-``args.speed`` m/s is published;
    its latency is the wall time from just before ``publish`` to the arrival of
    the first joint_states whose left wheel velocity has the command's sign and
    at least half its magnitude. Also reads the node's CPU time over the run.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from geometry_msgs.msg import Twist
    from sensor_msgs.msg import JointState

    stop = stop_flag()
    init_ros(args.domain)
    node = rclpy.create_node('bench_latency')
    publisher = node.create_publisher(Twist, 'cmd_vel', 10)
    perf_counter = time.perf_counter
    state = {'index': None, 'pending': None, 'target': 0.0, 'seen': 0}
    latencies, steps, arrivals = [], [], []

    def on_joint_states(msg):
        now = perf_counter()
        state['seen'] += 1
        stamp = msg.header.stamp
        steps.append(round((stamp.sec * 10**9 + stamp.nanosec) * PHYSICS_RATE_HZ / 1e9))
        arrivals.append(now)
        if state['index'] is None:
            state['index'] = list(msg.name).index(LEFT_WHEEL)
        if state['pending'] is None:
            return
        velocity = msg.velocity[state['index']]
        target = state['target']
        if velocity * target > 0.0 and abs(velocity) >= 0.5 * abs(target):
            latencies.append(now - state['pending'])
            state['pending'] = None

    node.create_subscription(JointState, 'joint_states', on_joint_states, 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        deadline = time.monotonic() + 30.0
        while publisher.get_subscription_count() < 1 or state['seen'] < 10:
            if time.monotonic() > deadline or stop.is_set():
                raise SystemExit('latency: the simulator never appeared')
            executor.spin_once(timeout_sec=0.05)
        cpu0, wall0 = process_cpu_s(args.node_pid), perf_counter()
        steps.clear()
        arrivals.clear()
        missed, sign = 0, -1.0
        next_publish = perf_counter()
        end = next_publish + args.duration
        while not stop.is_set():
            now = perf_counter()
            if now >= next_publish:
                if now >= end:
                    break
                if state['pending'] is not None:
                    missed += 1
                sign = -sign
                command = Twist()
                command.linear.x = sign * args.speed
                state['target'] = command.linear.x / WHEEL_RADIUS_M
                state['pending'] = perf_counter()
                publisher.publish(command)
                next_publish += args.period
            executor.spin_once(timeout_sec=max(0.0, min(next_publish - perf_counter(), 0.05)))
        cpu1, wall1 = process_cpu_s(args.node_pid), perf_counter()
        publisher.publish(Twist())
        write_json(args.out, {'latencies_s': latencies, 'missed': missed,
                              'node_cpu_share': (cpu1 - cpu0) / (wall1 - wall0),
                              'steps': steps, 'arrivals': arrivals})
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()


# -- measurements run by the bench ---------------------------------------------------

def measure_fidelity(work, domain_id, sim_seconds, publish_rate):
    """Real-time run: harness process (node) plus a subscriber process; return the summary."""
    harness_out = os.path.join(work, f'harness_{publish_rate:g}.json')
    subscriber_out = os.path.join(work, f'subscriber_{publish_rate:g}.json')
    harness_log = os.path.join(work, f'harness_{publish_rate:g}.log')
    subscriber_log = os.path.join(work, f'subscriber_{publish_rate:g}.log')
    subscriber = harness = None
    try:
        subscriber = start_role('subscriber', domain_id, subscriber_log,
                                '--out', subscriber_out, '--timeout', sim_seconds + 60)
        harness = start_role('harness', domain_id, harness_log, '--out', harness_out,
                             '--sim-seconds', sim_seconds, '--publish-rate', publish_rate)
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
    published = (node['steps'] if not publish_rate
                 else int(node['steps'] * publish_rate / PHYSICS_RATE_HZ))
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
        'cpu_share': node['cpu_s'] / node['wall_s'],
        'involuntary_switches': node['involuntary_switches'],
        'joint_states_received': sum(1 for s in received['joint_steps'] if s >= 1),
        'odom_received': sum(1 for s in received['odom_steps'] if s >= 1),
        'published': published,
        'delivery_p50_ms': percentile(delivery_ms, 50),
        'delivery_p99_ms': percentile(delivery_ms, 99),
        'subscriber_cpu_share': received['cpu_s'] / node['wall_s'],
        'system_busy_cores': node['load']['busy_cores'],
        'steal_cores': node['load']['steal_cores'],
        # Cores other processes on the machine kept busy during the run.
        'other_load_cores': max(0.0, node['load']['busy_cores'] - node['cpu_s'] / node['wall_s']
                                - received['cpu_s'] / node['wall_s']),
    }


def measure_latency(work, domain_id, duration_s, period_s, speed):
    """Command latency against the node as a subprocess at real time."""
    out = os.path.join(work, 'latency.json')
    log = os.path.join(work, 'latency.log')
    sim_log = os.path.join(work, 'sim_latency.log')
    sim = probe = None
    try:
        # Without the acceleration ramp: this measures the bridge, not how long the
        # wheels take to reverse at 1 m/s^2 (2 x 0.2 m/s / 1 m/s^2 = 0.4 s by design).
        sim = start_sim(domain_id, sim_log, real_time_factor=1.0,
                        max_linear_acceleration=0.0, max_angular_acceleration=0.0)
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


class ArrivalSubscriber:
    """A joint_states subscriber in a context of its own that records arrival times."""

    def __init__(self, domain_id, name):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from sensor_msgs.msg import JointState
        self.context = Context()
        init_ros(domain_id, self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.received = []
        self.node.create_subscription(
            JointState, 'joint_states',
            lambda msg: self.received.append(time.perf_counter()), 10)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def close(self):
        """Stop the executor, destroy the node, shut the context down."""
        import rclpy
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def startup_once(work, domain_id, tag, subscriber=None):
    """
    Seconds from Popen of the simulator to the first joint_states received.

    ``subscriber`` is an :class:`ArrivalSubscriber` kept across runs; by
    default a fresh one is made just before the Popen.
    """
    own = subscriber is None
    if own:
        subscriber = ArrivalSubscriber(domain_id, 'bench_startup')
    executor, received = subscriber.executor, subscriber.received
    received.clear()
    log = os.path.join(work, f'sim_startup_{tag}.log')
    sim = None
    try:
        start = time.perf_counter()
        sim = start_sim(domain_id, log)
        deadline = time.monotonic() + 20.0
        while not received and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.01)
        if not received:
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
    subscriber = ArrivalSubscriber(domain_id, 'bench_startup_kept')
    executor = subscriber.executor
    restart_times = []
    try:
        for i in range(restarts + 1):
            elapsed = startup_once(work, domain_id, f'kept{i}', subscriber)
            if i:  # the first start is not a restart
                restart_times.append(elapsed)
            # Drop messages still queued from this run before the next one starts.
            drain_until = time.monotonic() + 0.3
            while time.monotonic() < drain_until:
                executor.spin_once(timeout_sec=0.05)
    finally:
        subscriber.close()
    return {'runs_s': times, 'median_s': statistics.median(times),
            'restarts_s': restart_times}


def measure_subprocess_rtf0(work, domain_id, window_s, publish_rate):
    """
    Steps/s of the node run as a subprocess at real_time_factor 0, from /clock stamps.

    A keep-last-1 best-effort subscriber samples the newest /clock at the start
    and end of a window without spinning in between, so this process does not
    compete with the node for CPU while it runs flat out.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    context = Context()
    init_ros(domain_id, context)
    node = rclpy.create_node('bench_clock', context=context)
    latest = []
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
    node.create_subscription(
        Clock, '/clock',
        lambda msg: latest.append((msg.clock.sec + msg.clock.nanosec * 1e-9,
                                   time.perf_counter())), qos)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    log = os.path.join(work, f'sim_rtf0_{publish_rate:g}.log')
    sim = None

    def sample():
        latest.clear()
        deadline = time.monotonic() + 5.0
        while len(latest) < 2 and time.monotonic() < deadline:  # the 1st may be queued
            executor.spin_once(timeout_sec=0.05)
        if len(latest) < 2:
            raise RuntimeError('no /clock from the simulator:\n' + log_tail(log))
        return latest[-1]

    try:
        sim = start_sim(domain_id, log, real_time_factor=0.0, publish_rate=publish_rate)
        deadline = time.monotonic() + 20.0
        while not latest and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        time.sleep(0.5)
        first = sample()
        time.sleep(window_s)
        last = sample()
    finally:
        if sim is not None:
            stop_process(sim)
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return (last[0] - first[0]) / (last[1] - first[1]) * PHYSICS_RATE_HZ


def steps_per_second(advance, min_s, chunk=60):
    """
    Call ``advance(chunk)`` for ``min_s`` wall seconds; return steps/s by CPU and by wall time.

    The CPU rate divides by this thread's CPU time, so time the scheduler
    gives to other processes on a shared machine does not count as our cost.
    """
    steps, start, cpu_start = 0, time.perf_counter(), time.thread_time()
    while True:
        advance(chunk)
        steps += chunk
        elapsed = time.perf_counter() - start
        if elapsed >= min_s:
            return steps / (time.thread_time() - cpu_start), steps / elapsed


def make_inprocess_node(context, name, urdf='', publish_rate=0.0):
    """Build a SimNode at rtf 0 in ``context`` under the namespace ``/bench_<name>``."""
    from rclpy.logging import LoggingSeverity, set_logger_level
    from rclpy.parameter import Parameter
    # Quieten the 'no default wheel joints' warning of the chain robots.
    set_logger_level(f'bench_{name}.r2d2_sim', LoggingSeverity.ERROR)
    with silenced_stdout():
        from r2d2_sim.node import SimNode
        return SimNode(context=context, namespace=f'/bench_{name}', parameter_overrides=[
            Parameter('real_time_factor', value=0.0),
            Parameter('publish_rate', value=float(publish_rate)),
            Parameter('urdf', value=urdf)])


def measure_inprocess(work, domain_id, reps, min_s):
    """
    Bridge overhead and scaling: SimNode.advance against raw stepping, interleaved.

    Each world has a node of its own; 'raw' steps a node's world directly with
    the cached ``stepSimulation`` (SimWorld.step), the same world and settings
    without the bridge. One round measures every configuration once; the
    medians of ``reps`` rounds are returned as steps per CPU second of the
    stepping thread (and per wall second).
    """
    import rclpy
    from rclpy.context import Context

    context = Context()
    init_ros(domain_id, context)
    nodes, configs = [], []
    subscriber = None
    try:
        raw = make_inprocess_node(context, 'raw')
        nodes.append(raw)
        configs.append(('raw', raw.world.step))
        for rate in PUBLISH_RATES_HZ:
            node = make_inprocess_node(context, f'rate{rate:g}', publish_rate=rate)
            nodes.append(node)
            configs.append((f'node@{rate:g}', node.advance))
        # The same every-step node with another process subscribed to joint_states and odom.
        listened = make_inprocess_node(context, 'listened')
        nodes.append(listened)
        configs.append(('node@240+subscriber', listened.advance))
        subscriber = start_role('subscriber', domain_id, os.path.join(work, 'sub_inproc.log'),
                                '--namespace', '/bench_listened', '--timeout', 600,
                                '--out', os.path.join(work, 'sub_inproc.json'))
        for joints in CHAIN_JOINTS:
            path = os.path.join(work, f'chain{joints}.urdf')
            with open(path, 'w', encoding='utf-8') as urdf:
                urdf.write(chain_urdf(joints))
            # Raw and node step the same world (an every-step node does not mind
            # raw steps in between), so world-to-world differences cancel.
            chain_node = make_inprocess_node(context, f'chain{joints}', urdf=path)
            nodes += [chain_node, chain_node]
            configs.append((f'chain{joints}:raw', chain_node.world.step))
            configs.append((f'chain{joints}:node', chain_node.advance))
        joints_published = {name: len(node.world.movable_joints())
                            for (name, _), node in zip(configs, nodes)}
        deadline = time.monotonic() + 30.0
        while (listened.count_subscribers('joint_states') < 1
               or listened.count_subscribers('odom') < 1):
            if time.monotonic() > deadline:
                raise RuntimeError('no subscriber process appeared:\n'
                                   + log_tail(os.path.join(work, 'sub_inproc.log')))
            time.sleep(0.02)
        for _, advance in configs:  # warm-up: the robots settle, code paths get hot
            advance(240)
        samples = {name: [] for name, _ in configs}
        wall_samples = {name: [] for name, _ in configs}
        for _ in range(reps):
            for name, advance in configs:
                cpu_rate, wall_rate = steps_per_second(advance, min_s)
                samples[name].append(cpu_rate)
                wall_samples[name].append(wall_rate)
    finally:
        if subscriber is not None:
            stop_process(subscriber)
        for node in {id(node): node for node in nodes}.values():
            node.destroy_node()
        rclpy.try_shutdown(context=context)
    return {'median_steps_per_s': {name: statistics.median(v) for name, v in samples.items()},
            'median_wall_steps_per_s': {name: statistics.median(v)
                                        for name, v in wall_samples.items()},
            'samples_steps_per_s': samples, 'samples_wall_steps_per_s': wall_samples,
            'joints_published': joints_published}


# -- report -------------------------------------------------------------------------

def status(ok):
    """Return PASS or MISS."""
    return 'PASS' if ok else 'MISS'


def build_table(results):
    """Turn the measurements into rows of (section, metric, value, target, status)."""
    rows = []
    fid = results['fidelity']
    rate_error = abs(fid['node_rtf'] - 1.0)
    rows += [
        ('1 fidelity', f'physics rate, node clock ({fid["sim_seconds"]:g} s sim, '
         f'publish every step)', f'{fid["node_rate_hz"]:.2f} Hz (rtf {fid["node_rtf"]:.5f})',
         'within 0.5% of 240 Hz', status(rate_error <= TARGET_RATE_ERROR)),
        ('1 fidelity', 'physics rate, subscriber (stamps vs arrival)',
         f'rtf {fid["subscriber_rtf"]:.5f}', 'within 0.5%',
         status(abs(fid['subscriber_rtf'] - 1.0) <= TARGET_RATE_ERROR)),
        ('1 fidelity', 'tick jitter mean / p50 (wake - deadline)',
         f'{fid["jitter_mean_ms"]:.3f} / {fid["jitter_p50_ms"]:.3f} ms', '', ''),
        ('1 fidelity', 'tick jitter p99', f'{fid["jitter_p99_ms"]:.3f} ms',
         f'< {TARGET_JITTER_P99_MS} ms', status(fid['jitter_p99_ms'] < TARGET_JITTER_P99_MS)),
        ('1 fidelity', 'tick jitter max', f'{fid["jitter_max_ms"]:.3f} ms '
         f'({fid["late_over_1ms"]} ticks > 1 ms)', '', ''),
        ('1 fidelity', 'node process CPU (of one core)', f'{100 * fid["cpu_share"]:.1f} %',
         f'< {100 * TARGET_CPU_SHARE:g} %', status(fid['cpu_share'] < TARGET_CPU_SHARE)),
        ('1 fidelity', 'tick cost p50 in the paced loop: advance / physics alone',
         f'{1e3 * fid["step_cost_p50_ms"]:.0f} / {1e3 * fid["physics_cost_p50_ms"]:.0f} us',
         '', ''),
        ('1 fidelity', 'subscriber CPU; other processes; steal (cores)',
         f'{100 * fid["subscriber_cpu_share"]:.1f} %; {fid["other_load_cores"]:.2f}; '
         f'{fid["steal_cores"]:.2f}', 'quiet machine: ~0', ''),
        ('1 fidelity', 'joint_states / odom received of published',
         f'{fid["joint_states_received"]} / {fid["odom_received"]} of {fid["published"]}',
         '', ''),
        ('1 fidelity', 'delivery step start -> subscriber p50 / p99',
         f'{fid["delivery_p50_ms"]:.3f} / {fid["delivery_p99_ms"]:.3f} ms', '', ''),
    ]
    fid50 = results.get('fidelity_50hz')
    if fid50:
        rows += [
            ('1 fidelity', f'@ publish_rate 50 ({fid50["sim_seconds"]:g} s): rate / jitter p99',
             f'rtf {fid50["node_rtf"]:.5f} / {fid50["jitter_p99_ms"]:.3f} ms',
             '0.5% / < 0.3 ms', status(abs(fid50['node_rtf'] - 1.0) <= TARGET_RATE_ERROR
                                       and fid50['jitter_p99_ms'] < TARGET_JITTER_P99_MS)),
            ('1 fidelity', '@ publish_rate 50: node process CPU',
             f'{100 * fid50["cpu_share"]:.1f} %', f'< {100 * TARGET_CPU_SHARE:g} %',
             status(fid50['cpu_share'] < TARGET_CPU_SHARE)),
        ]

    over = results['overhead']
    sps = over['median_steps_per_s']
    wall = over['median_wall_steps_per_s']
    raw = sps['raw']
    every, fifty = sps['node@240'] / raw, sps['node@50'] / raw
    rows += [
        ('2 overhead', 'raw PyBullet steps/s, same world (CPU time; wall)',
         f'{raw:,.0f}; {wall["raw"]:,.0f}', '', ''),
        ('2 overhead', 'node publishing every step: steps/s, ratio (wall ratio)',
         f'{sps["node@240"]:,.0f}, {every:.3f} ({wall["node@240"] / wall["raw"]:.3f})',
         f'>= {TARGET_RATIO_EVERY}', status(every >= TARGET_RATIO_EVERY)),
        ('2 overhead', 'node publishing at 50 Hz: steps/s, ratio (wall ratio)',
         f'{sps["node@50"]:,.0f}, {fifty:.3f} ({wall["node@50"] / wall["raw"]:.3f})',
         f'>= {TARGET_RATIO_50HZ}', status(fifty >= TARGET_RATIO_50HZ)),
    ]
    listened = sps['node@240+subscriber']
    rows.append(('2 overhead', 'node every step + subscriber process (joint_states, odom): '
                 'steps/s, ratio (wall ratio)',
                 f'{listened:,.0f}, {listened / raw:.3f} '
                 f'({wall["node@240+subscriber"] / wall["raw"]:.3f})', '', ''))
    for key, label in (('subprocess_rtf0_every', 'every step'),
                       ('subprocess_rtf0_50hz', '50 Hz')):
        if results.get(key):
            rows.append(('2 overhead',
                         f'node subprocess rtf 0, {label}: steps/s (/clock, wall), wall ratio',
                         f'{results[key]:,.0f}, {results[key] / wall["raw"]:.3f}', '', ''))

    lat = results['latency']
    rows += [
        ('3 latency', f'cmd_vel -> joint_states min / p50 ({lat["commands"]} commands, '
         f'{lat["missed"]} missed)', f'{lat["min_ms"]:.2f} / {lat["p50_ms"]:.2f} ms', '', ''),
        ('3 latency', 'cmd_vel -> joint_states p99 / max',
         f'{lat["p99_ms"]:.2f} / {lat["max_ms"]:.2f} ms',
         f'< {TARGET_LATENCY_P99_MS:g} ms (physics period {PHYSICS_PERIOD_MS:.2f} ms)',
         status(lat['p99_ms'] < TARGET_LATENCY_P99_MS and not lat['missed'])),
        ('3 latency', 'node subprocess during it: CPU, rtf',
         f'{100 * lat["subprocess_cpu_share"]:.1f} %, {lat["subprocess_rtf"]:.4f}', '', ''),
    ]

    scale = results['scaling']
    for rate in PUBLISH_RATES_HZ:
        node_us = 1e6 / sps[f'node@{rate:g}']
        rows.append(('4 scaling', f'publish {rate:>3g} Hz: node / raw us per step',
                     f'{node_us:.0f} / {1e6 / raw:.0f} (+{node_us - 1e6 / raw:.0f})', '', ''))
    rows.append(('4 scaling', 'bridge cost = fixed + per publication',
                 f'{scale["rate_fixed_us"]:.1f} + {scale["per_publication_us"]:.1f} us '
                 'x publications/step', '', ''))
    rows.append(('4 scaling', f'R2D2 ({scale["r2d2_joints"]} joints + odom): bridge us/step',
                 f'+{scale["r2d2_overhead_us"]:.0f}', '', ''))
    for joints in CHAIN_JOINTS:
        node_us = 1e6 / sps[f'chain{joints}:node']
        raw_us = 1e6 / sps[f'chain{joints}:raw']
        rows.append(('4 scaling', f'chain {joints} joints: node / raw us per step',
                     f'{node_us:.0f} / {raw_us:.0f} (+{node_us - raw_us:.0f})', '', ''))
    rows.append(('4 scaling', 'bridge cost vs joints (chains, every step)',
                 f'{scale["joint_fixed_us"]:.1f} + {scale["per_joint_us"]:.2f} us x joints',
                 '', ''))

    start = results['startup']
    rows.append(('5 start-up', f'Popen -> first joint_states (fresh subscriber), median of '
                 f'{len(start["runs_s"])}',
                 f'{start["median_s"]:.3f} s ('
                 + ', '.join(f'{t:.3f}' for t in start['runs_s']) + ')',
                 f'< {TARGET_STARTUP_S:g} s', status(start['median_s'] < TARGET_STARTUP_S)))
    if start['restarts_s']:
        rows.append(('5 start-up', 'restart while a subscriber stays up (Fast DDS re-discovery)',
                     ', '.join(f'{t:.3f}' for t in start['restarts_s']) + ' s', '', ''))
    return rows


def scaling_summary(overhead):
    """Fit the bridge cost against publications per step and against published joints."""
    sps = overhead['median_steps_per_s']
    raw_us = 1e6 / sps['raw']
    fractions = [rate / PHYSICS_RATE_HZ for rate in PUBLISH_RATES_HZ]
    extra = [1e6 / sps[f'node@{rate:g}'] - raw_us for rate in PUBLISH_RATES_HZ]
    rate_fixed, per_publication = fit_line(fractions, extra)
    joint_extra = [1e6 / sps[f'chain{j}:node'] - 1e6 / sps[f'chain{j}:raw']
                   for j in CHAIN_JOINTS]
    joint_fixed, per_joint = fit_line(list(CHAIN_JOINTS), joint_extra)
    return {'rate_fixed_us': rate_fixed, 'per_publication_us': per_publication,
            'bridge_us_by_rate': dict(zip([f'{r:g}' for r in PUBLISH_RATES_HZ], extra)),
            'joint_fixed_us': joint_fixed, 'per_joint_us': per_joint,
            'bridge_us_by_chain_joints': dict(zip(map(str, CHAIN_JOINTS), joint_extra)),
            'r2d2_joints': overhead['joints_published']['node@240'],
            'r2d2_overhead_us': extra[0]}


def print_table(rows, header):
    """Print the rows aligned, under ``header`` lines."""
    widths = [max(len(str(row[i])) for row in rows) for i in range(5)]
    print('\n'.join(header))
    print('-' * (sum(widths) + 8))
    section = None
    for row in rows:
        cells = list(row)
        if cells[0] == section:
            cells[0] = ''
        else:
            section = cells[0]
        print('  '.join(str(c).ljust(w) for c, w in zip(cells, widths)).rstrip())


def run_bench(args):
    """Measure everything once and write bench/results.json."""
    quick = args.quick
    plan = {
        'fidelity_sim_s': 10.0 if quick else 60.0,
        'fidelity_50hz_sim_s': 0.0 if quick else 10.0,
        'latency_s': 5.0 if quick else 10.0,
        'latency_period_s': 0.25, 'latency_speed_m_s': 0.2,
        'startup_runs': 3,
        'startup_restarts': 0 if quick else 2,
        'rtf0_window_s': 1.0 if quick else 2.0,
        'inprocess_reps': 3 if quick else 7,
        'inprocess_min_s': 0.15 if quick else 0.3,
    }
    base = args.domain
    began = time.monotonic()
    results = {'background_load_before': background_load()}
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

        phase(f'1. real-time fidelity, {plan["fidelity_sim_s"]:g} s simulated')
        results['fidelity'] = measure_fidelity(work, base, plan['fidelity_sim_s'], 0.0)
        if plan['fidelity_50hz_sim_s']:
            phase(f'1b. real-time fidelity at publish_rate 50, '
                  f'{plan["fidelity_50hz_sim_s"]:g} s simulated')
            results['fidelity_50hz'] = measure_fidelity(
                work, base, plan['fidelity_50hz_sim_s'], 50.0)
        phase('3. command latency')
        results['latency'] = measure_latency(work, base + 1, plan['latency_s'],
                                             plan['latency_period_s'],
                                             plan['latency_speed_m_s'])
        phase('5. start-up')
        results['startup'] = measure_startup(work, base + 2, plan['startup_runs'],
                                             plan['startup_restarts'])
        phase('2. node subprocess at rtf 0')
        results['subprocess_rtf0_every'] = measure_subprocess_rtf0(
            work, base + 3, plan['rtf0_window_s'], 0.0)
        if not quick:
            results['subprocess_rtf0_50hz'] = measure_subprocess_rtf0(
                work, base + 3, plan['rtf0_window_s'], 50.0)
        phase('2+4. in-process overhead and scaling')
        results['overhead'] = measure_inprocess(work, base + 4, plan['inprocess_reps'],
                                                plan['inprocess_min_s'])
        results['scaling'] = scaling_summary(results['overhead'])
        phase('done')
    elapsed = time.monotonic() - began
    machine = {'cpu_model': cpu_model(), 'cores': os.cpu_count(),
               'usable_cores': len(os.sched_getaffinity(0)),
               'python': sys.version.split()[0]}
    date = datetime.datetime.now().astimezone().isoformat(timespec='seconds')
    rows = build_table(results)
    header = [f'r2d2_sim benchmark ({"quick" if quick else "full"}), {date}',
              f'{machine["cpu_model"]}, {machine["cores"]} cores, Python {machine["python"]}, '
              f'run took {elapsed:.0f} s; other processes kept '
              f'{results["background_load_before"]["busy_cores"]:.2f} cores busy before it '
              f'and {results["fidelity"]["other_load_cores"]:.2f} during the fidelity run',
              'cores busy per phase, the bench included: ' + ', '.join(
                  f'{name.split(".")[0]}: {busy:.2f}' for name, busy in loads.items())]
    print()
    print_table(rows, header)
    write_json(args.output, {
        'date': date, 'mode': 'quick' if quick else 'full', 'machine': machine,
        'elapsed_s': elapsed, 'plan': plan,
        'table': [dict(zip(('section', 'metric', 'value', 'target', 'status'), row))
                  for row in rows],
        'results': results})
    print(f'\nwrote {args.output}')
    return 0


def main(argv=None):
    """Parse arguments: run the benchmark, or one of its helper roles."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--quick', action='store_true',
                        help='shorter runs (10 s fidelity instead of 60 s)')
    parser.add_argument('--domain', type=int, default=90,
                        help='first of the 5 ROS domain ids the bench uses (default 90)')
    parser.add_argument('--output', default=RESULTS_PATH, help='where to write the JSON')
    parser.add_argument('--wait-quiet', type=float, default=0.0, metavar='SECONDS',
                        help='first wait up to SECONDS for other processes to use < 0.25 cores')
    parser.add_argument('--role', choices=('harness', 'subscriber', 'latency'),
                        help=argparse.SUPPRESS)
    parser.add_argument('--out', help=argparse.SUPPRESS)
    parser.add_argument('--sim-seconds', type=float, default=10.0, help=argparse.SUPPRESS)
    parser.add_argument('--publish-rate', type=float, default=0.0, help=argparse.SUPPRESS)
    parser.add_argument('--timeout', type=float, default=120.0, help=argparse.SUPPRESS)
    parser.add_argument('--duration', type=float, default=10.0, help=argparse.SUPPRESS)
    parser.add_argument('--period', type=float, default=0.25, help=argparse.SUPPRESS)
    parser.add_argument('--speed', type=float, default=0.2, help=argparse.SUPPRESS)
    parser.add_argument('--node-pid', type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument('--namespace', default='/', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    roles = {'harness': role_harness, 'subscriber': role_subscriber, 'latency': role_latency}
    if args.role:
        return roles[args.role](args) or 0
    return run_bench(args)


if __name__ == '__main__':
    sys.exit(main())
