"""
The public testing API where it starts processes: the README's examples, leases, SimProcess.

The examples run in a subprocess under ``pytest -n 2``, as a user's own test
files would, next to a test that proves two workers never share a domain.
The same API in process, and the README's section against test/examples/,
are testing/test_testing_api.py's.
"""

import importlib.util
import os
from pathlib import Path
import re
import subprocess
import sys
import textwrap
import time

from helpers import REPO
import pytest

from common import EXAMPLE_FILES, EXAMPLES
from r2d2_sim import testing
from r2d2_sim.testing import (
    DomainUnavailable, HarnessError, lease_domain, SimHarness, SimProcess, StartupError)


# -- the README and the examples ----------------------------------------------------


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


MISTAKEN_PARAMETERS = """\
import pytest

pytest_plugins = ['r2d2_sim.pytest_plugin']


@pytest.fixture
def r2d2_sim_parameters():
    return PARAMETERS


def test_never_runs(r2d2_sim):
    pass
"""


@pytest.mark.parametrize('parameters, says', [
    ("{'world': '/no/such/arena.sdf'}", 'world /no/such/arena.sdf: no such world file'),
    ("{'namespace': 'a b'}", "namespace '/a b': Invalid namespace: namespace must not"),
    ("{'domain_id': 'x'}", "a ROS domain id is an integer 0-231, got 'x'")])
def test_parameters_the_simulator_refuses_are_one_line_in_pytest(tmp_path, parameters, says):
    """A missing world, a bad namespace or domain: the harness's line, not its traceback."""
    (tmp_path / 'test_mistake.py').write_text(
        MISTAKEN_PARAMETERS.replace('PARAMETERS', parameters))
    env = testing.ros_child_env()
    env['PYTHONPATH'] = REPO
    result = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                             'test_mistake.py'], cwd=tmp_path, env=env,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 1 and '1 error' in result.stdout, result.stdout[-800:]
    assert f'r2d2_sim_parameters: {says}' in result.stdout, result.stdout[-800:]
    assert 'r2d2_sim/' not in result.stdout  # no frame of the library (or rclpy's) shown
    assert 'Traceback' not in result.stdout
    # Once in the error's report, not thrice; the short summary below it repeats the line
    # whole where pytest thinks it runs on CI ($CI set) and cut to the terminal elsewhere.
    report = result.stdout.split('short test summary info')[0]
    assert report.count(says) == 1, result.stdout[-800:]


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
    with pytest.raises(StartupError,
                       match=r'^parameter physics_rate must be in \[10, 10000\] Hz, got -1$'):
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
                                             ('230-232', 'within 0-231'),
                                             ('5-1', 'R2D2_SIM_DOMAIN_IDS must lie'),
                                             ('lots', 'must be "first-last"')])
def test_the_leased_domain_range_can_be_set_for_a_shared_machine(value, expected):
    """R2D2_SIM_DOMAIN_IDS keeps harnesses inside the ids a machine's users agreed on."""
    env = dict(os.environ, R2D2_SIM_DOMAIN_IDS=value)
    result = subprocess.run([sys.executable, '-c',
                             'import r2d2_sim.testing as t; print(t.DOMAIN_IDS)'],
                            env=env, capture_output=True, text=True, timeout=60)
    assert expected in result.stdout + result.stderr


@pytest.mark.parametrize('ending, status', [('', 0), ('raise RuntimeError("late")', 1)])
def test_a_harness_left_open_at_exit_is_closed_and_the_process_ends_normally(ending, status):
    """No close(), or an exception outside ``with``: exit 0 (or 1 and the traceback), no abort."""
    script = textwrap.dedent(f'''
        from r2d2_sim.testing import SimHarness
        harness = SimHarness()
        harness.advance(seconds=0.5)
        print('stepped', flush=True)
        {ending}
    ''')
    env = dict(os.environ, PYTHONPATH=str(REPO))
    ended = subprocess.run([sys.executable, '-c', script], env=env, capture_output=True,
                           text=True, timeout=120)
    assert ended.returncode == status, ended.stderr[-2000:]  # SIGABRT was -6
    assert 'stepped' in ended.stdout
    assert 'terminate called' not in ended.stderr
    assert ('RuntimeError: late' in ended.stderr) == bool(ending)


def test_a_process_the_simulator_refuses_to_start_is_a_startup_error_in_one_line():
    """A missing world file: StartupError (as in process), also a HarnessError; its own line."""
    with pytest.raises(StartupError) as refused:
        SimProcess(world='romo.world.yaml')
    assert isinstance(refused.value, HarnessError)
    assert str(refused.value) == 'world romo.world.yaml: no such world file'


def test_a_process_keyword_the_simulator_does_not_read_is_refused_before_it_starts():
    """SimProcess(cmd_vel_timout=0.0): StartupError with the node's own hint; nothing started."""
    with pytest.raises(StartupError, match=r'^unknown parameter cmd_vel_timout '
                       r'\(did you mean cmd_vel_timeout\?\)$') as refused:
        SimProcess(cmd_vel_timout=0.0)
    assert isinstance(refused.value, HarnessError)


def test_a_process_robot_namespace_ros_refuses_is_the_simulators_one_line():
    """A namespace 'x y': the node's one line (as SimHarness's), not rclpy's traceback here."""
    with pytest.raises(StartupError, match=r"^parameter a\.namespace must be a ROS namespace "
                       r".*, got 'x y'$"):
        SimProcess(robots={'a': {'namespace': 'x y'}})


# docs/several-robots.md's fleet.yaml
FLEET_YAML = """
r2d2_sim:
  ros__parameters:
    robots: [a, b]
    b:
      initial_pose: [2.0, 0.0, 3.1416]   # facing robot a, 2 m ahead of it
      max_linear_velocity: 0.5
      enable_stamped_cmd_vel: true
      namespace: /fleet/b                # default: b
"""


def test_a_process_whose_params_file_lists_robots_starts_with_them(tmp_path):
    """
    The robots a --params-file lists, where it puts them: asked of the node, then driven.

    It used to wait for a robot in the namespace the keywords imply (/), for
    the whole timeout, then said the node served no services.
    """
    fleet = tmp_path / 'fleet.yaml'
    fleet.write_text(FLEET_YAML)
    with SimProcess(start_paused=True, publish_rate=20.0, cmd_vel_timeout=0.0, timeout_s=20.0,
                    ros_args=['--params-file', str(fleet)]) as sim:
        assert sim.robot_names == ['a', 'b']
        assert [sim.robot(name).namespace for name in ('a', 'b')] == ['/a', '/fleet/b']
        assert sim.robot() is sim.robot('a')  # the first robot is the harness's own
        sim.send_cmd_vel(0.3)
        sim.robot('b').send_cmd_vel(0.3)  # TwistStamped: its enable_stamped_cmd_vel
        sim.step(20)  # 1 s
        a, b = (sim.robot(name).ground_truth().pose.pose.position for name in ('a', 'b'))
        assert a.x > 0.1 and b.x < 1.9  # towards each other


@pytest.mark.skipif(importlib.util.find_spec('tf2_msgs') is None, reason='tf2_msgs is needed')
def test_a_process_lookup_after_reset_world_is_of_the_new_run(r2d2_sim_process):
    """Driven 2 s, reset_world, 1 s standing: the transform is the new run's, not the old."""
    sim = r2d2_sim_process(real_time_factor=0.0, publish_rate=60.0, cmd_vel_timeout=0.0)
    sim.lookup_transform('odom', 'base_link')  # listening from the start
    sim.send_cmd_vel(linear=0.5)
    assert testing.wait_for(lambda: sim.odom().pose.pose.position.x > 0.5, timeout_s=30.0)
    sim.send_cmd_vel(linear=0.0)
    sim.reset_world()
    assert abs(sim.odom().pose.pose.position.x) < 0.05  # standing at the start again
    latest = sim.lookup_transform('odom', 'base_link')
    assert abs(latest.transform.translation[0]) < 0.05, latest  # not the old run's 0.5 m


@pytest.mark.parametrize('keywords, says', [
    ({'world': {'name': 'room'}}, 'parameter world: a dict is no ROS parameter value'),
    ({'robots': {'a': 5}}, "robots: robot 'a' takes a dict of its parameters"),
    ({'ros_args': '--log-level debug'}, 'ros_args must be a list of strings'),
])
def test_a_process_given_what_cannot_be_a_parameter_is_one_line_and_leases_nothing(
        keywords, says):
    """One line, before any domain is leased: the same domain is free at once after."""
    from r2d2_sim.testing import lease_domain
    with lease_domain() as first:
        domain = first.domain_id
    with pytest.raises(StartupError, match=re.escape(says)):
        SimProcess(domain_id=domain, **keywords)
    with lease_domain(domain, timeout_s=1.0) as again:  # not held by the refused process
        assert again.domain_id == domain


@pytest.mark.parametrize('timeout_s', [0, -1.0, float('nan')])
def test_a_timeout_that_is_no_time_is_one_line(timeout_s):
    """Both harnesses, SimProcess and the in-process one, refuse it before anything starts."""
    for make in (SimProcess, SimHarness):
        with pytest.raises(ValueError, match=r'^timeout_s must be a finite number of '
                           r'seconds > 0, got '):
            make(timeout_s=timeout_s)


def test_a_stopped_process_says_so_in_one_line(r2d2_sim_process):
    """After stop(): the standard's verbs, the services and lookups: HarnessError, one line."""
    sim = r2d2_sim_process(real_time_factor=0.0)
    robot = sim.robot()
    sim.stop()
    calls = [sim.entities, sim.status, lambda: sim.step_physics(1), sim.joint_info,
             lambda: sim.spawn('package://r2d2_sim/urdf/r2d2.urdf', name='late')]
    if importlib.util.find_spec('tf2_msgs') is not None:
        calls += [lambda: sim.lookup_transform('odom', 'base_link'),
                  lambda: robot.lookup_transform('odom', 'base_link')]
    for call in calls:
        with pytest.raises(HarnessError, match='^the simulator process was stopped'):
            call()


def test_a_process_command_that_is_not_finite_is_one_line_and_never_sent(r2d2_sim_process):
    """The send_cmd_vel of SimProcess refuses NaN as SimHarness's does, before publishing."""
    sim = r2d2_sim_process()
    robot = sim.robot()
    received = robot.commands_received()
    with pytest.raises(ValueError, match='send_cmd_vel: linear must be a finite number'):
        sim.send_cmd_vel(linear=float('nan'))
    assert robot.commands_received() == received
