"""
Helpers of this project's own tests, on top of the public testing API.

The harnesses, deadline waits, process helpers and ROS domain leases live in
:mod:`r2d2_sim.testing` (the user-facing fixtures in :mod:`r2d2_sim.pytest_plugin`);
what is left here records every message for exact-count checks, or knows this
repository's layout (what needs no ROS, such as ``REPO``, is in ``common``
and re-exported here). Test modules import from here, never from ``conftest``;
the fast tier (model/, physics/, sim/) never imports this module, which loads
rclpy and the node. Below the general helpers: what an in-process test file
and its system/ counterpart share since the tests were split by tier, each
under the name its tests call it by.
"""

import math
from pathlib import Path
import random
import string
import subprocess
from typing import List, Tuple

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
from rcl_interfaces.msg import ParameterType
from rcl_interfaces.srv import (
    DescribeParameters, GetParameters, GetParameterTypes, ListParameters)
from rclpy.parameter import parameter_value_to_python
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Header, String

import common
from common import RATE_HZ, REPO  # noqa: F401 (for the tests)
from r2d2_sim import testing
from r2d2_sim.client import ros_child_env as ros_env, stamp_ns, wait_for  # noqa: F401
from r2d2_sim.ros.node import SimNode
from r2d2_sim.ros.parameters import ROS_TYPES
from r2d2_sim.ros.standard import server as sim_interfaces
from r2d2_sim.testing import (  # noqa: F401 (for the tests)
    RemoteProbe, sim_node_command, stop_process)
from r2d2_sim.model.transforms import quaternion_to_yaw
from r2d2_sim.sim.settings.table import PARAMETERS, PARAMETERS_BY_NAME


def next_domain_id() -> int:
    """Lease a ROS domain id that no other test on this machine uses, until this test ends."""
    lease = testing.lease_domain()
    common.leases.append(lease)
    return lease.domain_id


def start_sim_process(domain_id, *ros_args, command=None):
    """Start the simulator executable in its own process on ``domain_id``, output piped."""
    return subprocess.Popen(sim_node_command(ros_args=ros_args, command=command),
                            env=ros_env(domain_id), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


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
    """A test-side node: publishes cmd_vel, records every message the simulator sends."""

    def __init__(self, ros, sim):
        from rclpy.qos import DurabilityPolicy, QoSProfile
        self.sim = sim
        self.node = ros.create_node('probe', use_sim_time=False)
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


def make_sim(ros, node_kwargs=None, **params):
    """Build the simulator in the harness's context: parameter overrides, SimNode keywords."""
    return ros.add_node(SimNode(context=ros.context,
                                parameter_overrides=testing.parameter_overrides(params),
                                **(node_kwargs or {})),
                        use_sim_time=False)


def latest_truth(sim):
    """Return the simulator's true (x, y, yaw) now."""
    base = sim.simulation.robot.body.base_state()
    return base.position[0], base.position[1], quaternion_to_yaw(*base.orientation)


# -- the determinism schedule: ros/test_control.py and system/test_control_system.py

# (step, linear, angular) commands of the determinism schedule; NaN is refused.
SCHEDULE = [(0, 0.3, 0.0), (40, 0.2, 0.5), (90, 0.0, -0.6), (130, math.nan, 0.0),
            (150, -0.2, 0.3)]
SCHEDULE_STEPS = 200


def _run_schedule_in_process(ros):
    """Drive SCHEDULE through the in-process API; return per-step joint and truth states."""
    sim = make_sim(ros)
    probe = Probe(ros, sim)
    commands = {step: (v, w) for step, v, w in SCHEDULE}
    record = []
    for step in range(SCHEDULE_STEPS):
        if step in commands:
            probe.send(*commands[step])
        sim.advance(1)
        record.append(_snapshot(sim))
    return record


def _snapshot(sim):
    body = sim.simulation.robot.body
    joints = body.joint_states([j.index for j in body.movable_joints()])
    base = body.base_state()
    return (tuple(joints.positions), tuple(joints.velocities), base.position,
            base.orientation, base.linear_velocity, base.angular_velocity)


# -- two robots facing each other: ros/test_fleet.py and system/test_fleet_system.py

FACING = {'a': {}, 'b': {'initial_pose': [2.0, 0.0, math.pi]}}
needs_standard = pytest.mark.skipif(not sim_interfaces.available(),
                                    reason='simulation_interfaces is not built here')


def x_of(odometry):
    """Return an Odometry's x (m)."""
    return odometry.pose.pose.position.x


# -- the node's outputs with sensors on: ros/test_live_view.py, system/test_live_view_system.py

SENSORS = {'scan_rate': 10.0, 'imu_rate': 60.0, 'camera_rate': 10.0, 'camera_width': 32,
           'camera_height': 24}
# Every output the node has with these parameters, and its type.
OUTPUTS = {
    '/clock': 'rosgraph_msgs/msg/Clock', '/joint_states': 'sensor_msgs/msg/JointState',
    '/odom': 'nav_msgs/msg/Odometry', '/ground_truth': 'nav_msgs/msg/Odometry',
    '/tf': 'tf2_msgs/msg/TFMessage', '/tf_static': 'tf2_msgs/msg/TFMessage',
    '/scan': 'sensor_msgs/msg/LaserScan', '/imu': 'sensor_msgs/msg/Imu',
    '/robot_description': 'std_msgs/msg/String',
    '/camera/image_raw': 'sensor_msgs/msg/Image',
    '/camera/camera_info': 'sensor_msgs/msg/CameraInfo',
}
LATCHED = ('/robot_description', '/tf_static')


def stamp_of(msg):
    """Return the stamp (ns) of a message with a header, a Clock's time, a TFMessage's first."""
    if hasattr(msg, 'clock'):
        return stamp_ns(msg.clock)
    if hasattr(msg, 'transforms'):
        return stamp_ns(msg.transforms[0].header.stamp)
    return stamp_ns(msg.header.stamp)


# -- the parameters as ros2 param reads them: ros/ and system/test_parameter_services*.py

NODE = '/r2d2_sim'
TIMEOUT_S = 20.0


def _read_everything(probe):
    """Return {name: (ParameterValue, ParameterDescriptor)} the way ros2 param dump gets it."""
    listed = probe.call(ListParameters, f'{NODE}/list_parameters', ListParameters.Request(),
                        TIMEOUT_S, resend_after_s=2.0)
    names = list(listed.result.names)
    values = probe.call(GetParameters, f'{NODE}/get_parameters',
                        GetParameters.Request(names=names), TIMEOUT_S, resend_after_s=2.0)
    assert len(values.values) == len(names), (
        f'get_parameters returned {len(values.values)} values for {len(names)} names')
    types = probe.call(GetParameterTypes, f'{NODE}/get_parameter_types',
                       GetParameterTypes.Request(names=names), TIMEOUT_S, resend_after_s=2.0)
    assert len(types.types) == len(names)
    described = probe.call(DescribeParameters, f'{NODE}/describe_parameters',
                           DescribeParameters.Request(names=names), TIMEOUT_S,
                           resend_after_s=2.0)
    assert len(described.descriptors) == len(names)
    for name, value, type_ in zip(names, values.values, types.types):
        assert value.type == type_, name
    return {name: (value, descriptor)
            for name, value, descriptor in zip(names, values.values, described.descriptors)}


def _expected(name, overrides):
    """Return the value the node should report: the override, else the table's default."""
    spec = PARAMETERS_BY_NAME[name]
    value = overrides.get(name, spec.default)
    if spec.ros_type == 'double':
        return float(value)
    if spec.ros_type.endswith('_array'):
        return list(value)
    return value


def _check_all(read, overrides=None):
    overrides = overrides or {}
    assert set(PARAMETERS_BY_NAME) <= set(read), set(PARAMETERS_BY_NAME) - set(read)
    for spec in PARAMETERS:
        value, descriptor = read[spec.name]
        assert value.type == ROS_TYPES[spec.ros_type].value, (
            f'{spec.name}: type {value.type}, expected {spec.ros_type}')
        assert value.type != ParameterType.PARAMETER_NOT_SET, spec.name
        got = parameter_value_to_python(value)
        if spec.ros_type.endswith('_array'):
            got = list(got)
        assert got == _expected(spec.name, overrides), spec.name
        assert descriptor.type == value.type, spec.name
        assert descriptor.read_only, spec.name
        assert descriptor.description == spec.description, spec.name
        bounds = spec.bounds
        if spec.ros_type == 'double' and bounds is not None and bounds.zero is None:
            (fp,) = descriptor.floating_point_range
            assert math.isclose(fp.from_value, bounds.low) and \
                math.isclose(fp.to_value, bounds.high), spec.name
        if spec.ros_type == 'integer' and bounds is not None and bounds.zero is None:
            (ir,) = descriptor.integer_range
            assert (ir.from_value, ir.to_value) == (bounds.low, bounds.high), spec.name
    assert read['use_sim_time'][0].type == ParameterType.PARAMETER_BOOL


# -- random message values: ros/test_serialization.py and system/test_serialization_system.py

SPECIAL_STAMPS = [(0, 0), (0, 999_999_999), (2**31 - 1, 999_999_999), (-2**31, 0),
                  (1_800_000_000, 1), (-1, 999_999_999)]
SPECIAL_FLOAT64 = [0.0, -0.0, 1.0, -1.5, math.pi, 1e308, -1e308, 5e-324, -2.5e-310,
                   math.inf, -math.inf, math.nan]


def floats64(rng: random.Random, count: int) -> List[float]:
    """Return ``count`` float64 values, a fifth of them special (NaN, inf, -0.0, tiny, huge)."""
    return [rng.choice(SPECIAL_FLOAT64) if rng.random() < 0.2 else rng.uniform(-1e3, 1e3)
            for _ in range(count)]


def stamp(rng: random.Random) -> Tuple[int, int]:
    """Return (sec, nanosec): the edge cases, or random in the whole int32/nanosecond range."""
    if rng.random() < 0.3:
        return rng.choice(SPECIAL_STAMPS)
    return rng.randrange(-2**31, 2**31), rng.randrange(10**9)


def text(rng: random.Random, length: int) -> str:
    """Return a random ASCII identifier-like string of ``length`` characters."""
    return ''.join(rng.choice(string.ascii_letters + '_/') for _ in range(length))


def header(frame_id: str, sec: int, nanosec: int) -> Header:
    """Return a std_msgs/Header."""
    return Header(frame_id=frame_id, stamp=Time(sec=sec, nanosec=nanosec))
