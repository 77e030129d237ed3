"""
Helpers every tier of this project's tests may use: no ROS, no PyBullet.

The fast tier (``test/model``, ``test/physics``, ``test/sim``) imports from
here, never from ``helpers`` (which loads rclpy and the node). What several
tiers share after a test file was split by tier lives here too, under the
names the tests call it by; the ROS helpers shared that way are in ``helpers``.
Imports of anything heavier than the standard library happen inside the
functions, so importing this module stays cheap (the top conftest does).
"""

import json
import math
import os
from pathlib import Path
import re
import sys

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TEST_DIR = os.path.join(REPO, 'test')
RATE_HZ = 240

# Leases taken by helpers.next_domain_id, released by conftest after each test.
leases = []


def load_r2d2(world, pose=(0.0, 0.0, 0.0), urdf=None):
    """Load R2D2 (the package's, or ``urdf``) standing at (x, y, yaw), as a robot is loaded."""
    from r2d2_sim.physics.description import default_urdf_path
    return world.load_robot(urdf or default_urdf_path(), pose)


# -- the classic R2D2: ros/test_robots.py, ros/test_camera_ros.py, system/test_robots_system.py

CLASSIC_YAML = os.path.join(REPO, 'urdf', 'classic_r2d2.yaml')


def classic_params():
    """Return the parameters of urdf/classic_r2d2.yaml as a dict."""
    import yaml
    with open(CLASSIC_YAML, encoding='utf-8') as handle:
        return yaml.safe_load(handle)['r2d2_sim']['ros__parameters']


# -- what the demo prints and writes: apps/test_demo_apps.py and system/test_demo.py

PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'
PROGRESS = re.compile(
    r'^t=\s*(?P<t>[-+\d.]+) s\s+odom x=(?P<ox>\S+) y=(?P<oy>\S+) yaw=\s*(?P<oyaw>\S+) deg'
    r' \| truth x=(?P<tx>\S+) y=(?P<ty>\S+) yaw=\s*(?P<tyaw>\S+) deg$')

# -- sim_node --help: apps/test_cli_apps.py and system/test_cli.py


def _check_help(text, prog):
    """Check the help text: a usage line for ``prog``, then every parameter of the table."""
    from r2d2_sim.sim.settings.table import PARAMETERS
    assert text.startswith(f'usage: {prog} [-h] [--ros-args [-p NAME:=VALUE]...'), text[:200]
    flat = ' '.join(text.split())  # the lines are wrapped to 79 columns
    for spec in PARAMETERS:
        assert f' {spec.name}: {spec.ros_type}; default {json.dumps(spec.default)}' in flat, \
            spec.name
        assert ' '.join(spec.description.split()) in flat, spec.name
    assert 'physics_rate: double; default 240.0; range [10, 10000] Hz' in flat
    assert 'publish_rate: double; default 0.0; range [0.001, 10000] Hz or 0 (every step)' in flat
    assert 'noise_seed: integer; default 0; range [0, 2147483647]; per robot' in flat
    assert 'robots: string_array; default []' in flat and '-p b.initial_pose:=' in flat
    assert 'base_forward_axis: string; default "x"; one of x, y, -x, -y' in flat
    assert max(len(line) for line in text.splitlines()) <= 90


# -- MCAP files read back: recording/test_foxglove_sink.py, system/test_foxglove_sink_system.py


def read_with_mcap(path):
    """Return (header, summary, [(channel, schema, message)]) from mcap's reader."""
    from mcap.reader import make_reader
    with open(path, 'rb') as stream:
        reader = make_reader(stream)
        header, summary = reader.get_header(), reader.get_summary()
        messages = [(channel, schema, message)
                    for schema, channel, message in reader.iter_messages(log_time_order=False)]
    return header, summary, messages


# -- a small box to spawn: ros/test_sim_interfaces.py and system/test_sim_interfaces_system.py

BOX = ('<robot name="box"><link name="box"><inertial><mass value="1"/><inertia ixx="0.01" '
       'iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial><collision><geometry>'
       '<box size="0.2 0.2 0.2"/></geometry></collision></link></robot>')

# -- the README's examples: testing/test_testing_api.py, system/test_testing_api_system.py

EXAMPLES = Path(REPO) / 'test' / 'examples'
# In README order.
EXAMPLE_FILES = ['test_drive_forward.py', 'test_closed_loop.py', 'test_sim_process.py',
                 'test_change_the_world.py', 'test_stopper.py', 'test_two_robots.py']

# -- rigid transforms: model/test_transforms.py and physics/test_transforms_physics.py

PACKAGE_URDF = os.path.join(REPO, 'urdf', 'r2d2.urdf')


def classic_urdf_path():
    pybullet_data = pytest.importorskip('pybullet_data')
    return os.path.join(pybullet_data.getDataPath(), 'r2d2.urdf')


def read(path):
    with open(path) as f:
        return f.read()


def matrix_of(q):
    """Columns are the images of x, y and z, so the result reads as a rotation matrix."""
    from r2d2_sim.model.transforms import rotate
    columns = [rotate(q, axis) for axis in ((1, 0, 0), (0, 1, 0), (0, 0, 1))]
    return [[columns[c][r] for c in range(3)] for r in range(3)]


def assert_same_transform(actual, expected, tol=1e-12):
    """Compare translations and rotation matrices (q and -q are the same rotation)."""
    assert actual.translation == pytest.approx(expected.translation, abs=tol)
    for row_a, row_e in zip(matrix_of(actual.rotation), matrix_of(expected.rotation)):
        assert row_a == pytest.approx(row_e, abs=tol)


def robot(*joints):
    return '<robot name="r">' + ''.join(joints) + '</robot>'


# -- the transform buffer: model/test_tf_buffer.py and ros/test_tf_buffer_ros.py


def yaw(angle_rad):
    """Return the quaternion of a turn about z."""
    return (0.0, 0.0, math.sin(angle_rad / 2.0), math.cos(angle_rad / 2.0))


def approx(values, tol=1e-12):
    return pytest.approx(values, abs=tol)


# -- the room's surfaces: sim/test_camera_info_samples.py, sim/test_point_clouds_core.py

ROOM = 'package://r2d2_sim/urdf/room.urdf'
# urdf/room.urdf: four walls and three boxes, each (low corner, high corner), on the floor z = 0.
ROOM_SOLIDS = [((2.0, -2.6, 0.0), (2.1, 2.6, 1.0)), ((-3.1, -2.6, 0.0), (-3.0, 2.6, 1.0)),
               ((-3.0, 2.5, 0.0), (2.0, 2.6, 1.0)), ((-3.0, -2.6, 0.0), (2.0, -2.5, 1.0)),
               ((0.8, 1.0, 0.0), (1.2, 1.4, 0.4)), ((-1.7, -1.2, 0.0), (-1.3, -0.8, 0.4)),
               ((-0.2, -1.7, 0.0), (0.2, -1.3, 0.4))]


def distance_to_the_room(points):
    """Return each point's (N x 3, world) distance to the room's nearest surface or floor."""
    import numpy
    distance = numpy.abs(points[:, 2])
    for low, high in ROOM_SOLIDS:
        centre, half = numpy.add(low, high) / 2.0, numpy.subtract(high, low) / 2.0
        q = numpy.abs(points - centre) - half
        signed = numpy.linalg.norm(numpy.maximum(q, 0.0), axis=1) + numpy.minimum(q.max(1), 0.0)
        distance = numpy.minimum(distance, numpy.abs(signed))
    return distance


# -- OpenSCENARIO scenarios (test/osc, system/test_osc_over_ros.py) ---------------------------

OSC_EXAMPLES = Path(REPO) / 'test' / 'examples' / 'osc'


def osc_env(shim_dir, **extra):
    """
    Return an environment in which scenario_execution finds osc.r2d2 from this source tree.

    An installed r2d2_sim registers its entry points; a source checkout does
    not, so a shim ``.dist-info`` is written into ``shim_dir`` and put on
    PYTHONPATH before the tree. ``extra``: more variables (ROS_DOMAIN_ID...).
    """
    from r2d2_sim.osc.entry_points import write_shim
    env = dict(os.environ)
    # A build in the tree (pip wheel, setup.py) leaves an egg-info that registers them
    # already: a second registration would make scenario_execution refuse both.
    built = any('r2d2_sim.osc:library' in (info / 'entry_points.txt').read_text()
                for info in Path(REPO).glob('*.egg-info') if (info / 'entry_points.txt').exists())
    shim = '' if built else write_shim(str(shim_dir))
    env['PYTHONPATH'] = os.pathsep.join(p for p in (shim, REPO, env.get('PYTHONPATH')) if p)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.update({key: str(value) for key, value in extra.items()})
    return env


def scenario_execution(args, env, cwd, timeout_s=300):
    """Run the scenario_execution command; return (exit status, its output, test.xml's cases)."""
    import subprocess
    import sys
    import xml.etree.ElementTree as ElementTree
    command = os.path.join(os.path.dirname(sys.executable), 'scenario_execution')
    result = subprocess.run([command, '-o', 'out', *map(str, args)], cwd=cwd, env=env,
                            capture_output=True, text=True, timeout=timeout_s)
    junit = Path(cwd) / 'out' / 'test.xml'
    cases = {}
    if junit.exists():
        for case in ElementTree.parse(junit).getroot().iter('testcase'):
            failure = case.find('failure')
            cases[case.get('name')] = None if failure is None else failure.get('message')
    return result.returncode, result.stdout + result.stderr, cases


# -- the learning environments: gym/test_gym_env.py, gym/test_gym_parallel.py, gym_ros/,
# system/test_gym_system.py

def gym_actions(seed, count=40):
    """Return ``count`` random actions in [-1, 1] (float32) drawn from ``seed``."""
    import numpy
    return numpy.random.default_rng(seed).uniform(-1.0, 1.0, (count, 2)).astype(numpy.float32)


def gym_rollout(env, seed, actions, options=None):
    """Reset with ``seed``, step ``actions`` until the end; return a hash of all it returned."""
    import hashlib
    import numpy
    digest = hashlib.sha256()
    observation, info = env.reset(seed=seed, options=options)
    digest.update(_observation_bytes(observation) + json.dumps(info, sort_keys=True).encode())
    for action in actions:
        observation, reward, terminated, truncated, info = env.step(action)
        digest.update(_observation_bytes(observation) + numpy.float64(reward).tobytes()
                      + json.dumps(info, sort_keys=True).encode())
        if terminated or truncated:
            break
    return digest.hexdigest()


def _observation_bytes(observation):
    if isinstance(observation, dict):
        return b''.join(observation[key].tobytes() for key in sorted(observation))
    return observation.tobytes()


def parallel_rollout(env, seed, steps=30):
    """Reset a ParallelEnv with ``seed``; step random actions (from the seed); a hash."""
    import hashlib
    import numpy
    rng = numpy.random.default_rng(seed)
    digest = hashlib.sha256()
    observations, _ = env.reset(seed=seed)
    for _ in range(steps):
        for agent in sorted(observations):
            digest.update(agent.encode() + observations[agent].tobytes())
        if not env.agents:
            break
        actions = {agent: rng.uniform(-1, 1, 2).astype(numpy.float32) for agent in env.agents}
        observations, rewards, _, _, _ = env.step(actions)
        digest.update(repr(sorted(rewards.items())).encode())
    return digest.hexdigest()


def setup_py_console_scripts():
    """
    Return setup.py's ``console_scripts`` entries, read from its syntax tree (not run).

    Only that key is read as a literal: ``entry_points`` also spreads the
    OpenSCENARIO library's entry points (``**OSC_ENTRY_POINTS``), which are not.
    """
    import ast
    tree = ast.parse((Path(REPO) / 'setup.py').read_text(encoding='utf-8'))
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, 'id', '') == 'setup':
            for keyword in node.keywords:
                if keyword.arg == 'entry_points' and isinstance(keyword.value, ast.Dict):
                    for key, value in zip(keyword.value.keys, keyword.value.values):
                        if isinstance(key, ast.Constant) and key.value == 'console_scripts':
                            return ast.literal_eval(value)
    raise AssertionError('setup.py has no console_scripts')


def clean_fast_dds_zombies() -> None:
    """
    Run eProsima's ``fastdds shm clean`` (the venv's copy), which removes only unlocked files.

    A process killed with SIGKILL (this suite kills many on purpose) leaves its
    segments and ports in /dev/shm; later participants on the same domain then
    wait on them (docs/limits.md), and the suite slowed run after run: one
    module of ours took 23.3 s with 84 such files about, 16.5 s without.
    Only at the session's start: during it, a test may be checking that
    r2d2_sim's own farm removed a killed worker's files.
    """
    import contextlib
    import importlib.util
    import io
    tool = Path(sys.prefix) / 'tools' / 'fastdds' / 'shm' / 'clean.py'
    spec = importlib.util.spec_from_file_location('fastdds_shm_clean', tool)
    if not tool.is_file() or spec is None or spec.loader is None:
        return  # a ROS install elsewhere: its own tool, not ours to run
    module = importlib.util.module_from_spec(spec)
    with contextlib.redirect_stdout(io.StringIO()):
        spec.loader.exec_module(module)
        module.Clean().run()


def gym_noisy():
    """
    Return the learning environments' keywords for a noisy scan, in process and over ROS.

    Each episode draws its scan noise from the space (0.02 to 0.05 m), so that the seed's
    noise is part of what must repeat. (A function: the gym package loads Gymnasium.)
    """
    import dataclasses
    from r2d2_sim.gym.settings import DEFAULT_SPACE
    return {'space': dataclasses.replace(DEFAULT_SPACE, scan_noise_std=(0.02, 0.05))}


def drive_and_read(simulation, steps=240):
    """Drive every robot of a core Simulation for ``steps``; return each body's name and state."""
    for robot in simulation.robots:
        robot.command(0.4, 0.3)
    for _ in range(steps):
        simulation.step()
    return [(name, body.world_state()) for name, body in simulation.world.bodies.items()]


def connected_clients():
    """Return the ids of the PyBullet clients connected in this process."""
    import pybullet
    return [i for i in range(64) if pybullet.isConnected(physicsClientId=i)]


class FakeGoal:
    """
    What the standard's _simulate_steps uses of a ServerGoalHandle, in process.

    Keeps each feedback's (completed, remaining) and how the goal ended. A cancel is
    requested after ``cancel_after`` feedbacks; ``call()`` runs after ``call_after``
    (what a request from the executor's other thread would do between chunks), its
    replies kept.
    """

    def __init__(self, steps, cancel_after=None, call_after=None, call=None):
        from simulation_interfaces.action import SimulateSteps
        self.request = SimulateSteps.Goal(steps=steps)
        self.feedback, self.ended, self.replies = [], None, []
        self._cancel_after, self._call_after, self._call = cancel_after, call_after, call

    @property
    def is_cancel_requested(self):
        return self._cancel_after is not None and len(self.feedback) >= self._cancel_after

    def publish_feedback(self, feedback):
        self.feedback.append((feedback.completed_steps, feedback.remaining_steps))
        if self._call is not None and len(self.feedback) == self._call_after:
            self.replies.append(self._call())

    def succeed(self):
        self.ended = 'succeeded'

    def canceled(self):
        self.ended = 'canceled'

    def abort(self):
        self.ended = 'aborted'


# -- the interface build missing: testing/test_interfaces_missing.py, system/test_process_...

def block_package(monkeypatch, package):
    """Make every import of ``package`` and its modules fail, as if it were not installed."""
    for name in [n for n in sys.modules if n == package or n.startswith(package + '.')]:
        monkeypatch.delitem(sys.modules, name)
    for name in (package, package + '.msg', package + '.srv', package + '.action'):
        monkeypatch.setitem(sys.modules, name, None)  # import raises ImportError


def assert_says_build(error, package):
    """Assert a raised MissingInterfaceError is one line naming ``package`` and the build."""
    text = str(error.value)
    assert '\n' not in text and package in text and 'tools/build_interfaces.sh VENV' in text
    assert type(error.value).__name__ == 'MissingInterfaceError'
