"""
A subscriber in a process of its own, for tests of publishers in other processes.

    python topic_listener.py SPEC_JSON OUT_JSON

or, from a test, :func:`start_listener` then :func:`read_listener`.

SPEC_JSON: ``{"topics": {name: {"type": "pkg/msg/Type", "durability":
"volatile"|"transient_local", "distinct": N, "count": M}}, "timeout_s": S}``.
Prints ``ready`` once subscribed, then takes raw messages until every topic
has ``distinct`` different payloads and ``count`` (default 0) messages in
all, or the time is up, and writes
``{name: [[monotonic receive time, hex payload], ...]}`` to OUT_JSON. Exit
status 0 when complete, 1 at the deadline. A process of its own because a
Python subscriber sharing the GIL with a fast publisher misses messages.
"""

import importlib
import json
import os
import subprocess
import sys
import time

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile


def main() -> int:
    """Subscribe, collect, write the result."""
    spec = json.loads(sys.argv[1])
    out_path = sys.argv[2]
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    context = Context()
    rclpy.init(context=context)
    received = {name: [] for name in spec['topics']}
    distinct = {name: set() for name in spec['topics']}
    try:
        node = rclpy.create_node('topic_listener', context=context)
        for name, topic in spec['topics'].items():
            package, namespace, type_name = topic['type'].split('/')
            cls = getattr(importlib.import_module(f'{package}.{namespace}'), type_name)
            qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, durability=DurabilityPolicy[
                topic.get('durability', 'volatile').upper()])

            def take(data, name=name):
                received[name].append((time.monotonic(), data.hex()))
                distinct[name].add(data)
            node.create_subscription(cls, name, take, qos, raw=True)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        print('ready', flush=True)
        deadline = time.monotonic() + spec.get('timeout_s', 30.0)

        def complete():
            return all(len(distinct[name]) >= topic['distinct']
                       and len(received[name]) >= topic.get('count', 0)
                       for name, topic in spec['topics'].items())
        while not complete() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        with open(out_path, 'w') as stream:
            json.dump(received, stream)
        return 0 if complete() else 1
    finally:
        rclpy.try_shutdown(context=context)


def start_listener(domain_id, topics, out_path, timeout_s=60.0):
    """Start topic_listener.py and wait until it has subscribed."""
    from r2d2_sim.client import ros_child_env  # the child itself needs no r2d2_sim
    spec = {'topics': topics, 'timeout_s': timeout_s}
    process = subprocess.Popen([sys.executable, __file__, json.dumps(spec), str(out_path)],
                               env=ros_child_env(domain_id), stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    assert process.stdout.readline().strip() == 'ready', process.stderr.read()
    return process


def read_listener(process, out_path, timeout_s):
    """Wait for the listener's exit; return its result {topic: [(time, bytes)]}."""
    try:
        process.wait(timeout=timeout_s)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, f'incomplete: {process.stderr.read()}'
    result = json.loads(out_path.read_text())
    return {topic: [(t, bytes.fromhex(data)) for t, data in messages]
            for topic, messages in result.items()}


if __name__ == '__main__':
    sys.exit(main())
