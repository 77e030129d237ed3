"""
Every way a user installs r2d2_sim, proved by taking it: here, a plain ``pip install .``.

A fresh virtual environment gets the package, not editable, built from a copy
of the sources, and nothing else but pytest: the ROS wheels, PyBullet, numpy
and matplotlib must come from the package's own declared dependencies (the
pip cache makes that about 20 s). Everything then runs from another directory with no
``PYTHONPATH`` and no ``AMENT_PREFIX_PATH``, as for a pip user without a ROS
install. (./run.sh puts the source tree on ``PYTHONPATH``, which once hid that
such an install could not find its own URDF.) The colcon layout is proved in
test_colcon.py; the source tree by the rest of the suite.
"""

import fcntl
import json
import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import textwrap

from helpers import next_domain_id, REPO, RemoteProbe, stop_process
import pytest
from sensor_msgs.msg import JointState

# What a pip user adds to test their own code (README "pip install"); no ROS, no PyBullet.
USER_REQUIREMENTS = ['pytest']
# Run-time dependencies that requirements.txt pins too: the installed package must agree.
PINNED = ('ros-jazzy-rclpy', 'ros-jazzy-common-interfaces', 'pybullet', 'numpy', 'matplotlib',
          'google-re2', 'defusedxml', 'pycollada', 'trimesh')
PYBULLET_CHATTER = ('pybullet build time', 'argv[0]=')


def _run(args, **kwargs):
    result = subprocess.run(args, capture_output=True, text=True, **kwargs)
    assert result.returncode == 0, f'{args}:\n{result.stdout[-3000:]}{result.stderr[-3000:]}'
    return result


@pytest.fixture(scope='session')
def pip_venv(tmp_path_factory):
    """
    Provide a fresh venv with r2d2_sim pip-installed (not editable) from a source copy.

    Built once per run: pytest-xdist's workers share the run's base directory,
    and the first to ask builds it under a lock while the others wait (a
    module fixture was built again on each worker this file's tests went to:
    three times, 91 s, in one run). Tests add to it only what the documented
    interface build adds (under that script's own lock); one that installs
    more with pip works on a copy of its own (:func:`private_copy`).
    """
    # Under xdist, the run's directory every worker's base directory is in (new each run);
    # else this run's own (a parent outlives the run).
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get('PYTEST_XDIST_WORKER') else base
    root, done = shared / 'pip_user', shared / 'pip_user.done'
    with open(shared / 'pip_user.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when closed: a builder that failed too
        if not done.exists():
            shutil.rmtree(root, ignore_errors=True)  # half of one that failed
            _build_pip_venv(root)
            done.touch()
    return root / 'venv'


def _build_pip_venv(root: Path) -> None:
    sources = root / 'src'
    files = subprocess.run(['git', 'ls-files'], cwd=REPO, capture_output=True, text=True,
                           check=True).stdout.split()
    for name in files:
        target = sources / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(Path(REPO) / name, target)
    venv = root / 'venv'
    _run([sys.executable, '-m', 'venv', str(venv)])
    pip = [str(venv / 'bin' / 'python'), '-m', 'pip', 'install', '--quiet',
           '--disable-pip-version-check']
    _run(pip + [str(sources)], cwd=root)  # alone: the package brings what it needs
    _run(pip + USER_REQUIREMENTS)
    shutil.rmtree(sources)  # nothing may come from the source tree


def private_copy(venv: Path, where: Path) -> Path:
    """
    Return a copy of ``venv`` in ``where`` that pip may change, the shared one as it was.

    A whole copy (not hard links: an interface build writes into the shared
    venv in place), taken while no build runs there (the build's own lock).
    Its python finds its own pyvenv.cfg beside it, so pip installs into the copy.
    """
    copy = where / 'venv'
    with open(venv / '.build_interfaces.lock', 'a') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        _run(['cp', '-a', str(venv), str(copy)])
    return copy


def user_env(domain_id=None):
    """Return a pip user's environment: no PYTHONPATH, no AMENT_PREFIX_PATH, local discovery."""
    env = {k: v for k, v in os.environ.items()
           if k not in ('PYTHONPATH', 'AMENT_PREFIX_PATH', 'VIRTUAL_ENV')}
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    if domain_id is not None:
        env['ROS_DOMAIN_ID'] = str(domain_id)
    return env


def _requirement(line):
    """Split a requirement into (name with extras, version specifier)."""
    for i, char in enumerate(line):
        if char in '=<>!~':
            return line[:i].strip(), line[i:].strip()
    return line.strip(), ''


def test_pip_install_alone_brings_the_pinned_dependencies(pip_venv, tmp_path):
    """Install package.xml's version, declaring ROS, PyBullet, numpy... at their pins."""
    script = textwrap.dedent('''
        import json
        from importlib import metadata
        print(json.dumps({
            'version': metadata.version('r2d2_sim'),
            'requires': metadata.requires('r2d2_sim'),
            'versions': {name: metadata.version(name) for name in (
                'ros-jazzy-rclpy', 'ros-jazzy-common-interfaces', 'ros-jazzy-rosidl-parser',
                'pybullet', 'numpy', 'matplotlib')}}))
    ''')
    result = _run([str(pip_venv / 'bin' / 'python'), '-c', script], cwd=tmp_path,
                  env=user_env())
    facts = json.loads(result.stdout.strip().splitlines()[-1])
    # The version installed is package.xml's (test_changelog.py keeps setup.py's the same).
    package_xml = (Path(REPO) / 'package.xml').read_text()
    assert f"<version>{facts['version']}</version>" in package_xml, facts['version']
    declared = dict(_requirement(line) for line in facts['requires'])
    lines = (Path(REPO) / 'requirements.txt').read_text().splitlines()
    pinned = dict(_requirement(line) for line in lines if line and not line.startswith('#'))
    for name in PINNED:
        key = next(k for k in pinned if k.split('[')[0] == name)
        assert key in declared, f'{key} is not declared by setup.py: {sorted(declared)}'
        assert set(declared[key].split(',')) == set(pinned[key].split(',')), name
    for name, version in facts['versions'].items():
        spec = declared[next(k for k in declared if k.split('[')[0] == name)]
        if spec.startswith('=='):
            assert version == spec[2:], (name, version, spec)
    # The scenarios extra pins scenario_execution as requirements.txt does.
    extra = [line for line in facts['requires'] if 'extra == "scenarios"' in line]
    assert [r.split(';')[0].strip() for r in extra] == [
        line for line in lines if line.startswith('scenario_execution')], extra
    # pip's own consistency check: every declared dependency is there, at its version.
    _run([str(pip_venv / 'bin' / 'python'), '-m', 'pip', 'check'], env=user_env())


def test_pip_installed_sim_node_help(pip_venv, tmp_path):
    """The installed sim_node prints its usage and parameters, exit 0, without starting ROS."""
    result = _run([str(pip_venv / 'bin' / 'sim_node'), '--help'], cwd=tmp_path,
                  env=user_env(), timeout=60)
    assert result.stdout.startswith('usage: sim_node [-h]'), result.stdout[:200]
    assert 'physics_rate: double; default 240.0' in result.stdout
    assert result.stderr == ''


def test_in_process_simulator_finds_its_installed_urdf(pip_venv, tmp_path):
    """SimNode() builds from share/r2d2_sim/urdf under the venv, and package:// resolves."""
    script = textwrap.dedent('''
        import json, sys
        import rclpy
        from rclpy.context import Context
        from r2d2_sim.physics.description import resolve_description_path
        from r2d2_sim.ros.node import SimNode
        import r2d2_sim
        context = Context()
        rclpy.init(context=context, domain_id=%d)
        sim = SimNode(context=context)
        sim.advance(24)
        print(json.dumps({
            'package': r2d2_sim.__file__, 'urdf': sim.simulation.robot.source,
            'prefix': sys.prefix,
            'package_uri': resolve_description_path('package://r2d2_sim/urdf/r2d2.urdf'),
            'classic': resolve_description_path('package://r2d2_sim/urdf/classic_r2d2.yaml'),
            'joints': len(sim.simulation.robot.body.joints), 'step': sim.step_count}))
        sim.destroy_node()
        rclpy.shutdown(context=context)
    ''' % next_domain_id())
    result = _run([str(pip_venv / 'bin' / 'python'), '-c', script], cwd=tmp_path,
                  env=user_env())
    facts = json.loads(result.stdout.strip().splitlines()[-1])
    share = os.path.join(facts['prefix'], 'share', 'r2d2_sim')
    assert facts['package'].startswith(facts['prefix']) and 'site-packages' in facts['package']
    assert facts['urdf'] == os.path.join(share, 'urdf', 'r2d2.urdf')
    assert facts['package_uri'] == facts['urdf']
    assert facts['classic'] == os.path.join(share, 'urdf', 'classic_r2d2.yaml')
    assert facts['joints'] == 15 and facts['step'] == 24
    for chatter in PYBULLET_CHATTER:
        assert chatter not in result.stdout + result.stderr


@pytest.mark.parametrize('command', [['bin/sim_node'], ['bin/python', '-m', 'r2d2_sim']])
def test_pip_installed_simulator_starts_publishes_and_stops(pip_venv, tmp_path, command):
    """sim_node and python -m r2d2_sim start from the venv, publish, and exit 0 on SIGINT."""
    domain = next_domain_id()
    args = [str(pip_venv / command[0])] + command[1:]
    process = subprocess.Popen(args, cwd=tmp_path, env=user_env(domain), text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    probe = RemoteProbe(domain, 'pip_probe')
    try:
        joints = []
        probe.node.create_subscription(JointState, 'joint_states', joints.append, 10)
        started = probe.spin_until(lambda: joints or process.poll() is not None, 30.0)
        assert started and joints, 'no joint_states from the pip-installed simulator'
        assert len(joints[-1].name) == 8  # the non-fixed joints of the package's R2D2
    finally:
        code, out, err = stop_process(process, signal.SIGINT)
        probe.close()
    assert code == 0, err
    assert 'Traceback' not in out + err
    # A ROS node's output is its own log lines, not PyBullet's banner.
    for chatter in PYBULLET_CHATTER:
        assert chatter not in out + err, out + err


def test_pip_installed_demo_runs(pip_venv, tmp_path):
    """The demo executable drives the pip-installed simulator and writes its plot."""
    result = subprocess.run(
        [str(pip_venv / 'bin' / 'demo'), '--real-time-factor', '0', '--output-dir', 'out',
         '--domain-id', str(next_domain_id())],
        cwd=tmp_path, env=user_env(), capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    assert (tmp_path / 'out' / 'trajectory.png').stat().st_size > 1000


def test_users_own_pytest_run_shows_no_ros_wheel_warnings(pip_venv, tmp_path):
    """The installed pytest plugin filters the ROS wheels' lark DeprecationWarnings."""
    (tmp_path / 'test_mine.py').write_text(textwrap.dedent('''
        import rclpy
        from rclpy.context import Context

        def test_ros_starts():
            context = Context()
            rclpy.init(context=context, domain_id=%d)
            rclpy.shutdown(context=context)
    ''' % next_domain_id()))
    result = subprocess.run([str(pip_venv / 'bin' / 'python'), '-m', 'pytest', '-q',
                             'test_mine.py'], cwd=tmp_path, env=user_env(),
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    assert '1 passed' in result.stdout
    assert 'DeprecationWarning' not in result.stdout and 'warning' not in result.stdout


def test_tf_scan_and_imu_reach_another_process_after_the_documented_build(pip_venv, tmp_path):
    """tools/build_tf2_msgs.sh VENV gives a pip-only venv /tf; sensors cross processes too."""
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from sensor_msgs.msg import Imu, LaserScan
    from tf2_msgs.msg import TFMessage
    _run(['bash', os.path.join(REPO, 'tools', 'build_tf2_msgs.sh'), str(pip_venv)],
         env=user_env())
    domain = next_domain_id()
    process = subprocess.Popen(
        [str(pip_venv / 'bin' / 'sim_node'), '--ros-args', '-p',
         'world:=package://r2d2_sim/urdf/room.urdf'],
        cwd=tmp_path, env=user_env(domain), text=True, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE)
    probe = RemoteProbe(domain, 'tools_probe')
    try:
        got = {'tf': [], 'tf_static': [], 'scan': [], 'imu': []}
        node = probe.node
        node.create_subscription(TFMessage, '/tf', got['tf'].append, 100)
        node.create_subscription(TFMessage, '/tf_static', got['tf_static'].append,
                                 QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        node.create_subscription(LaserScan, 'scan', got['scan'].append, 10)
        node.create_subscription(Imu, 'imu', got['imu'].append, 10)
        assert probe.spin_until(lambda: all(got.values()) or process.poll() is not None, 30.0)
        assert all(got.values()), {k: len(v) for k, v in got.items()}
    finally:
        code, out, err = stop_process(process, signal.SIGINT)
        probe.close()
    assert code == 0, err
    assert 'tf2_msgs is not installed' not in err
    pairs = {(t.header.frame_id, t.child_frame_id) for m in got['tf'] for t in m.transforms}
    assert ('odom', 'base_footprint') in pairs
    scan = got['scan'][-1]
    assert len(scan.ranges) == 360 and scan.ranges[180] == pytest.approx(2.0, abs=0.01)
    assert got['imu'][-1].linear_acceleration.z == pytest.approx(9.8, abs=0.3)


def test_the_standard_drives_the_pip_installed_simulator(pip_venv, tmp_path):
    """After tools/build_interfaces.sh VENV, a client of the standard alone drives sim_node."""
    _run(['bash', os.path.join(REPO, 'tools', 'build_interfaces.sh'), str(pip_venv)],
         env=user_env())
    domain = next_domain_id()
    process = subprocess.Popen(
        [str(pip_venv / 'bin' / 'sim_node'), '--ros-args', '-p', 'scan_rate:=60.0'],
        cwd=tmp_path, env=user_env(domain), text=True, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE)
    try:
        out = tmp_path / 'seen.json'
        client = subprocess.run(
            [str(pip_venv / 'bin' / 'python'),
             os.path.join(REPO, 'test', 'children', 'standard_client.py'), str(out)],
            cwd=tmp_path, env=user_env(domain), capture_output=True, text=True, timeout=120)
    finally:
        code, _, err = stop_process(process, signal.SIGINT)
    assert client.returncode == 0, client.stderr + err
    assert code == 0, err
    assert 'simulation_interfaces is not installed' not in err
    seen = json.loads(out.read_text())
    assert seen['clock_advance_ns'] == 10**9
    assert seen['scan_ahead_m'] == pytest.approx(1.35, abs=0.01)
    assert seen['after_delete'] == ['ground_plane', 'r2d2']


def test_readme_examples_run_unchanged_in_the_pip_venv(pip_venv, tmp_path):
    """The testing section's examples pass with nothing but pip install . and pytest."""
    examples = list((Path(REPO) / 'test' / 'examples').glob('test_*.py'))
    for example in examples:
        shutil.copy(example, tmp_path / example.name)
    result = subprocess.run([str(pip_venv / 'bin' / 'python'), '-m', 'pytest', '-q', '-p',
                             'no:cacheprovider', '.'], cwd=tmp_path, env=user_env(),
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert f'{len(examples)} passed' in result.stdout  # one test per example file


def test_the_scenarios_extra_runs_a_documented_scenario_pip_only(pip_venv, tmp_path):
    """
    pip-installed r2d2_sim plus scenario_execution: the command runs docs' crossing, in process.

    The installed package registers osc.r2d2 through its entry points and ships its
    library file; nothing comes from the source tree. (On a copy of the venv: the
    install takes PyYAML down to scenario_execution's pin.)
    """
    pip_venv = private_copy(pip_venv, tmp_path)
    pip = [str(pip_venv / 'bin' / 'python'), '-m', 'pip', 'install', '--quiet',
           '--disable-pip-version-check']
    extra = next(line for line in (Path(REPO) / 'requirements.txt').read_text().splitlines()
                 if line.startswith('scenario_execution'))
    _run(pip + [extra], cwd=tmp_path)
    scenario = tmp_path / 'crossing.osc'
    shutil.copy2(Path(REPO) / 'test' / 'examples' / 'osc' / 'crossing.osc', scenario)
    result = subprocess.run(
        [str(pip_venv / 'bin' / 'scenario_execution'), '--simulation',
         'r2d2_sim.osc:R2D2Simulation', '-o', 'out', str(scenario)], cwd=tmp_path,
        env=user_env(), capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    assert "Scenario 'crossing' succeeded." in result.stdout
    _run([str(pip_venv / 'bin' / 'python'), '-m', 'pip', 'check'], env=user_env())
