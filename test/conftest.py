"""Shared fixtures: isolated ROS contexts and domains, deadline waits, subprocess helpers."""

import itertools
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

# Discovery must stay on this host; set before any rclpy.init.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# Domains 1..100 are safe with Fast DDS's port mapping; start from the pid so
# concurrent pytest processes on one machine are unlikely to share one.
_domains = itertools.count(os.getpid() % 100)


def next_domain_id() -> int:
    """Return a ROS domain id not used by earlier tests of this process."""
    return next(_domains) % 100 + 1


def wait_for(condition, timeout_s=10.0, interval_s=0.002):
    """Poll ``condition`` until it returns a truthy value or the deadline passes."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            return value
        time.sleep(interval_s)


class RosHarness:
    """One rclpy context on its own domain, with an executor spinning in a thread."""

    def __init__(self):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        self.domain_id = next_domain_id()
        self.context = Context()
        rclpy.init(context=self.context, domain_id=self.domain_id)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.nodes = []
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        from rclpy.executors import ExternalShutdownException
        try:
            self.executor.spin()
        except ExternalShutdownException:
            pass

    def add(self, node):
        """Register a node with the executor (and for teardown)."""
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def node(self, name):
        """Create a plain probe node in this context."""
        from rclpy.node import Node
        return self.add(Node(name, context=self.context))

    def close(self):
        """Shut down the executor, destroy nodes, shut the context down."""
        import rclpy
        self.executor.shutdown(timeout_sec=2.0)
        self._thread.join(timeout=2.0)
        for node in reversed(self.nodes):
            node.destroy_node()
        rclpy.try_shutdown(context=self.context)


@pytest.fixture
def ros():
    """Provide an isolated ROS harness, torn down after the test."""
    harness = RosHarness()
    try:
        yield harness
    finally:
        harness.close()


def ros_env(domain_id):
    """Return an environment for a ROS subprocess on ``domain_id``, on this host."""
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['PYTHONPATH'] = REPO + os.pathsep + env.get('PYTHONPATH', '')
    env['PYTHONUNBUFFERED'] = '1'
    return env


def start_sim_process(domain_id, *ros_args, command=None):
    """Start the simulator executable in its own process on ``domain_id``."""
    command = command or [sys.executable, '-m', 'r2d2_sim.node']
    args = list(command) + (['--ros-args', *ros_args] if ros_args else [])
    return subprocess.Popen(args, env=ros_env(domain_id), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def stop_process(process, sig=signal.SIGINT, timeout_s=10.0):
    """Send ``sig``, wait for exit, kill as a last resort; return (code, stdout, stderr)."""
    if process.poll() is None:
        process.send_signal(sig)
    try:
        out, err = process.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
    return process.returncode, out, err
