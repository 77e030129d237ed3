"""
A user's URDF that PyBullet would crash on or misread: refused in one line before it sees it.

No ROS. PyBullet 3.2 kills the whole process (SIGSEGV) on some URDFs a user
may well write, so these are tried in a process of their own: a crash there
fails the test instead of taking the test runner with it. Every way a URDF
comes in is tried: SpawnEntity by uri and by resource_string, a world's
model, and the ``robot_description`` parameter at start-up; each refusal is
RESOURCE_PARSE_ERROR naming the joint or link, and the URI or "the
resource_string", never a temporary file, and nothing changes.
"""

import json
import subprocess
import sys

import pytest

LINK = ('<link name="{}"><inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" '
        'iyy="0.01" iyz="0" izz="0.01"/></inertial><collision><geometry><box size="0.1 0.1 '
        '0.1"/></geometry></collision></link>')
JOINT = ('<joint name="{}" type="revolute"><parent link="{}"/><child link="{}"/>'
         '<origin xyz="0 0.2 0"/><axis xyz="1 0 0"/>'
         '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>')


def robot(links, *joints: str) -> str:
    """Return a URDF of ``links`` (names) and ``joints`` (their elements' text)."""
    return ('<robot name="r">' + ''.join(LINK.format(name) for name in links) +
            ''.join(joints) + '</robot>')


# name -> (URDF, what the refusal says). PyBullet 3.2.6 crashed on the first five.
REFUSED = {
    'two joints of one name': (
        robot('abc', JOINT.format('j', 'a', 'b'), JOINT.format('j', 'a', 'c')),
        "two joints are named 'j'"),
    'a joint with no name': (robot('ab', JOINT.format('', 'a', 'b')), 'a <joint> has no name'),
    'a joint with no type': (
        robot('ab', JOINT.format('j', 'a', 'b').replace(' type="revolute"', '')),
        "joint 'j' has type '', not one of continuous, fixed, floating, planar, prismatic, "
        'revolute, spherical'),
    'a link that is the child of two joints': (
        robot('abc', JOINT.format('j', 'a', 'c'), JOINT.format('k', 'b', 'c')),
        "link 'c' is the child of two joints"),
    'two root links': (robot('ab'), "the links must make one tree, but 2 links are no joint's "
                                    "child: 'a', 'b'"),
    # PyBullet refused these itself (a link's name taken twice, a joint to no link), or
    # silently dropped links (a loop of joints apart from the root).
    'two links of one name': (robot('abb', JOINT.format('j', 'a', 'b')),
                              "two links are named 'b'"),
    'a joint to no link': (robot('a', JOINT.format('j', 'a', 'zz')),
                           "joint 'j': its child 'zz' names no link"),
    'a loop apart from the root': (
        robot('abc', JOINT.format('j', 'b', 'c'), JOINT.format('k', 'c', 'b')),
        "link 'b' is on a loop of joints, not joined to the root 'a'"),
}

# Run in a child process: every way in, for every URDF; one JSON line of outcomes.
TRY_EVERY_WAY_IN = '''
import json, os, sys
from r2d2_sim.errors import RefusedError, SetupError
from r2d2_sim.sim.settings.robots import parse_world
from r2d2_sim.sim.simulation import Simulation, SpawnRequest
directory, texts = sys.argv[1], json.loads(sys.argv[2])
defaults = {'scan_rate': 0.0, 'imu_rate': 0.0, 'cmd_vel_timeout': 0.0}
simulation = Simulation(*parse_world({**defaults, 'world_paths': [directory]}))
before = simulation.entities.names()
outcomes = {}
for what, text in texts.items():
    path = os.path.join(directory, 'bad.urdf')
    with open(path, 'w') as handle:
        handle.write(text)
    with open(os.path.join(directory, 'bad.world.yaml'), 'w') as handle:
        handle.write('r2d2_sim_world: 1\\nmodels:\\n  - {uri: bad.urdf, name: m}\\n')
    got = []
    for call in (lambda: simulation.spawn(SpawnRequest(resource_string=text)),
                 lambda: simulation.spawn(SpawnRequest(uri=path)),
                 lambda: simulation.load_world(os.path.join(directory, 'bad.world.yaml'))):
        try:
            call()
            got.append('loaded')
        except RefusedError as exc:
            got.append(str(exc))
    try:
        Simulation(*parse_world({**defaults, 'robot_description': text})).close()
        got.append('started')
    except SetupError as exc:
        got.append(str(exc))
    outcomes[what] = got
outcomes['entities unchanged'] = simulation.entities.names() == before
simulation.close()
print(json.dumps(outcomes))
'''


def test_urdfs_pybullet_crashes_on_or_misreads_are_refused_every_way_in(tmp_path):
    texts = {what: text for what, (text, _) in REFUSED.items()}
    result = subprocess.run(
        [sys.executable, '-c', TRY_EVERY_WAY_IN, str(tmp_path), json.dumps(texts)],
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, (result.returncode, result.stderr[-2000:])
    outcomes = json.loads(result.stdout.splitlines()[-1])
    assert outcomes.pop('entities unchanged') is True
    uri, world_uri = str(tmp_path / 'bad.urdf'), str(tmp_path / 'bad.world.yaml')
    for what, (_, problem) in REFUSED.items():
        spawned, by_uri, world, started = outcomes[what]
        assert spawned == f'RESOURCE_PARSE_ERROR: the resource_string: {problem}', what
        assert by_uri == f'RESOURCE_PARSE_ERROR: {uri}: {problem}', what
        assert world == f'RESOURCE_PARSE_ERROR: {world_uri}: model bad.urdf: {problem}', what
        assert started.startswith('cannot load robot_description: ') and problem in started, \
            what
        for message in (spawned, by_uri, world, started):
            assert '\n' not in message and 'r2d2_sim_' not in message, (what, message)


@pytest.mark.parametrize('what', ['two joints of one name', 'two root links'])
def test_the_checked_urdfs_crash_pybullet_itself(tmp_path, what):
    """The reason for the checks: PyBullet, given these URDFs, ends the process (SIGSEGV)."""
    path = tmp_path / 'bad.urdf'
    path.write_text(REFUSED[what][0])
    code = ('import pybullet, sys; client = pybullet.connect(pybullet.DIRECT); '
            'pybullet.loadURDF(sys.argv[1], physicsClientId=client)')
    result = subprocess.run([sys.executable, '-c', code, str(path)], capture_output=True,
                            timeout=60)
    assert result.returncode != 0
