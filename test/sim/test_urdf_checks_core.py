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


def body(collision='<box size="0.2 0.2 0.2"/>', origin='', mass='1', ixx='0.01',
         visual='') -> str:
    """Return a URDF of one link ``l``: a 0.2 m box unless told otherwise."""
    return (f'<robot name="r"><link name="l"><inertial><mass value="{mass}"/><inertia '
            f'ixx="{ixx}" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>'
            f'<collision>{origin}<geometry>{collision}</geometry></collision>{visual}'
            '</link></robot>')


def jointed(axis='<axis xyz="1 0 0"/>', limit='lower="-1" upper="1" effort="1" velocity="1"',
            kind='revolute', dynamics='') -> str:
    """Return a URDF of two boxes on one joint ``j``."""
    joint = (f'<joint name="j" type="{kind}"><parent link="a"/><child link="b"/>'
             f'<origin xyz="0 0.2 0"/>{axis}<limit {limit}/>{dynamics}</joint>')
    return robot('ab', joint)


# name -> (URDF, what the refusal says): what PyBullet 3.2.6 loaded as a success, misread
# with a warning on stdout at most (a box of size 0, NaN bounds, a floating static body).
MISREAD = {
    'a box of 2 numbers': (body('<box size="1 1"/>'),
                           "link 'l': collision box size '1 1' is not 3 finite numbers above 0"),
    'a box of words': (body('<box size="a b c"/>'),
                       "link 'l': collision box size 'a b c' is not 3 finite numbers above 0"),
    'a box of size 0': (body('<box size="1 0 1"/>'),
                        "link 'l': collision box size '1 0 1' is not 3 finite numbers above 0"),
    'an origin of nan': (body(origin='<origin xyz="nan 0 0"/>'),
                         "link 'l': collision origin xyz 'nan 0 0' is not 3 finite numbers"),
    'an infinite rpy': (body(visual='<visual><origin rpy="0 inf 0"/><geometry><sphere '
                                    'radius="1"/></geometry></visual>'),
                        "link 'l': visual origin rpy '0 inf 0' is not 3 finite numbers"),
    'a negative mass': (body(mass='-5'), "link 'l': mass value '-5' is not a finite number >= 0"),
    'a mass of nan': (body(mass='nan'), "link 'l': mass value 'nan' is not a finite number >= 0"),
    'an inertia of words': (body(ixx='big'),
                            "link 'l': inertia ixx 'big' is not a finite number"),
    'a sphere of radius 0': (body('<sphere radius="0"/>'),
                             "link 'l': collision sphere radius '0' is not a finite number "
                             'above 0'),
    'a cylinder of length -1': (body('<cylinder radius="0.1" length="-1"/>'),
                                "link 'l': collision cylinder length '-1' is not a finite "
                                'number above 0'),
    'a capsule of radius inf': (body('<capsule radius="inf" length="1"/>'),
                                "link 'l': collision capsule radius 'inf' is not a finite "
                                'number above 0'),
    'a mesh scale of 0': (body('<mesh filename="cube.obj" scale="1 0 1"/>'),
                          "link 'l': collision mesh scale '1 0 1' is not 3 finite numbers (or "
                          '1), none 0'),
    'a joint axis of 0 0 0': (jointed('<axis xyz="0 0 0"/>'),
                              "joint 'j': axis xyz '0 0 0' is not 3 finite numbers, not all 0"),
    'a joint axis without xyz': (jointed('<axis/>'),
                                 "joint 'j': axis xyz none is not 3 finite numbers, not all 0"),
    'an infinite limit': (jointed(limit='lower="-1" upper="inf" effort="1" velocity="1"'),
                          "joint 'j': limit upper 'inf' is not a finite number"),
    'a damping of nan': (jointed(dynamics='<dynamics damping="nan"/>'),
                         "joint 'j': dynamics damping 'nan' is not a finite number"),
}

# Odd but read right by PyBullet, as its own data has them: they load as written.
READ_RIGHT = {
    'a blank origin, read as 0': body(origin='<origin xyz="" rpy=""/>'),
    'a vector of 4 numbers, the first 3 read': body(origin='<origin xyz="0 0 0 7"/>'),
    'numbers with commas after them': body(origin='<origin xyz="0, 0, 0"/>'),
    'a mass of 0, a static link': body(mass='0'),
    'a visual of radius 0, drawn as nothing': body(
        visual='<visual><geometry><sphere radius="0.0"/></geometry></visual>'),
    'a mesh scale of one number': body('<mesh filename="cube.obj" scale="0.2"/>'),
    'a joint with lower above upper, no limits': jointed(
        limit='lower="1" upper="-1" effort="1" velocity="1"'),
    'a fixed joint with an axis of 0 0 0, unused': jointed('<axis xyz="0 0 0"/>', kind='fixed'),
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
print('\\n' + json.dumps(outcomes))  # PyBullet's messages on stdout end in no newline
'''


def assert_refused_every_way_in(tmp_path, cases):
    """Assert each of ``cases`` (name -> (URDF, problem)) is refused every way in."""
    texts = {what: text for what, (text, _) in cases.items()}
    result = subprocess.run(
        [sys.executable, '-c', TRY_EVERY_WAY_IN, str(tmp_path), json.dumps(texts)],
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, (result.returncode, result.stderr[-2000:])
    outcomes = json.loads(result.stdout.splitlines()[-1])
    unchanged = outcomes.pop('entities unchanged')
    uri, world_uri = str(tmp_path / 'bad.urdf'), str(tmp_path / 'bad.world.yaml')
    for what, (_, problem) in cases.items():
        spawned, by_uri, world, started = outcomes[what]
        assert spawned == f'RESOURCE_PARSE_ERROR: the resource_string: {problem}', what
        assert by_uri == f'RESOURCE_PARSE_ERROR: {uri}: {problem}', what
        assert world == f'RESOURCE_PARSE_ERROR: {world_uri}: model bad.urdf: {problem}', what
        assert started.startswith('cannot load robot_description: ') and problem in started, \
            what
        for message in (spawned, by_uri, world, started):
            assert '\n' not in message and 'r2d2_sim_' not in message, (what, message)
    assert unchanged is True


def test_urdfs_pybullet_crashes_on_or_misreads_are_refused_every_way_in(tmp_path):
    assert_refused_every_way_in(tmp_path, REFUSED)


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


def test_urdfs_pybullet_misreads_are_refused_every_way_in(tmp_path):
    assert_refused_every_way_in(tmp_path, MISREAD)


@pytest.mark.parametrize('what', list(READ_RIGHT))
def test_what_pybullet_reads_right_spawns_as_written(make, tmp_path, what):
    """
    A box of 0.2 m (or pybullet_data's 1 m cube.obj scaled to it) about its link's origin.

    Two jointed boxes of 0.1 m stand 0.2 m apart along y.
    """
    import shutil

    import pybullet_data

    from r2d2_sim.sim.simulation import SpawnRequest
    shutil.copy(f'{pybullet_data.getDataPath()}/cube.obj', tmp_path)
    (tmp_path / 'odd.urdf').write_text(READ_RIGHT[what])
    simulation = make()
    name = simulation.spawn(SpawnRequest(uri=str(tmp_path / 'odd.urdf'),
                                         position=(3.0, 3.0, 2.0)))
    upper, lower = simulation.entities.bounds(name).points  # in the entity's frame
    if 'joint' in what:
        assert lower == pytest.approx((-0.05, -0.05, -0.05), abs=0.005)
        assert upper == pytest.approx((0.05, 0.25, 0.05), abs=0.005)
    else:
        assert lower == pytest.approx((-0.1, -0.1, -0.1), abs=0.005)
        assert upper == pytest.approx((0.1, 0.1, 0.1), abs=0.005)


def test_every_urdf_of_pybullet_data_and_r2d2_sim_that_pybullet_reads_passes():
    """The URDFs GetSpawnables lists and every one of pybullet_data that parses, but husky's."""
    import glob
    import os
    import xml.etree.ElementTree as ElementTree

    import pybullet_data

    from r2d2_sim.physics.description import check_urdf_xml, DescriptionError, SOURCE_TREE
    from r2d2_sim.sim.spawnables import spawnable_uris
    data = pybullet_data.getDataPath()
    paths = glob.glob(os.path.join(data, '**', '*.urdf'), recursive=True)
    paths += glob.glob(os.path.join(SOURCE_TREE, 'urdf', '*.urdf'))
    listed = [uri for uri in spawnable_uris() if not uri.startswith('package://')]
    assert 'r2d2.urdf' in listed and len(listed) > 20
    assert {os.path.join(data, uri) for uri in listed} <= set(paths)
    refused = []
    for path in paths:
        with open(path, encoding='utf-8') as handle:
            text = handle.read()
        try:
            ElementTree.fromstring(text)
        except ElementTree.ParseError:
            continue  # refused as before: three files of pybullet_data are not XML
        try:
            check_urdf_xml(text, path)
        except DescriptionError as exc:
            refused.append(str(exc))
    # A xacro leftover, which PyBullet reads as xyz (0, 0, 0.19): misread, so refused.
    assert refused == [f"cannot load {os.path.join(data, 'husky', 'husky.urdf')}: joint "
                       "'imu_joint' origin xyz '$(optenv HUSKY_IMU_XYZ 0.19 0 0.149)' is not "
                       '3 finite numbers']


# Run in a child process: every start-up parameter that names a URDF, for every URDF; one
# JSON line of outcomes. Its working directory is where the URDF is: PyBullet looks for a
# mesh from there too, which is how robot_description's text finds a relative one.
TRY_EVERY_START_UP = '''
import json, os, sys
from r2d2_sim.errors import SetupError
from r2d2_sim.sim.settings.robots import parse_world
from r2d2_sim.sim.simulation import Simulation
texts = json.loads(sys.argv[1])
path = os.path.abspath('bad.urdf')
defaults = {'scan_rate': 0.0, 'imu_rate': 0.0, 'cmd_vel_timeout': 0.0}
outcomes = {}
for what, text in texts.items():
    with open(path, 'w') as handle:
        handle.write(text)
    got = []
    for parameters in ({'urdf': path}, {'robot_description': text},
                       {'extra_models': [path + ' 2 2 0.5']}, {'world': path}):
        try:
            Simulation(*parse_world({**defaults, **parameters})).close()
            got.append('started')
        except SetupError as exc:
            got.append(str(exc))
    outcomes[what] = got
print('\\n' + json.dumps(outcomes))
'''


def test_start_up_urdfs_pybullet_crashes_or_hangs_on_are_refused_in_one_line(tmp_path):
    """
    The urdf, robot_description, extra_models and world parameters: each a one-line refusal.

    PyBullet ended the whole process on an extra model of two joints of one
    name (SIGSEGV) and on a mesh that is a directory (std::bad_alloc, exit
    134), and waited for ever on a mesh that is a FIFO: a spawn's checks,
    which refused all three, did not run on start-up URDFs.
    """
    import os
    (tmp_path / 'hollow.obj').mkdir()
    os.mkfifo(tmp_path / 'pipe.stl')
    where = str(tmp_path)
    cases = {
        'two joints of one name': REFUSED['two joints of one name'],
        'a mesh that is a directory': (
            body('<mesh filename="hollow.obj"/>'),
            f"link 'l': collision mesh 'hollow.obj' ({where}/hollow.obj) is a directory, not "
            'a regular file'),
        'a mesh that is a FIFO': (
            body('<mesh filename="pipe.stl"/>'),
            f"link 'l': collision mesh 'pipe.stl' ({where}/pipe.stl) is a special file (a FIFO, "
            'socket or device), not a regular file'),
    }
    texts = {what: text for what, (text, _) in cases.items()}
    result = subprocess.run([sys.executable, '-c', TRY_EVERY_START_UP, json.dumps(texts)],
                            cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, (result.returncode, result.stderr[-2000:])
    outcomes = json.loads(result.stdout.splitlines()[-1])
    path = str(tmp_path / 'bad.urdf')
    for what, (_, problem) in cases.items():
        assert outcomes[what] == [f'cannot load {path}: {problem}',
                                  f'cannot load robot_description: {problem}',
                                  f'extra_models: cannot load {path}: {problem}',
                                  f'world {path}: {path}: {problem}'], what


def reaching(joint_origin='0 0.2 0', axis='1 0 0') -> str:
    """Return a URDF of two boxes on one revolute joint ``j`` at ``joint_origin``."""
    return robot('ab', f'<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
                       f'<origin xyz="{joint_origin}"/><axis xyz="{axis}"/>'
                       '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>')


# name -> (URDF, what the refusal says): what PyBullet loaded and could not simulate, its
# state NaN from the first step on (a driven robot put back on every step, for ever).
CANNOT_SIMULATE = {
    'a joint axis of 1e-300 0 0': (
        reaching(axis='1e-300 0 0'),
        "joint 'j': axis xyz '1e-300 0 0' is not a vector of length 1e-09 or more"),
    'a joint origin 1e300 m out': (
        reaching(joint_origin='1e300 0 0'),
        "joint 'j' origin xyz '1e300 0 0' is not within 10000 m of its frame"),
    'a collision origin 20 km out': (
        body(origin='<origin xyz="0 2e4 0"/>'),
        "link 'l': collision origin xyz '0 2e4 0' is not within 10000 m of its frame"),
    'an inertial origin 1e300 m out': (
        body().replace('<inertial>', '<inertial><origin xyz="0 0 1e300"/>'),
        "link 'l': inertial origin xyz '0 0 1e300' is not within 10000 m of its frame"),
    'a box of 1e300 m': (
        body('<box size="1e300 1 1"/>'),
        "link 'l': collision box size '1e300 1 1' is not 10000 m or less each"),
    'a cylinder 20 km long': (
        body('<cylinder radius="0.1" length="2e4"/>'),
        "link 'l': collision cylinder length '2e4' is not 10000 m or less"),
}


def test_urdfs_pybullet_cannot_simulate_are_refused_every_way_in(tmp_path):
    assert_refused_every_way_in(tmp_path, CANNOT_SIMULATE)


def test_what_the_bounds_leave_is_simulated(make):
    """An axis of 1e-6 is a direction, and 10 km is still a length: both load and step."""
    from r2d2_sim.sim.simulation import SpawnRequest
    simulation = make()
    for text in (reaching(axis='1e-6 0 0'), reaching(joint_origin='0 0 1e4'),
                 body('<box size="1e4 0.1 0.1"/>', mass='0')):
        name = simulation.spawn(SpawnRequest(resource_string=text, allow_renaming=True,
                                             position=(3.0, 3.0, 2.0)))
        for _ in range(24):
            simulation.step()
        assert simulation.world.bodies[name].finite(), text


def heavy_child(kg: str) -> str:
    """Return :func:`reaching`'s two boxes, the child ``b`` of ``kg``."""
    return reaching().replace('<link name="b"><inertial><mass value="1"/>',
                              f'<link name="b"><inertial><mass value="{kg}"/>')


# name -> (URDF, what the refusal says): masses and inertias PyBullet loaded and could not
# simulate (NaN from the first step on, or a box sinking through the ground plane).
TOO_HEAVY = {
    'a child link of 1e300 kg': (
        heavy_child('1e300'),
        "link 'b': mass value '1e300' is not 1e9 kg or less"),
    'a box of 1e12 kg': (
        body(mass='1e12'),
        "link 'l': mass value '1e12' is not 1e9 kg or less"),
    'an inertia of 1e300': (
        body(ixx='1e300'),
        "link 'l': inertia ixx '1e300' is not within 1e9 kg m^2 of 0"),
    'a product of inertia of -1e10': (
        body().replace('ixy="0"', 'ixy="-1e10"'),
        "link 'l': inertia ixy '-1e10' is not within 1e9 kg m^2 of 0"),
}


def test_masses_and_inertias_pybullet_cannot_simulate_are_refused_every_way_in(tmp_path):
    """A spawn answered OK read NaN for ever (1e300 kg) or fell through the floor (1e12 kg)."""
    assert_refused_every_way_in(tmp_path, TOO_HEAVY)


def test_the_heaviest_links_the_bounds_leave_stand_on_the_ground(make):
    """A 1e9 kg box and a two-link body whose child is 1e9 kg stay on the ground, finite."""
    from r2d2_sim.sim.simulation import SpawnRequest
    simulation = make()
    heavy = heavy_child('1e9')
    names = [simulation.spawn(SpawnRequest(resource_string=text, allow_renaming=True,
                                           position=position))
             for text, position in ((body(mass='1e9', ixx='1e9'), (3.0, 3.0, 0.1)),
                                    (heavy, (-3.0, 3.0, 0.1)))]
    for _ in range(480):
        simulation.step()
    for name in names:
        assert simulation.world.bodies[name].finite(), name
        assert simulation.entities.state(name).position[2] > -0.05, name


def two_boxes(inertia: str, mass='1', base_mass='1') -> str:
    """Return a URDF of two boxes on a continuous joint, both of ``inertia`` (ixx iyy izz)."""
    ixx, iyy, izz = inertia.split()

    def link(name, kg):
        return (f'<link name="{name}"><inertial><mass value="{kg}"/><inertia ixx="{ixx}" '
                f'ixy="0" ixz="0" iyy="{iyy}" iyz="0" izz="{izz}"/></inertial><collision>'
                '<geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>')
    return (f'<robot name="t">{link("a", base_mass)}{link("b", mass)}<joint name="j" '
            'type="continuous"><parent link="a"/><child link="b"/><origin xyz="0.2 0 0"/>'
            '<axis xyz="0 0 1"/></joint></robot>')


NO_WHEELS = {'left_wheel_names': [], 'right_wheel_names': [], 'scan_rate': 0.0}


@pytest.mark.parametrize('inertia, moments', [
    ('0 0 0', '(0, 0, 0)'),
    ('-0.01 0.01 0.01', '(-0.01, 0.01, 0.01)'),
    ('1 0.01 0.01', '(0.01, 0.01, 1)'),  # PyBullet reads one above the other two as 0 too
])
def test_a_driven_robot_needs_inertias_pybullet_does_not_read_as_0(make, inertia, moments):
    """
    At start-up and as a spawned robot: refused in one line; as a plain body, loaded.

    A driven robot takes its inertias from the file: with these (PyBullet read
    each as 0) it blew up on its first step, and on every step it was put
    back, 240 error lines a second, for ever. A plain body takes them from
    its shapes and simulates.
    """
    from r2d2_sim.errors import RefusedError, SetupError
    from r2d2_sim.sim.simulation import SpawnRequest
    text = two_boxes(inertia)
    problem = (f"link 'a': a driven robot's link of 1 kg needs an inertia of principal moments "
               f'above 0, none above the other two together, not {moments}: PyBullet reads it '
               'as 0')
    with pytest.raises(SetupError) as refused:
        make(robot_description=text, **NO_WHEELS)
    assert str(refused.value) == f'cannot load robot_description: {problem}'
    simulation = make(scan_rate=0.0)
    before = simulation.entities.names()
    with pytest.raises(RefusedError) as spawned:
        simulation.spawn(SpawnRequest('t', resource_string=text, namespace='t',
                                      position=(2.0, 2.0, 0.1)))
    assert str(spawned.value) == f'RESOURCE_PARSE_ERROR: the resource_string: {problem}'
    assert simulation.entities.names() == before
    name = simulation.spawn(SpawnRequest('t', resource_string=text, position=(2.0, 2.0, 0.1)))
    for _ in range(240):
        simulation.step()
    assert simulation.world.bodies[name].finite()


def test_a_driven_robot_of_mass_0_or_of_inertias_pybullet_reads_starts_and_stays(make):
    """A base of mass 0 is static (inertia 0 unused); real inertias drive: no blow-up."""
    for text in (two_boxes('0 0 0', mass='0', base_mass='0'), two_boxes('0.01 0.01 0.01'),
                 two_boxes('0.02 0.01 0.01')):
        simulation = make(robot_description=text, **NO_WHEELS)
        for _ in range(240):
            simulation.step()
        assert simulation.blow_ups == 0 and simulation.robot.body.finite()
