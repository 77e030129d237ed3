"""
The public testing API (r2d2_sim.testing, r2d2_sim.pytest_plugin) and its example files.

The examples of docs/testing.md are test/examples/ (lint/test_docs.py checks them
byte for byte). They run in a subprocess under ``pytest -n 2``, as a user's own
test files would, in system/test_testing_api_system.py, with SimProcess and
everything else that starts a process.
"""

import fcntl
import importlib.util
import time

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
from rclpy.context import Context
from rclpy.node import Node

from common import EXAMPLES
from r2d2_sim import testing
from r2d2_sim.ros.node import StartupError
from r2d2_sim.testing import (
    CallbackError, DomainUnavailable, HarnessError, lease_domain, SimHarness)


def _load_example(name):
    spec = importlib.util.spec_from_file_location(f'example_{name[:-3]}', EXAMPLES / name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# -- domain leases -----------------------------------------------------------------


def test_harnesses_release_their_domain():
    """A closed harness gives its domain back; a second harness at once gets another."""
    with SimHarness() as first:
        with SimHarness() as second:
            assert first.domain_id != second.domain_id
            assert first.lease.held and second.lease.held
        assert not second.lease.held
    assert not first.lease.held


# -- SimHarness -------------------------------------------------------------------


def test_state_readers_return_the_latest_publication(r2d2_sim):
    """ground_truth, odom and joint_states are stamped with the time of the last publication."""
    assert r2d2_sim.ground_truth().header.stamp.sec == 0  # the constructor's publication
    r2d2_sim.send_cmd_vel(linear=0.3, angular=0.2)
    assert r2d2_sim.advance(seconds=0.5) == 120
    assert r2d2_sim.sim.step_count == 120 and r2d2_sim.sim.commands_received == 1
    for msg in (r2d2_sim.ground_truth(), r2d2_sim.odom(), r2d2_sim.joint_states()):
        assert testing.stamp_ns(msg.header.stamp) == 500_000_000
    truth, odom = r2d2_sim.ground_truth(), r2d2_sim.odom()
    assert truth.pose.pose.position.x > 0.02
    assert odom.pose.pose.position.x == pytest.approx(truth.pose.pose.position.x, abs=0.01)
    assert odom.twist.twist.angular.z > 0.05


def test_a_whole_twist_and_the_fixture_parameters(r2d2_sim):
    """send_cmd_vel takes a Twist; the fixture's simulator holds commands (timeout 0)."""
    assert r2d2_sim.sim.config.cmd_vel_timeout_s == 0.0
    twist = Twist()
    twist.angular.z = 0.5
    r2d2_sim.send_cmd_vel(twist=twist)
    r2d2_sim.advance(seconds=2.0)  # longer than the node's default 0.5 s timeout
    assert r2d2_sim.odom().twist.twist.angular.z == pytest.approx(0.5, abs=0.05)


class TestOverriddenParameters:
    """Overriding r2d2_sim_parameters changes the r2d2_sim fixture's simulator."""

    @pytest.fixture
    def r2d2_sim_parameters(self):
        """Publish at 60 Hz; brake 0.25 s after the last command."""
        return {'publish_rate': 60.0, 'cmd_vel_timeout': 0.25}

    def test_advance_without_arguments_is_one_control_period(self, r2d2_sim):
        """advance() moves to and including the next publication, as ~/step does."""
        assert r2d2_sim.advance() == 4
        assert r2d2_sim.advance() == 4
        assert r2d2_sim.last_publication_ns() == r2d2_sim.sim.sim_time_ns
        assert r2d2_sim.advance(3) == 3
        # The state is still that of the last publication, one step ago.
        assert testing.stamp_ns(r2d2_sim.ground_truth().header.stamp) == 8 * 10**9 // 240
        r2d2_sim.send_cmd_vel(linear=0.3)
        r2d2_sim.advance(seconds=1.0)
        assert abs(r2d2_sim.odom().twist.twist.linear.x) < 1e-3  # braked: the timeout is on


def test_advance_until_counts_simulated_time(r2d2_sim):
    """True once the predicate holds; False after exactly timeout_s of simulated time."""
    r2d2_sim.send_cmd_vel(linear=0.3)
    assert r2d2_sim.advance_until(lambda: r2d2_sim.ground_truth().pose.pose.position.x > 0.1,
                                  timeout_s=5.0)
    x = r2d2_sim.ground_truth().pose.pose.position.x
    assert 0.1 < x < 0.11  # stopped at the first publication past it (one step here)
    start = r2d2_sim.sim.step_count
    assert not r2d2_sim.advance_until(lambda: False, timeout_s=0.25)
    assert r2d2_sim.sim.step_count - start == 60
    assert r2d2_sim.advance_until(lambda: True, timeout_s=1.0)  # checked before any step
    assert r2d2_sim.sim.step_count - start == 60


def test_reset_returns_the_json_state_and_the_readers_the_reset_robot(r2d2_sim):
    """reset() goes through ~/reset; the next ground_truth is at the origin, time goes on."""
    r2d2_sim.send_cmd_vel(linear=0.3)
    r2d2_sim.advance(seconds=1.0)
    assert r2d2_sim.ground_truth().pose.pose.position.x > 0.1
    state = r2d2_sim.reset()
    assert state == {'paused': False, 'step': 240, 'sim_time_ns': 10**9, 'sim_time': 1.0,
                     'published_ns': 10**9, 'commands_received': 1,
                     'robots': {'r2d2': {'namespace': '/', 'tf': '/tf',
                                         'commands_received': 1}}}
    truth = r2d2_sim.ground_truth()
    assert abs(truth.pose.pose.position.x) < 1e-6 and truth.header.stamp.sec == 1


def test_factory_builds_isolated_simulators_with_parameters(r2d2_sim_factory):
    """Two harnesses at once: their own domains, parameters and commands."""
    cube = r2d2_sim_factory(urdf='cube.urdf')
    robot = r2d2_sim_factory(cmd_vel_timeout=0.0, node_name='robot', namespace='/r1')
    assert cube.domain_id != robot.domain_id
    assert not cube.sim.has_wheels
    with pytest.raises(HarnessError, match='no wheels'):
        cube.odom()
    assert robot.sim.get_fully_qualified_name() == '/r1/robot'
    robot.send_cmd_vel(linear=0.3)
    robot.advance(seconds=1.0)
    cube.advance(seconds=1.0)
    assert robot.ground_truth().pose.pose.position.x > 0.1
    assert cube.sim.commands_received == 0


def test_bad_parameters_raise_startup_error_and_leave_nothing_behind(lock_dir):
    """A refused start raises the node's StartupError and releases the domain."""
    with pytest.raises(StartupError, match='physics_rate'):
        SimHarness(physics_rate=-1.0)
    # It did lease one (a domain whose domain_coordinator port another process holds
    # leaves a lock file too: it was tried first), and gave it back:
    tried = sorted(lock_dir.glob('domain-*.lock'))
    assert tried
    for path in tried:
        with open(path, 'rb') as lock:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)  # BlockingIOError if still held
    given_back = []
    for path in tried:
        try:
            lease_domain(int(path.stem.split('-')[1]), timeout_s=0.0).release()
            given_back.append(path)
        except DomainUnavailable:
            continue  # its coordinator port is another process's
    assert given_back


def test_a_raising_callback_fails_the_test_as_callback_error(r2d2_sim):
    """An exception in your callback is raised by the next harness call."""
    node = r2d2_sim.create_node('fragile')

    def explode(msg):
        raise ValueError('controller bug')
    node.create_subscription(Odometry, 'odom', explode, 10)
    with pytest.raises(CallbackError, match='ValueError: controller bug'):
        r2d2_sim.advance(1)
    r2d2_sim.raise_callback_error()  # reported once


def test_nodes_of_another_context_are_refused(r2d2_sim):
    """add_node says how to build the node."""
    context = Context()
    import rclpy
    rclpy.init(context=context, domain_id=r2d2_sim.domain_id)
    node = Node('elsewhere', context=context)
    try:
        with pytest.raises(ValueError, match='context=harness.context'):
            r2d2_sim.add_node(node)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def _closed_loop_run(seconds):
    drive_to_x = _load_example('test_closed_loop.py').DriveToX
    with SimHarness(cmd_vel_timeout=0.0) as harness:
        controller = harness.add_node(drive_to_x(context=harness.context))
        assert controller.get_parameter('use_sim_time').value
        harness.advance(seconds=seconds)
        assert controller.get_clock().now().nanoseconds == harness.sim.sim_time_ns
        pose = harness.ground_truth().pose.pose
        return (pose.position.x, pose.position.y, pose.orientation.z,
                harness.sim.commands_received)


def test_lockstep_closed_loop_repeats_bit_for_bit():
    """The README's controller, twice: the same trajectory, one command per 20 Hz tick."""
    first, second = _closed_loop_run(2.0), _closed_loop_run(2.0)
    assert first == second
    # One command per tick of simulated time (the first tick comes one period
    # after the controller's first /clock).
    assert first[0] > 0.3 and first[3] == 39


# -- RemoteProbe -------------------------------------------------------------------


def test_remote_call_resends_an_idempotent_request_whose_reply_is_late():
    """resend_after_s: a reply that does not come is asked for again; late ones are dropped."""
    import threading

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from std_srvs.srv import Trigger

    calls, answered = [], []
    slow_calls = [0]  # how many of the next calls take 1 s to answer

    def answer(request, response):
        calls.append(time.monotonic())
        if slow_calls[0] > 0:
            slow_calls[0] -= 1
            time.sleep(1.0)
        response.success = True
        response.message = f'call {len(calls)}'
        answered.append(response.message)
        return response

    with lease_domain() as lease:
        context = Context()
        rclpy.init(context=context, domain_id=lease.domain_id)
        server = Node('slow_server', context=context)
        server.create_service(Trigger, 'query', answer)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(server)
        spinner = threading.Thread(target=executor.spin, daemon=True)
        spinner.start()
        try:
            with testing.RemoteProbe(lease.domain_id) as probe:
                slow_calls[0] = 1
                reply = probe.call(Trigger, '/query', Trigger.Request(), timeout_s=10.0,
                                   resend_after_s=0.3)
                # Sent again every 0.3 s; the reply taken is the last send's.
                assert len(calls) >= 2 and reply.message == f'call {len(calls)}'
                # Without a resend the caller waits for the slow reply, and gets it.
                slow_calls[0] = 1
                reply = probe.call(Trigger, '/query', Trigger.Request(), timeout_s=10.0)
                assert reply.message == f'call {len(calls)}'
                slow_calls[0] = 1
                with pytest.raises(HarnessError, match='did not answer within 0.2 s'):
                    probe.call(Trigger, '/query', Trigger.Request(), timeout_s=0.2)
                assert testing.wait_for(lambda: len(answered) == len(calls), 5.0)
        finally:
            executor.shutdown()
            server.destroy_node()
            rclpy.try_shutdown(context=context)
            spinner.join(timeout=5.0)
