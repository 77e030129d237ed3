"""
The public testing API (r2d2_sim.testing, r2d2_sim.pytest_plugin) and its example files.

The examples of docs/testing.md are test/examples/ (test/lint/test_docs.py checks
them byte for byte). They run here in a subprocess under ``pytest -n 2``, as a
user's own test files would, next to a test that proves two workers never share
a domain.
"""

import importlib.util
import os
from pathlib import Path
import subprocess
import sys
import textwrap
import time

from helpers import REPO
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
from rclpy.context import Context
from rclpy.node import Node

from r2d2_sim import testing
from r2d2_sim.ros.node import StartupError
from r2d2_sim.testing import (
    CallbackError, DomainUnavailable, HarnessError, lease_domain, SimHarness, SimProcess)

EXAMPLES = Path(REPO) / 'test' / 'examples'
# In the order docs/testing.md shows them.
EXAMPLE_FILES = ['test_drive_forward.py', 'test_closed_loop.py', 'test_sim_process.py',
                 'test_change_the_world.py', 'test_two_robots.py']


def _load_example(name):
    spec = importlib.util.spec_from_file_location(f'example_{name[:-3]}', EXAMPLES / name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


ISOLATION_TEST = '''
import os
from pathlib import Path
import time

pytest_plugins = ['r2d2_sim.pytest_plugin']
MEETING = Path(os.environ['R2D2_TEST_MEETING'])


def meet(stage):
    """Wait until both workers have reached ``stage``."""
    (MEETING / f'{stage}-{os.environ["PYTEST_XDIST_WORKER"]}').write_text('')
    deadline = time.monotonic() + 30.0
    while len(list(MEETING.glob(f'{stage}-*'))) < 2:
        assert time.monotonic() < deadline, f'the other worker never reached {stage}'
        time.sleep(0.01)


def test_two_workers_at_once_never_hear_each_other(r2d2_sim):
    (MEETING / f'domain-{r2d2_sim.domain_id}').write_text('')
    meet('ready')
    for _ in range(20):
        r2d2_sim.send_cmd_vel(linear=0.2)
    r2d2_sim.advance(seconds=0.5)
    meet('sent')  # both have sent all theirs: any cross-talk has happened by now
    assert r2d2_sim.sim.commands_received == 20
    assert len(list(MEETING.glob('domain-*'))) == 2
'''


def test_examples_pass_in_parallel_workers_without_cross_talk(tmp_path):
    """``pytest -n 2 --dist each``: both workers run every example at once, on domains apart."""
    for name in EXAMPLE_FILES:
        (tmp_path / name).write_text((EXAMPLES / name).read_text(encoding='utf-8'))
    (tmp_path / 'test_isolation.py').write_text(ISOLATION_TEST)
    meeting = tmp_path / 'meeting'
    meeting.mkdir()
    env = testing.ros_child_env()
    env.pop('ROS_DOMAIN_ID', None)  # every harness takes a free domain
    env['PYTHONPATH'] = os.pathsep.join(p for p in (REPO, env.get('PYTHONPATH')) if p)
    env['R2D2_TEST_MEETING'] = str(meeting)
    started = time.monotonic()
    result = subprocess.run(
        [sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', '-n', '2',
         '--dist', 'each', str(tmp_path)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    # Each worker runs every example and the isolation test.
    assert f'{2 * (len(EXAMPLE_FILES) + 1)} passed' in result.stdout, result.stdout[-2000:]
    print(f'pytest -n 2 of the examples: {time.monotonic() - started:.1f} s')


def test_a_suite_shards_over_machines_with_pytest_split(tmp_path):
    """The README's CI recipe: two shards at once run every example exactly once, all passing."""
    for name in EXAMPLE_FILES:
        (tmp_path / name).write_text((EXAMPLES / name).read_text(encoding='utf-8'))
    env = testing.ros_child_env()
    env.pop('ROS_DOMAIN_ID', None)
    env['PYTHONPATH'] = os.pathsep.join(p for p in (REPO, env.get('PYTHONPATH')) if p)
    shards = [subprocess.Popen(
        [sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider', '-rA',
         '--splits', '2', '--group', str(group), str(tmp_path)],
        cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        for group in (1, 2)]
    ran = []
    for shard in shards:
        out, _ = shard.communicate(timeout=120)
        assert shard.returncode == 0, out[-3000:]
        ran.append({line.split()[1] for line in out.splitlines() if line.startswith('PASSED ')})
    assert ran[0] and ran[1] and not ran[0] & ran[1]
    assert len(ran[0] | ran[1]) == len(EXAMPLE_FILES)  # one test per example file


def test_the_pytest_plugins_line_also_works_where_r2d2_sim_is_installed(tmp_path):
    """With setup.py's pytest11 entry point active (pip, colcon), the README's files still run."""
    # egg_info writes the metadata an install would, entry points included.
    subprocess.run([sys.executable, 'setup.py', '-q', 'egg_info', '--egg-base', str(tmp_path)],
                   cwd=REPO, check=True, capture_output=True, timeout=60)
    tests = tmp_path / 'tests'
    tests.mkdir()
    (tests / EXAMPLE_FILES[0]).write_text((EXAMPLES / EXAMPLE_FILES[0]).read_text())
    env = testing.ros_child_env()
    env['PYTHONPATH'] = os.pathsep.join([str(tmp_path), REPO])
    result = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                             str(tests)], cwd=tests, env=env, capture_output=True, text=True,
                            timeout=120)
    # pytest registers an entry point's module under the entry point's name, and
    # refuses the same module again under its module name (pytest_plugins).
    assert result.returncode == 0, (
        'name the pytest11 entry point after its module in setup.py '
        "('r2d2_sim.pytest_plugin = r2d2_sim.pytest_plugin'):\n" + result.stdout[-800:])
    assert '1 passed' in result.stdout


# -- import costs -------------------------------------------------------------------


def test_plugin_import_is_cheap_and_testing_needs_no_pytest():
    """The auto-loaded plugin imports neither rclpy nor PyBullet; r2d2_sim.testing no pytest."""
    script = textwrap.dedent('''
        import sys
        import r2d2_sim.pytest_plugin
        heavy = [m for m in ('rclpy', 'pybullet', 'r2d2_sim.testing') if m in sys.modules]
        sys.modules['pytest'] = None  # any import of pytest now fails
        del sys.modules['r2d2_sim.pytest_plugin'], sys.modules['_pytest']
        import r2d2_sim.testing
        print(heavy, 'pybullet' in sys.modules)
    ''')
    result = subprocess.run([sys.executable, '-c', script], env=testing.ros_child_env(),
                            cwd=REPO, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split('\n')[-2] == '[] False'


# -- domain leases -----------------------------------------------------------------


@pytest.fixture
def lock_dir(tmp_path, monkeypatch):
    """Lease domains in a directory of this test's own, away from concurrent test runs."""
    monkeypatch.setenv(testing.DOMAIN_LOCK_DIR_ENV, str(tmp_path))
    return tmp_path


HOLD_LEASE = '''
import sys
from r2d2_sim.testing import lease_domain
lease = lease_domain(int(sys.argv[1]), timeout_s=5.0)
print('held', flush=True)
sys.stdin.read()
'''


def test_a_domain_leased_in_another_process_waits_for_its_release(lock_dir):
    """Two processes never hold one domain; its lease is free again once the holder ends."""
    with lease_domain() as mine:
        assert mine.held and mine.domain_id in testing.DOMAIN_IDS
        other = lease_domain()
        assert other.domain_id != mine.domain_id  # one process, two leases: two domains
        other.release()
    holder = subprocess.Popen([sys.executable, '-c', HOLD_LEASE, '7'], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True, env=testing.ros_child_env())
    try:
        assert holder.stdout.readline().strip() == 'held'
        with pytest.raises(DomainUnavailable, match='domain 7'):
            lease_domain(7, timeout_s=0.2)
        assert lease_domain().domain_id != 7
    finally:
        holder.communicate('', timeout=10)  # EOF: the holder exits, and its lock goes with it
    with lease_domain(7, timeout_s=5.0) as lease:
        assert lease.domain_id == 7
    assert not lease.held


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
    leased = [int(p.stem.split('-')[1]) for p in lock_dir.glob('domain-*.lock')]
    assert len(leased) == 1  # it did lease one, and gave it back:
    lease_domain(leased[0], timeout_s=0.0).release()


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


# -- SimProcess --------------------------------------------------------------------


def test_sim_process_services_reply_with_json(r2d2_sim_process):
    """pause, step, reset, status and joint_info parse the node's JSON replies."""
    sim = r2d2_sim_process(publish_rate=60.0, real_time_factor=0.0)
    assert not sim.paused and sim.last_status['paused'] is False
    paused = sim.pause()
    assert paused['paused'] and paused['step'] % 4 == 0  # lands on a publication
    step = sim.step(3)
    assert step['steps'] == 12 and step['step'] == paused['step'] + 12
    assert testing.stamp_ns(sim.joint_states().header.stamp) == step['sim_time_ns']
    assert sim.status() == {k: v for k, v in step.items() if k != 'steps'}
    sim.send_cmd_vel(linear=0.3)
    driven = sim.step(20)
    assert sim.ground_truth().pose.pose.position.x > 0.02
    assert sim.reset()['step'] == driven['step']
    with pytest.raises(HarnessError, match='step'):  # the reset shows at the next publication
        sim.ground_truth()
    sim.step()
    assert abs(sim.ground_truth().pose.pose.position.x) < 1e-3
    info = sim.joint_info()
    assert info['robot'] and len(info['joints']) == 15
    sim.resume()
    with pytest.raises(HarnessError, match='the simulation is running'):
        sim.step()
    result = sim.stop()
    assert result.returncode == 0, result.stderr
    assert sim.stop() is result


def test_sim_process_reports_a_refused_start_at_once():
    """A bad parameter: the node's one-line error, well before the start-up deadline."""
    started = time.monotonic()
    with pytest.raises(HarnessError, match='(?s)status 2.*physics_rate must be'):
        SimProcess(physics_rate=-1.0, timeout_s=30.0)
    assert time.monotonic() - started < 15.0


def test_sim_process_honours_ros_domain_id_unless_told_not_to(monkeypatch):
    """ROS_DOMAIN_ID from the environment is used (and leased); use_env_domain=False skips it."""
    with lease_domain() as free:  # a domain no other test uses, handed over below
        domain = free.domain_id
    monkeypatch.setenv('ROS_DOMAIN_ID', str(domain))
    with SimProcess(start_paused=True) as sim:
        assert sim.domain_id == domain
        environ = Path(f'/proc/{sim.process.pid}/environ').read_bytes().split(b'\0')
        assert f'ROS_DOMAIN_ID={domain}'.encode() in environ
        with pytest.raises(DomainUnavailable):
            lease_domain(domain, timeout_s=0.0)  # held while it runs
        # String and list values reach the node as such (written as JSON).
        with SimProcess(start_paused=True, use_env_domain=False, urdf='cube.urdf',
                        extra_models=['cube.urdf 2.0 0 0.5']) as other:
            assert other.domain_id != domain
            assert other.status()['paused']
            assert other.joint_info()['urdf'].endswith('cube.urdf')
    assert not sim.lease.held and not other.lease.held


@pytest.mark.parametrize('value, expected', [('229-231', 'range(229, 232)'),
                                             ('5-1', 'R2D2_SIM_DOMAIN_IDS must lie'),
                                             ('230-232', 'within 0-231'),
                                             ('lots', 'must be "first-last"')])
def test_the_leased_domain_range_can_be_set_for_a_shared_machine(value, expected):
    """R2D2_SIM_DOMAIN_IDS keeps harnesses inside the ids a machine's users agreed on."""
    env = dict(os.environ, R2D2_SIM_DOMAIN_IDS=value)
    result = subprocess.run([sys.executable, '-c',
                             'import r2d2_sim.testing as t; print(t.DOMAIN_IDS)'],
                            env=env, capture_output=True, text=True, timeout=60)
    assert expected in result.stdout + result.stderr


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
