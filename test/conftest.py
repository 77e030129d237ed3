"""Shared fixtures: isolated ROS contexts and domains, deadline waits, subprocess helpers."""

import itertools
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from r2d2_sim.kinematics import quaternion_to_yaw
from r2d2_sim.node import SimNode
from r2d2_sim.testing import ros_child_env as ros_env, spin_until

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


def start_sim_process(domain_id, *ros_args, command=None):
    """Start the simulator executable in its own process on ``domain_id``."""
    command = command or [sys.executable, '-m', 'r2d2_sim']
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


def simulators_in_domain(domain_id):
    """Return the pids of ``python -m r2d2_sim`` processes running with this ROS_DOMAIN_ID."""
    pids = []
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / 'cmdline').read_bytes().split(b'\0')
            environ = (entry / 'environ').read_bytes().split(b'\0')
        except OSError:  # gone, or not ours
            continue
        if b'r2d2_sim' in cmdline and f'ROS_DOMAIN_ID={domain_id}'.encode() in environ:
            pids.append(int(entry.name))
    return pids


RATE_HZ = 240


def drive_forward_until(spin_until, publisher, truth, distance_m, timeout_s, speed_m_s=0.3):
    """
    Publish a forward cmd_vel while spinning until ground truth x grows by ``distance_m``.

    ``truth`` is the list a ground_truth subscription appends to; returns
    ``spin_until``'s verdict (False when the deadline passed first).
    """
    x0 = truth[-1].pose.pose.position.x
    command = Twist()
    command.linear.x = speed_m_s

    def moved():
        publisher.publish(command)
        return truth[-1].pose.pose.position.x - x0 > distance_m
    return spin_until(moved, timeout_s)


class Probe:
    """A test-side node: publishes cmd_vel, records everything the simulator says."""

    def __init__(self, ros, sim):
        from rclpy.qos import DurabilityPolicy, QoSProfile
        self.sim = sim
        self.node = ros.node('probe')
        self.messages = {'joint_states': [], 'odom': [], 'ground_truth': [], 'clock': [],
                         'robot_description': []}
        node = self.node
        node.create_subscription(JointState, 'joint_states',
                                 self.messages['joint_states'].append, 100)
        node.create_subscription(Odometry, 'odom', self.messages['odom'].append, 100)
        node.create_subscription(Odometry, 'ground_truth',
                                 self.messages['ground_truth'].append, 100)
        node.create_subscription(Clock, '/clock', self.messages['clock'].append, 100)
        node.create_subscription(
            String, 'robot_description', self.messages['robot_description'].append,
            QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.cmd_pub = node.create_publisher(Twist, 'cmd_vel', 10)
        assert wait_for(lambda: self.cmd_pub.get_subscription_count() > 0), 'no cmd_vel link'

    def send(self, linear=0.0, angular=0.0, **fields):
        """Publish a Twist and wait until the simulator's callback has seen it."""
        msg = Twist()
        msg.linear.x, msg.angular.z = float(linear), float(angular)
        for name, value in fields.items():
            part, axis = name.split('_')
            setattr(getattr(msg, part), axis, value)
        before = self.sim.commands_received
        self.cmd_pub.publish(msg)
        assert wait_for(lambda: self.sim.commands_received > before), 'cmd_vel not received'

    def drive(self, linear, angular, seconds, resend_hz=20):
        """Command a twist for ``seconds`` of simulated time, re-sent at ``resend_hz``."""
        chunk = RATE_HZ // resend_hz
        for _ in range(round(seconds * resend_hz)):
            self.send(linear, angular)
            self.sim.advance(chunk)

    def advance_and_collect(self, steps, chunk=8):
        """Advance in chunks small enough that no published message is dropped."""
        topics = ('clock', 'joint_states', 'odom', 'ground_truth')
        for done in range(0, steps, chunk):
            expected = {t: len(self.messages[t]) + min(chunk, steps - done) for t in topics}
            self.sim.advance(min(chunk, steps - done))
            for topic in topics:
                self.wait_count(topic, expected[topic])

    def wait_count(self, topic, count):
        """Wait until ``count`` messages of ``topic`` have arrived."""
        assert wait_for(lambda: len(self.messages[topic]) >= count), \
            f'{topic}: {len(self.messages[topic])} < {count}'

    def call(self, srv_type, name, request, timeout_s=10.0):
        """Call a service of the simulator and return the response."""
        client = self.node.create_client(srv_type, name)
        assert client.wait_for_service(timeout_sec=timeout_s), f'{name} unavailable'
        future = client.call_async(request)
        assert wait_for(future.done, timeout_s), f'{name} did not answer'
        return future.result()


def make_sim(ros, **params):
    """Build the simulator in the harness's context with parameter overrides."""
    overrides = [Parameter(k, value=v) for k, v in params.items()]
    return ros.add(SimNode(context=ros.context, parameter_overrides=overrides))


@pytest.fixture
def sim(ros):
    """Provide the default simulator."""
    return make_sim(ros)


@pytest.fixture
def probe(ros, sim):
    """Provide a probe node linked to the simulator."""
    return Probe(ros, sim)


def latest_truth(sim):
    """Return the simulator's true (x, y, yaw) now."""
    base = sim.world.base_state()
    return base.position[0], base.position[1], quaternion_to_yaw(*base.orientation)


class RemoteProbe:
    """A probe node in its own context on ``domain_id``, for talking to a sim subprocess."""

    def __init__(self, domain_id, name='remote_probe'):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_until(self, condition, timeout_s):
        """Spin until ``condition()`` holds (True) or the deadline passes (False)."""
        return spin_until(self.executor, condition, timeout_s)

    def close(self):
        """Destroy the node and shut its context down."""
        import rclpy
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
