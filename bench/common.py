"""
Helpers shared by the benchmarks: CPU and load meters, statistics, JSON, processes, nodes.

Importing this module puts the repository first on ``sys.path`` (so the
benchmarks measure this checkout's ``r2d2_sim``) and keeps ROS discovery on
this host (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) before anything
imports rclpy. Nothing here imports rclpy or PyBullet at module level.
"""

import datetime
import functools
import json
import math
import os
import subprocess
import sys
import time

BENCH_DIR = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(BENCH_DIR)
if REPO not in sys.path:
    sys.path.insert(0, REPO)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

ROLES_SCRIPT = os.path.join(BENCH_DIR, 'roles.py')
PHYSICS_RATE_HZ = 240.0

# The sensor outputs, off: throughput and CPU rows measure the state outputs
# alone. Only the parameters this r2d2_sim declares are set (see
# existing_parameters): some of them are being added while the bench exists.
OUTPUTS_OFF = {'scan_rate': 0.0, 'imu_rate': 0.0, 'publish_tf': False, 'camera_rate': 0.0}


# -- statistics --------------------------------------------------------------------

def percentile(values, q):
    """Interpolate linearly the value below which q % (0..100) of ``values`` fall."""
    from r2d2_sim.farm.report import percentile as farm_percentile  # one definition
    return farm_percentile(values, q)


def fit_line(xs, ys):
    """Fit a least-squares line through (xs, ys): return (intercept, slope)."""
    n = len(xs)
    mean_x, mean_y = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mean_x) ** 2 for x in xs)
    sxy = sum((x - mean_x) * (y - mean_y) for x, y in zip(xs, ys))
    slope = sxy / sxx if sxx else math.nan
    return mean_y - slope * mean_x, slope


def status(ok):
    """Return PASS or MISS."""
    return 'PASS' if ok else 'MISS'


def step_of(stamp, rate_hz=PHYSICS_RATE_HZ):
    """Return the physics step of a builtin_interfaces Time stamp."""
    return round((stamp.sec * 10**9 + stamp.nanosec) * rate_hz / 1e9)


# -- the machine -------------------------------------------------------------------

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


def machine_info():
    """Return the CPU model, core counts and Python version of this machine."""
    return {'cpu_model': cpu_model(), 'cores': os.cpu_count(),
            'usable_cores': len(os.sched_getaffinity(0)), 'python': sys.version.split()[0]}


def local_date():
    """Return the local date and time in ISO format, to the second."""
    return datetime.datetime.now().astimezone().isoformat(timespec='seconds')


def process_cpu_s(pid):
    """Return user + system CPU seconds of process ``pid`` from /proc/<pid>/stat."""
    with open(f'/proc/{pid}/stat', encoding='utf-8') as stat:
        fields = stat.read().rsplit(')', 1)[1].split()
    # fields[0] is field 3 (state); utime and stime are fields 14 and 15.
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def child_pids(pid):
    """Return the pids of ``pid``'s children (``/proc/<pid>/task/*/children``)."""
    children = []
    for task in os.listdir(f'/proc/{pid}/task'):
        try:
            with open(f'/proc/{pid}/task/{task}/children', encoding='utf-8') as listing:
                children += [int(child) for child in listing.read().split()]
        except OSError:  # the thread ended meanwhile
            pass
    return children


def process_tree_cpu_s(pid):
    """Return the CPU seconds of ``pid`` and its children (an outputs process)."""
    total = process_cpu_s(pid)
    for child in child_pids(pid):
        try:
            total += process_cpu_s(child)
        except OSError:
            pass
    return total


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

    def __init__(self):
        self._begin = None

    def start(self):
        """Begin a measurement window; return self."""
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


# -- processes ---------------------------------------------------------------------

def start_process(args, domain_id, log_path):
    """Start ``args`` on ``domain_id`` as a ChildProcess, stdout and stderr into ``log_path``."""
    from r2d2_sim.client import ros_child_env
    from r2d2_sim.testing import ChildProcess
    return ChildProcess(args, ros_child_env(domain_id), cwd=REPO, log_path=log_path).start()


def start_sim(domain_id, log_path, **params):
    """Start ``python -m r2d2_sim`` with ``params`` as ROS parameters."""
    from r2d2_sim.testing import sim_node_command
    return start_process(sim_node_command(params), domain_id, log_path)


def start_role(role, domain_id, log_path, *extra):
    """Start ``bench/roles.py`` in a helper role (see that module)."""
    args = [sys.executable, ROLES_SCRIPT, role, '--domain', str(domain_id), *map(str, extra)]
    return start_process(args, domain_id, log_path)


def stop_process(process, timeout_s=5.0):
    """SIGINT a ChildProcess, wait for it, kill it as a last resort; return its exit code."""
    return process.stop(timeout_s=timeout_s).returncode


def wait_process(process, timeout_s):
    """Wait up to ``timeout_s`` for a ChildProcess to exit by itself; True if it did."""
    try:
        process.process.wait(timeout=timeout_s)
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


# -- stepping side by side ---------------------------------------------------------

def alternate(advances, min_s, chunk=60):
    """
    Step each of ``advances`` ``chunk`` steps in turn until each had ``min_s`` s; return rates.

    Returns (steps per CPU second of this thread, steps per wall second) for
    each. Taking turns every chunk (about 10 ms) puts every configuration of a
    group under the same load from other processes; thread CPU time leaves
    out the time the scheduler gives to them.
    """
    thread_time, perf_counter = time.thread_time, time.perf_counter
    cpu, wall = [0.0] * len(advances), [0.0] * len(advances)
    steps, end = 0, perf_counter() + min_s * len(advances)
    while perf_counter() < end:
        for i, advance in enumerate(advances):
            wall0, cpu0 = perf_counter(), thread_time()
            advance(chunk)
            cpu[i] += thread_time() - cpu0
            wall[i] += perf_counter() - wall0
        steps += chunk
    return [steps / c for c in cpu], [steps / w for w in wall]


def raw_stepper(world):
    """
    Return ``advance(steps)`` that steps ``world``'s PyBullet client and nothing else.

    As SimWorld.step does, but without counting the steps: the node's
    schedules (sensor rates) do not see them, so raw and node stepping can
    alternate on one world and world-to-world differences cancel.
    """
    import pybullet
    step = functools.partial(pybullet.stepSimulation, physicsClientId=world.client._client)

    def advance(steps):
        for _ in range(steps):
            step()
    return advance


# -- ROS and the node ----------------------------------------------------------------

def init_ros(domain_id, context=None):
    """Initialise rclpy on ``domain_id`` without its signal handlers."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)


def existing_parameters(params):
    """
    Return the entries of ``params`` that this r2d2_sim declares, in their declared types.

    A parameter the node does not declare would only be warned about and
    ignored, so a measurement that needs one checks ``missing_parameters``.
    """
    from r2d2_sim.sim.settings.table import PARAMETERS_BY_NAME
    convert = {'double': float, 'integer': int, 'bool': bool, 'string': str}
    kept = {}
    for name, value in params.items():
        spec = PARAMETERS_BY_NAME.get(name)
        if spec is not None:
            kept[name] = convert.get(spec.ros_type, lambda v: v)(value)
    return kept


def missing_parameters(names):
    """Return those of ``names`` that this r2d2_sim does not declare."""
    from r2d2_sim.sim.settings.table import PARAMETERS_BY_NAME
    return [name for name in names if name not in PARAMETERS_BY_NAME]


def outputs_off():
    """Return the parameters that turn every sensor output off (those that exist)."""
    return existing_parameters(OUTPUTS_OFF)


def make_sim_node(context, namespace, params, quiet=True):
    """
    Build a SimNode in ``context`` (None: the default one) under ``namespace``.

    ``params`` maps parameter names to values. PyBullet's banner is silenced;
    with ``quiet`` the node logs errors only (a chain robot has no wheels to
    warn about).
    """
    from rclpy.logging import LoggingSeverity, set_logger_level
    from rclpy.parameter import Parameter
    from r2d2_sim.physics.stdio import silenced_output
    if quiet:
        prefix = '.'.join(part for part in namespace.split('/') if part)
        set_logger_level(f'{prefix}.r2d2_sim' if prefix else 'r2d2_sim',
                         LoggingSeverity.ERROR)
    with silenced_output():
        from r2d2_sim.ros.node import SimNode
        return SimNode(context=context, namespace=namespace, parameter_overrides=[
            Parameter(name, value=value) for name, value in params.items()])


# Topics a bench's takers leave alone: latched ones (published once), ROS's own.
NOT_TAKEN = ('/tf_static', 'robot_description', '/parameter_events', '/rosout')


def take_every_topic(context, nodes):
    """
    Subscribe, in ``context``, to every topic the simulator ``nodes`` publish; return the node.

    The outputs build and publish only what someone takes (issue 38), so a
    bench that measures "publishing every step" in one process must take
    every message: one subscription per topic (raw, best effort, depth 1,
    which matches reliable publishers too), on a node nobody spins, so the
    messages arrive and wait. Latched topics (``/tf_static``,
    ``robot_description``) are published once and are left out.
    """
    import rclpy
    from rclpy.qos import qos_profile_sensor_data
    taker = rclpy.create_node('bench_taker', context=context)
    publishers = {}
    for node in nodes:
        for owner in [node] + [robot.node for robot in node.robots]:
            for publisher in owner.all_publishers():  # the outputs process's too
                if not publisher.topic_name.endswith(NOT_TAKEN):
                    publishers.setdefault(publisher.topic_name, publisher)
    for topic, publisher in sorted(publishers.items()):
        taker.create_subscription(publisher.msg_type, topic, lambda _: None,
                                  qos_profile_sensor_data, raw=True)
    deadline = time.monotonic() + 10.0
    while not all(p.get_subscription_count() for p in publishers.values()):
        if time.monotonic() > deadline:
            raise RuntimeError("the bench's subscriptions did not match the simulator's topics")
        time.sleep(0.01)
    return taker


class TopicTaker:
    """
    Another context on ``domain_id`` taking every topic a simulator process publishes.

    For real-time rows that should pay for every message: the outputs build
    only what someone takes. Each topic with a publisher (but the latched
    ones, the parameter events and the log) gets a raw best-effort
    subscription of depth 1 on a node nobody spins; the messages arrive (Fast
    DDS's own threads receive them) and wait. ``wait(topics)`` returns once
    ``topics`` topics are matched.
    """

    def __init__(self, domain_id):
        import rclpy
        from rclpy.context import Context
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node('bench_topic_taker', context=self.context)
        self.subscriptions = {}

    def wait(self, topics, timeout_s=30.0):
        """Subscribe to every published topic until ``topics`` of them are matched."""
        from rclpy.qos import qos_profile_sensor_data
        from r2d2_sim.recording.reader import message_class
        deadline = time.monotonic() + timeout_s
        while True:
            for topic, types in self.node.get_topic_names_and_types():
                if (topic in self.subscriptions or topic.endswith(NOT_TAKEN)
                        or '/_action/' in topic or not self.node.count_publishers(topic)):
                    continue
                self.subscriptions[topic] = self.node.create_subscription(
                    message_class(types[0]), topic, lambda _: None, qos_profile_sensor_data,
                    raw=True)
            matched = sum(1 for s in self.subscriptions.values() if s.get_publisher_count())
            if matched >= topics:
                return matched
            if time.monotonic() > deadline:
                raise RuntimeError(f'only {matched} of {topics} topics to take appeared')
            time.sleep(0.05)

    def close(self):
        """Leave the domain."""
        import rclpy
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
