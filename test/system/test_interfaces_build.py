"""
The interface packages built by tools/build_interfaces.sh work from rclpy.

tf2_msgs: a TFMessage crosses from one process to another.
simulation_interfaces: every type loads with its type support, every type hash
equals upstream Jazzy 1.5.1's, and a service and the SimulateSteps action
(goal, feedback, result, cancel) work between two processes.

Checked in the venv the suite runs in (``sys.prefix``); a missing package
fails, naming the command that builds it.
"""

import json
import os
from pathlib import Path
import subprocess
import sys
import time

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor

from r2d2_sim import testing
from r2d2_sim.testing.remote import send_request

REPO = Path(__file__).resolve().parent.parent.parent
HASHES = REPO / 'tools' / 'interfaces' / 'simulation_interfaces_hashes.json'
# Wall-clock limit for any one wait on the other process (s).
TIMEOUT_S = 15.0


@pytest.fixture(autouse=True)
def _ros_env(monkeypatch):
    """Keep discovery on this host; make rclpy type-check message fields."""
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    # Read by each generated message module when first imported.
    monkeypatch.setenv('ROS_PYTHON_CHECK_FIELDS', '1')


def _fail_unusable(package, problem):
    pytest.fail('%s is not usable in %s (%s); run: tools/build_interfaces.sh %s %s'
                % (package, sys.prefix, problem, sys.prefix, package), pytrace=False)


def _load(package, kind, name):
    """Return the interface class with its C type support loaded, or fail naming the build."""
    try:
        module = __import__('%s.%s' % (package, kind), fromlist=[name])
        cls = getattr(module, name)
        cls.__class__.__import_type_support__()
        assert cls._TYPE_SUPPORT is not None, 'no type support for %s' % name
        return cls
    except Exception as exc:  # ImportError, or a type support library not found
        problem = '%s: %s' % (type(exc).__name__, exc)
    _fail_unusable(package, problem)


def _child_env(domain_id):
    env = testing.ros_child_env(domain_id)
    env['ROS_PYTHON_CHECK_FIELDS'] = '1'
    return env


class RosPeer:
    """One rclpy context, node and executor on a leased domain, torn down on exit."""

    def __init__(self, name):
        self.lease = testing.lease_domain()
        self.context = Context()
        rclpy.init(context=self.context, domain_id=self.lease.domain_id)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_until(self, condition, timeout_s=TIMEOUT_S):
        """Spin until ``condition()`` holds; False at the deadline."""
        return testing.spin_until(self.executor, condition, timeout_s)

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self.lease.release()


def _start_child(code, domain_id, *args):
    """Run ``code`` in a child process on ``domain_id``; it stops when its stdin closes."""
    return subprocess.Popen(
        [sys.executable, '-c', code, *map(str, args)], env=_child_env(domain_id),
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _finish_child(child):
    """Close the child's stdin, wait for its exit and return its stdout; fail on an error exit."""
    try:
        out, err = child.communicate(input='', timeout=TIMEOUT_S)  # closes stdin
    except subprocess.TimeoutExpired:
        result = testing.stop_process(child)
        pytest.fail('child process did not stop:\n%s%s' % (result.stdout, result.stderr))
    assert child.returncode == 0, 'child exited %d:\n%s%s' % (child.returncode, out, err)
    return out


# -- tf2_msgs ---------------------------------------------------------------------

# A subscriber in a child process: takes the first TFMessage on the topic and
# prints it serialized (CDR, hex), so the parent can compare every field.
TF_CHILD = r'''
import os, sys, time
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from tf2_msgs.msg import TFMessage

topic, timeout_s = sys.argv[1], float(sys.argv[2])
ctx = Context()
rclpy.init(context=ctx, domain_id=int(os.environ['ROS_DOMAIN_ID']))
try:
    node = rclpy.create_node('tf2_msgs_test_sub', context=ctx)
    got = []
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(TFMessage, topic, got.append, qos)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    deadline = time.monotonic() + timeout_s
    while not got and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    if not got:
        print('TIMEOUT: no TFMessage on %s within %.1f s' % (topic, timeout_s), flush=True)
        sys.exit(3)
    print('MSG ' + serialize_message(got[0]).hex(), flush=True)
finally:
    rclpy.try_shutdown(context=ctx)
'''


def _two_transforms(TFMessage):
    """Return a TFMessage with two transforms, every field set to a distinct value."""
    from geometry_msgs.msg import TransformStamped
    msg = TFMessage()
    for i, (parent, child) in enumerate((('odom', 'base_link'), ('base_link', 'head'))):
        t = TransformStamped()
        t.header.stamp.sec = 1700000000 + i
        t.header.stamp.nanosec = 123456789 + i
        t.header.frame_id = parent
        t.child_frame_id = child
        t.transform.translation.x = 0.1 + i
        t.transform.translation.y = -2.5e-7
        t.transform.translation.z = 3.141592653589793 * (i + 1)
        t.transform.rotation.x = 0.0
        t.transform.rotation.y = 0.0
        t.transform.rotation.z = 0.7071067811865476 * (1 - 2 * i)
        t.transform.rotation.w = 0.7071067811865476
        msg.transforms.append(t)
    return msg


def test_tfmessage_crosses_processes():
    """Two transforms published here arrive unchanged in a subscriber process."""
    TFMessage = _load('tf2_msgs', 'msg', 'TFMessage')
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.serialization import deserialize_message

    topic = '/tf2_msgs_build_test_%d' % os.getpid()
    msg = _two_transforms(TFMessage)
    with RosPeer('tf2_msgs_test_pub') as peer:
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        pub = peer.node.create_publisher(TFMessage, topic, qos)
        child = subprocess.Popen(
            [sys.executable, '-c', TF_CHILD, topic, '7'], env=_child_env(peer.lease.domain_id),
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            # Publish (again) whenever a subscriber is matched, until the child
            # has taken one message and exited, or the deadline passes.
            deadline = time.monotonic() + 8.0
            while child.poll() is None and time.monotonic() < deadline:
                if pub.get_subscription_count() > 0:
                    pub.publish(msg)
                time.sleep(0.02)
            try:
                out, err = child.communicate(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                child.kill()
                out, err = child.communicate()
                pytest.fail('subscriber process still running after 8 s\n' + out + err)
        finally:
            if child.poll() is None:
                child.kill()
                child.wait()
    assert child.returncode == 0, 'subscriber exited %d:\n%s%s' % (child.returncode, out, err)
    lines = [line for line in out.splitlines() if line.startswith('MSG ')]
    assert lines, 'no message printed by the subscriber:\n' + out + err
    # Compare messages, not bytes: Fast CDR leaves alignment padding in a
    # serialized message uninitialized, so equal messages may differ there.
    back = deserialize_message(bytes.fromhex(lines[0][4:]), TFMessage)
    assert back == msg, 'sent %r\nreceived %r' % (msg, back)
    assert [t.child_frame_id for t in back.transforms] == ['base_link', 'head']


# -- simulation_interfaces ------------------------------------------------------------


def _expected_hashes():
    with open(HASHES) as f:
        return json.load(f)['type_hashes']


def _interfaces():
    """Return (kind, name) of every msg, srv and action in upstream's list."""
    names = set()
    for type_name in _expected_hashes():
        _, kind, name = type_name.split('/')
        if '_' not in name:  # not a Request, Response, Event, Goal, ... part
            names.add((kind, name))
    return sorted(names)


def test_expected_hash_list_is_complete():
    """The committed list has the 15 msgs, 22 srvs and 1 action of Jazzy 1.5.1 and their parts."""
    kinds = [kind for kind, _ in _interfaces()]
    assert (kinds.count('msg'), kinds.count('srv'), kinds.count('action')) == (15, 22, 1)
    # A srv adds _Request, _Response, _Event; an action _Goal, _Result,
    # _Feedback, _FeedbackMessage and _SendGoal, _GetResult with their 3 parts.
    assert len(_expected_hashes()) == 15 + 22 * 4 + 13


def test_every_simulation_interfaces_type_loads():
    """Each msg, srv and action imports with its C type support; constants, defaults are there."""
    for kind, name in _interfaces():
        _load('simulation_interfaces', kind, name)
    from simulation_interfaces.action import SimulateSteps
    from simulation_interfaces.msg import (
        EntityCategory, Result, SimulationState, SimulatorFeatures, SpawnEntity as SpawnRequest,
        SpawnResult)
    from simulation_interfaces.srv import ResetSimulation, SpawnEntity, StepSimulation
    # Field values are checked (with ROS_PYTHON_CHECK_FIELDS=1 set before the
    # module's import, or when asked; the child processes check the former).
    with pytest.raises(AssertionError):
        Result(result=300, check_fields=True)
    assert (Result.RESULT_FEATURE_UNSUPPORTED, Result.RESULT_OK, Result.RESULT_OPERATION_FAILED) \
        == (0, 1, 4)
    assert (SimulatorFeatures.SPAWNING, SimulatorFeatures.STEP_SIMULATION_ACTION,
            SimulatorFeatures.SPAWNING_ENTITIES) == (0, 33, 50)
    assert SimulationState.STATE_PAUSED == 2
    assert EntityCategory.CATEGORY_STATIC_OBJECT == 5
    assert SpawnResult.INVALID_POSE == 109
    assert ResetSimulation.Request.SCOPE_ALL == 255
    assert StepSimulation.Request().steps == 1
    assert Result().result == Result.RESULT_FEATURE_UNSUPPORTED
    # The Jazzy (1.x) layout: flat uri/resource_string in the service, a
    # nested Resource in the message SpawnEntities takes.
    request = SpawnEntity.Request(uri='file:///r2d2.urdf', resource_string='')
    assert request.get_fields_and_field_types()['uri'] == 'string'
    assert SpawnRequest.get_fields_and_field_types()['entity_resource'] \
        == 'simulation_interfaces/Resource'
    assert list(SimulateSteps.Feedback.get_fields_and_field_types()) \
        == ['completed_steps', 'remaining_steps']


def _share_dir(package):
    path = Path(sys.prefix) / 'share' / package
    if path.is_dir():
        return path
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(package))
    except Exception as exc:  # not in the ament index, or no index at all
        problem = 'no share/%s: %s: %s' % (package, type(exc).__name__, exc)
    _fail_unusable(package, problem)


def test_type_hashes_match_upstream():
    """The generated RIHS01 hash of every type equals upstream 1.5.1's (same wire layout)."""
    expected = _expected_hashes()
    built = {}
    for path in sorted(_share_dir('simulation_interfaces').glob('*/*.json')):
        with open(path) as f:
            for entry in json.load(f).get('type_hashes', []):
                if entry['type_name'].startswith('simulation_interfaces/'):
                    built[entry['type_name']] = entry['hash_string']
    wrong = {name: (built.get(name), hash_) for name, hash_ in expected.items()
             if built.get(name) != hash_}
    assert not wrong, 'type hashes differ from upstream (built, expected): %r' % wrong
    assert set(built) == set(expected), 'types not in upstream: %r' % (set(built) - set(expected))
    # What the compiled type support announces on the graph, for each message.
    with RosPeer('hash_probe') as peer:
        for kind, name in _interfaces():
            if kind != 'msg':
                continue
            cls = _load('simulation_interfaces', kind, name)
            topic = '/hash_probe_%s' % name
            peer.node.create_publisher(cls, topic, 1)
            info = peer.node.get_publishers_info_by_topic(topic)
            assert len(info) == 1, topic
            assert str(info[0].topic_type_hash) == expected['simulation_interfaces/msg/' + name]


# A GetSimulatorFeatures server in a child process, until its stdin closes;
# prints how many requests it answered.
SERVICE_CHILD = r'''
import os, sys, threading
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from simulation_interfaces.msg import Result, SimulatorFeatures
from simulation_interfaces.srv import GetSimulatorFeatures

try:
    Result(result=300)
    sys.exit('ROS_PYTHON_CHECK_FIELDS is not in effect')
except AssertionError:
    pass
ctx = Context()
rclpy.init(context=ctx, domain_id=int(os.environ['ROS_DOMAIN_ID']))
served = []

def answer(request, response):
    response.features.features = [SimulatorFeatures.SPAWNING,
                                  SimulatorFeatures.STEP_SIMULATION_ACTION]
    response.features.spawn_formats = ['urdf']
    response.features.custom_info = '{"simulator": "test", "pid": %d}' % os.getpid()
    served.append(request)
    return response

stdin_closed = threading.Event()
threading.Thread(target=lambda: (sys.stdin.read(), stdin_closed.set()), daemon=True).start()
try:
    node = rclpy.create_node('features_server', context=ctx)
    node.create_service(GetSimulatorFeatures, sys.argv[1], answer)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    while not stdin_closed.is_set():
        executor.spin_once(timeout_sec=0.05)
    print('SERVED %d' % len(served), flush=True)
finally:
    rclpy.try_shutdown(context=ctx)
'''


def test_service_across_processes():
    """A GetSimulatorFeatures client here gets the answer of a server in another process."""
    GetSimulatorFeatures = _load('simulation_interfaces', 'srv', 'GetSimulatorFeatures')
    from simulation_interfaces.msg import SimulatorFeatures
    name = '/get_simulator_features_%d' % os.getpid()
    with RosPeer('features_client') as peer:
        child = _start_child(SERVICE_CHILD, peer.lease.domain_id, name)
        try:
            client = peer.node.create_client(GetSimulatorFeatures, name)
            assert peer.spin_until(client.service_is_ready), 'no %s server within %g s' % (
                name, TIMEOUT_S)
            # Sent again after 1 s without a reply: rmw_fastrtps drops a reply when the
            # server has not yet discovered our reply reader 100 ms after the request (a
            # CI run lost one so).
            reply = send_request(client, GetSimulatorFeatures.Request(), peer.spin_until,
                                 TIMEOUT_S, resend_after_s=1.0)
            assert reply is not None, 'no answer within %g s' % TIMEOUT_S
            features = reply.features
        finally:
            out = _finish_child(child)
    assert list(features.features) == [SimulatorFeatures.SPAWNING,
                                       SimulatorFeatures.STEP_SIMULATION_ACTION]
    assert features.spawn_formats == ['urdf']
    assert json.loads(features.custom_info) == {'simulator': 'test', 'pid': child.pid}
    served = [int(line.split()[1]) for line in out.splitlines() if line.startswith('SERVED')]
    assert served and served[0] >= 1, out


# A SimulateSteps action server in a child process, until its stdin closes:
# a goal of N steps publishes feedback after each step (STEP_S apart) and
# succeeds; a cancel request is accepted and ends the goal CANCELED. Prints
# one line per goal.
ACTION_CHILD = r'''
import os, sys, threading, time
import rclpy
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from rclpy.executors import MultiThreadedExecutor
from simulation_interfaces.action import SimulateSteps
from simulation_interfaces.msg import Result

STEP_S = 0.02
try:
    Result(result=300)
    sys.exit('ROS_PYTHON_CHECK_FIELDS is not in effect')
except AssertionError:
    pass
ctx = Context()
rclpy.init(context=ctx, domain_id=int(os.environ['ROS_DOMAIN_ID']))

def execute(goal_handle):
    steps = goal_handle.request.steps
    result = SimulateSteps.Result()
    for done in range(1, steps + 1):
        if goal_handle.is_cancel_requested:
            goal_handle.canceled()
            result.result.result = Result.RESULT_OPERATION_FAILED
            result.result.error_message = 'canceled after %d of %d steps' % (done - 1, steps)
            print('GOAL %d CANCELED after %d' % (steps, done - 1), flush=True)
            return result
        time.sleep(STEP_S)  # one simulation step's work
        goal_handle.publish_feedback(
            SimulateSteps.Feedback(completed_steps=done, remaining_steps=steps - done))
    goal_handle.succeed()
    result.result.result = Result.RESULT_OK
    print('GOAL %d SUCCEEDED' % steps, flush=True)
    return result

stdin_closed = threading.Event()
threading.Thread(target=lambda: (sys.stdin.read(), stdin_closed.set()), daemon=True).start()
try:
    node = rclpy.create_node('simulate_steps_server', context=ctx)
    server = ActionServer(
        node, SimulateSteps, sys.argv[1], execute_callback=execute,
        goal_callback=lambda goal: GoalResponse.ACCEPT,
        cancel_callback=lambda goal_handle: CancelResponse.ACCEPT,
        callback_group=ReentrantCallbackGroup())
    executor = MultiThreadedExecutor(num_threads=2, context=ctx)
    executor.add_node(node)
    while not stdin_closed.is_set():
        executor.spin_once(timeout_sec=0.05)
    server.destroy()
finally:
    rclpy.try_shutdown(context=ctx)
'''


def test_action_across_processes():
    """The SimulateSteps action between processes: goal, feedback, result, a cancel mid-way."""
    SimulateSteps = _load('simulation_interfaces', 'action', 'SimulateSteps')
    from action_msgs.msg import GoalStatus
    from action_msgs.srv import CancelGoal
    from rclpy.action import ActionClient
    from simulation_interfaces.msg import Result
    name = '/simulate_steps_%d' % os.getpid()
    with RosPeer('simulate_steps_client') as peer:
        child = _start_child(ACTION_CHILD, peer.lease.domain_id, name)
        try:
            client = ActionClient(peer.node, SimulateSteps, name)
            assert peer.spin_until(client.server_is_ready), 'no %s server within %g s' % (
                name, TIMEOUT_S)

            # 1. Five steps: accepted, feedback, then the result.
            feedback = []
            sent = client.send_goal_async(SimulateSteps.Goal(steps=5),
                                          feedback_callback=feedback.append)
            assert peer.spin_until(sent.done), 'goal not answered'
            goal = sent.result()
            assert goal.accepted
            result_future = goal.get_result_async()
            assert peer.spin_until(result_future.done), 'no result'
            outcome = result_future.result()
            assert outcome.status == GoalStatus.STATUS_SUCCEEDED
            assert outcome.result.result.result == Result.RESULT_OK
            # Feedback and result travel separately: wait for the last feedback.
            assert peer.spin_until(
                lambda: feedback and feedback[-1].feedback.completed_steps == 5), \
                'feedback: %r' % [f.feedback for f in feedback]
            for message in feedback:
                assert message.goal_id == goal.goal_id
                assert message.feedback.completed_steps + message.feedback.remaining_steps == 5
            assert [f.feedback.completed_steps for f in feedback] \
                == sorted(f.feedback.completed_steps for f in feedback)

            # 2. A long goal, cancelled once two steps are done.
            feedback = []
            sent = client.send_goal_async(SimulateSteps.Goal(steps=100000),
                                          feedback_callback=feedback.append)
            assert peer.spin_until(sent.done), 'goal not answered'
            goal = sent.result()
            assert goal.accepted
            assert peer.spin_until(
                lambda: feedback and feedback[-1].feedback.completed_steps >= 2), 'no feedback'
            cancel = goal.cancel_goal_async()
            assert peer.spin_until(cancel.done), 'cancel not answered'
            assert cancel.result().return_code == CancelGoal.Response.ERROR_NONE
            assert [g.goal_id for g in cancel.result().goals_canceling] == [goal.goal_id]
            result_future = goal.get_result_async()
            assert peer.spin_until(result_future.done), 'no result after cancel'
            outcome = result_future.result()
            assert outcome.status == GoalStatus.STATUS_CANCELED
            assert outcome.result.result.error_message.startswith('canceled after ')
            assert feedback[-1].feedback.completed_steps < 100000
            client.destroy()
        finally:
            out = _finish_child(child)
    lines = out.splitlines()
    assert lines[0] == 'GOAL 5 SUCCEEDED', out
    assert lines[1].startswith('GOAL 100000 CANCELED after '), out
