#!/usr/bin/env python3
"""
The benchmark's helper processes; ``run.py`` starts them, they are not meant to be run by hand.

::

    python bench/roles.py harness|subscriber|latency --domain N --out FILE [options]

``harness``
    SimNode in this process at real time, paced by ``run_paced`` as ``main()``
    paces it (with a recording pacer and advance passed in), recording every
    deadline and the wall time around every step.
``subscriber``
    Typed subscriptions on ``joint_states``, ``odom``, ``ground_truth`` and
    ``/clock``, as a Python consumer of the simulator would have them;
    records the step and arrival of each ``joint_states`` and ``/clock``.
``latency``
    Publishes alternating ``cmd_vel`` and times each command until
    ``joint_states`` shows the wheels follow it.

Each writes its JSON to ``--out`` when it ends (SIGINT or SIGTERM, or its own end).
"""

import argparse
import json
import resource
import threading
import time

from common import (
    init_ros, LoadMeter, make_sim_node, PHYSICS_RATE_HZ, process_cpu_s, step_of, write_json)

WHEEL_RADIUS_M = 0.035          # the package URDF's wheels (a command's wheel target is v / r)
LEFT_WHEEL = 'left_front_wheel_joint'
# The state topics a subscriber listens to, and the harness waits for.
STATE_TOPICS = ('joint_states', 'odom', 'ground_truth', '/clock')


def cpu_s():
    """Return this process's user + system CPU seconds."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def spin(executor, stop):
    """Serve callbacks until ``stop`` is set."""
    from rclpy.executors import ExternalShutdownException
    try:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.1)
    except ExternalShutdownException:
        pass


def harness(args):
    """
    Run SimNode at real time as ``main()`` does, recording each tick; write the record.

    ``run_paced`` takes a DeadlinePacer subclass that records the deadline
    each wait aims at and an ``advance`` that records ``perf_counter`` around
    each tick; the world's ``step`` is wrapped (on this instance only) to time
    the physics alone. Starts stepping once a subscriber is on every state
    topic.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from r2d2_sim.model import timing
    from r2d2_sim.apps.cli import stop_on_signals
    from r2d2_sim.apps.sim_node import run_paced

    deadlines, starts, ends, physics = [], [], [], []
    perf_counter = time.perf_counter

    class RecordingPacer(timing.DeadlinePacer):
        """A DeadlinePacer that records the deadline each wait() aims at."""

        def wait(self):
            deadlines.append(self._next)
            return super().wait()  # run_paced yields the lock when it did not sleep

    stop = stop_on_signals()
    init_ros(args.domain)
    params = dict(json.loads(args.params), real_time_factor=1.0)
    node = make_sim_node(None, '/', params, quiet=False)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    spinner = threading.Thread(target=spin, args=(executor, stop), daemon=True)
    spinner.start()
    try:
        deadline = time.monotonic() + 30.0
        while min(node.count_subscribers(topic) for topic in STATE_TOPICS) < 1:
            if time.monotonic() > deadline or stop.is_set():
                raise SystemExit('harness: no subscriber on ' + ', '.join(STATE_TOPICS))
            time.sleep(0.01)
        time.sleep(0.2)  # let the matching settle on both sides
        end_step = round(args.sim_seconds * PHYSICS_RATE_HZ)
        world_step = node.world.step

        def recording_advance(steps):
            starts.append(perf_counter())
            advanced = node.advance_if_running(steps)
            ends.append(perf_counter())
            if node.step_count >= end_step:
                stop.set()
            return advanced

        def recording_step(steps=1):
            begin = perf_counter()
            world_step(steps)
            physics.append(perf_counter() - begin)
        node.world.step = recording_step
        meter = LoadMeter().start()
        usage0, wall0 = resource.getrusage(resource.RUSAGE_SELF), perf_counter()
        run_paced(node, stop, RecordingPacer(1.0 / PHYSICS_RATE_HZ), recording_advance)
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
        spinner.join(timeout=1.0)
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()


def subscriber(args):
    """
    Receive the four state topics until SIGINT; write counts, steps and arrival times.

    ``cpu_s`` is the CPU time from the first message on; a caller that wants
    other windows reads ``/proc/<pid>/stat`` itself.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from nav_msgs.msg import Odometry
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from r2d2_sim.apps.cli import stop_on_signals

    stop = stop_on_signals()
    init_ros(args.domain)
    node = rclpy.create_node('bench_subscriber')
    perf_counter = time.perf_counter
    counts = dict.fromkeys(STATE_TOPICS, 0)
    joint_steps, joint_arrivals, clock_steps, clock_arrivals = [], [], [], []
    first_cpu = []

    def on_joint_states(msg):
        joint_arrivals.append(perf_counter())
        joint_steps.append(step_of(msg.header.stamp))
        counts['joint_states'] += 1
        if not first_cpu:
            first_cpu.append(cpu_s())

    def on_clock(msg):
        clock_arrivals.append(perf_counter())
        clock_steps.append(step_of(msg.clock))
        counts['/clock'] += 1

    def counter(topic):
        def on_message(msg):
            counts[topic] += 1
        return on_message

    node.create_subscription(JointState, 'joint_states', on_joint_states, 10)
    node.create_subscription(Odometry, 'odom', counter('odom'), 10)
    node.create_subscription(Odometry, 'ground_truth', counter('ground_truth'), 10)
    node.create_subscription(Clock, '/clock', on_clock, 10)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    deadline = time.monotonic() + args.timeout
    try:
        while not stop.is_set() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        write_json(args.out, {
            'counts': counts, 'joint_steps': joint_steps, 'joint_arrivals': joint_arrivals,
            'clock_steps': clock_steps, 'clock_arrivals': clock_arrivals,
            'cpu_s': cpu_s() - (first_cpu[0] if first_cpu else 0.0)})
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()


def latency(args):
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
    from r2d2_sim.apps.cli import stop_on_signals

    stop = stop_on_signals()
    init_ros(args.domain)
    node = rclpy.create_node('bench_latency')
    publisher = node.create_publisher(Twist, 'cmd_vel', 10)
    perf_counter = time.perf_counter
    state = {'index': None, 'pending': None, 'target': 0.0, 'seen': 0}
    latencies, steps, arrivals = [], [], []

    def on_joint_states(msg):
        now = perf_counter()
        state['seen'] += 1
        steps.append(step_of(msg.header.stamp))
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


ROLES = {'harness': harness, 'subscriber': subscriber, 'latency': latency}


def main(argv=None):
    """Run one role with its arguments."""
    parser = argparse.ArgumentParser(description=__doc__.strip().split('\n')[0])
    parser.add_argument('role', choices=sorted(ROLES))
    parser.add_argument('--domain', type=int, required=True, help='ROS domain id')
    parser.add_argument('--out', required=True, help='where to write the JSON result')
    parser.add_argument('--params', default='{}',
                        help='harness: node parameters as a JSON object')
    parser.add_argument('--sim-seconds', type=float, default=10.0,
                        help='harness: simulated seconds to run')
    parser.add_argument('--timeout', type=float, default=120.0,
                        help='subscriber: give up after this many wall seconds')
    parser.add_argument('--duration', type=float, default=10.0,
                        help='latency: seconds of commands')
    parser.add_argument('--period', type=float, default=0.25,
                        help='latency: seconds between commands')
    parser.add_argument('--speed', type=float, default=0.2, help='latency: command in m/s')
    parser.add_argument('--node-pid', type=int, default=0,
                        help='latency: the node process, for its CPU time')
    args = parser.parse_args(argv)
    return ROLES[args.role](args) or 0


if __name__ == '__main__':
    raise SystemExit(main())
