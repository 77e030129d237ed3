"""Check urdf/r2d2.urdf: inertias, joint tree, limits and REP-103 driving in PyBullet."""

import math
import os
import xml.etree.ElementTree as ET

import pybullet
import pybullet_data
from pybullet_utils.bullet_client import BulletClient
import pytest

from common import REPO

URDF_PATH = os.path.join(REPO, 'urdf', 'r2d2.urdf')
WHEEL_JOINTS = {
    'left_front_wheel_joint': 'left',
    'left_back_wheel_joint': 'left',
    'right_front_wheel_joint': 'right',
    'right_back_wheel_joint': 'right',
}
BASE_HEIGHT = 0.47
TIME_STEP = 1.0 / 240.0
REL_TOL = 1e-3


def classic_urdf_path():
    """Return the path of the classic pybullet_data r2d2.urdf."""
    return os.path.join(pybullet_data.getDataPath(), 'r2d2.urdf')


def parse(path):
    """Parse a URDF file and return its root <robot> element."""
    return ET.parse(path).getroot()


def floats(text, default):
    """Split a whitespace separated attribute into floats, or return the default."""
    if text is None:
        return list(default)
    return [float(v) for v in text.split()]


def origin_of(element):
    """Return (xyz, rpy) of an element's <origin> child, zeros when absent."""
    origin = element.find('origin')
    if origin is None:
        return [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
    return (floats(origin.get('xyz'), [0.0, 0.0, 0.0]),
            floats(origin.get('rpy'), [0.0, 0.0, 0.0]))


def joints_of(robot):
    """Return (name, type, parent, child) for every joint in order of appearance."""
    return [(j.get('name'), j.get('type'), j.find('parent').get('link'),
             j.find('child').get('link')) for j in robot.findall('joint')]


def expected_principal_inertia(geometry, mass):
    """Compute the solid-body principal inertia (ixx, iyy, izz) of a URDF primitive."""
    shape = list(geometry)[0]
    if shape.tag == 'box':
        x, y, z = floats(shape.get('size'), [])
        return (mass / 12.0 * (y * y + z * z),
                mass / 12.0 * (x * x + z * z),
                mass / 12.0 * (x * x + y * y))
    if shape.tag == 'cylinder':
        r = float(shape.get('radius'))
        h = float(shape.get('length'))
        transverse = mass * (3.0 * r * r + h * h) / 12.0
        return transverse, transverse, mass * r * r / 2.0
    if shape.tag == 'sphere':
        r = float(shape.get('radius'))
        value = 0.4 * mass * r * r
        return value, value, value
    raise AssertionError('unsupported collision geometry <%s>' % shape.tag)


def make_sim():
    """Connect a DIRECT client with a ground plane and the robot at rest height."""
    client = BulletClient(connection_mode=pybullet.DIRECT)
    client.setAdditionalSearchPath(pybullet_data.getDataPath())
    client.setGravity(0, 0, -9.8)
    client.setTimeStep(TIME_STEP)
    plane = client.loadURDF('plane.urdf')
    robot = client.loadURDF(URDF_PATH, [0, 0, BASE_HEIGHT])
    return client, robot, plane


def joint_indices(client, robot):
    """Map every joint name to its PyBullet index, read via getJointInfo."""
    return {client.getJointInfo(robot, i)[1].decode(): i
            for i in range(client.getNumJoints(robot))}


def step(client, count):
    """Advance the simulation by a number of steps."""
    for _ in range(count):
        client.stepSimulation()


def base_pose(client, robot):
    """Return the base position and (roll, pitch, yaw)."""
    position, orientation = client.getBasePositionAndOrientation(robot)
    return position, client.getEulerFromQuaternion(orientation)


def wrap(angle):
    """Wrap an angle to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def drive(client, robot, left, right, steps):
    """Command wheel velocities (rad/s) and return (dx, dy, dyaw) after the given steps."""
    indices = joint_indices(client, robot)
    for name, side in WHEEL_JOINTS.items():
        client.setJointMotorControl2(robot, indices[name], pybullet.VELOCITY_CONTROL,
                                     targetVelocity=left if side == 'left' else right,
                                     force=20.0)
    (x0, y0, _), (_, _, yaw0) = base_pose(client, robot)
    total_yaw = 0.0
    for _ in range(steps):
        client.stepSimulation()
        _, (_, _, yaw) = base_pose(client, robot)
        total_yaw += wrap(yaw - yaw0)
        yaw0 = yaw
    (x1, y1, _), _ = base_pose(client, robot)
    return x1 - x0, y1 - y0, total_yaw


@pytest.fixture
def sim():
    """Yield a fresh settled simulation (client, robot, plane) and disconnect it after."""
    client, robot, plane = make_sim()
    step(client, 240)
    try:
        yield client, robot, plane
    finally:
        client.disconnect()


def test_every_link_has_one_primitive_collision_and_no_mesh():
    """Check each link has exactly one box/cylinder/sphere collision and nothing uses a mesh."""
    robot = parse(URDF_PATH)
    assert robot.findall('.//mesh') == []
    for link in robot.findall('link'):
        collisions = link.findall('collision')
        assert len(collisions) == 1, link.get('name')
        shapes = list(collisions[0].find('geometry'))
        assert len(shapes) == 1 and shapes[0].tag in ('box', 'cylinder', 'sphere'), \
            link.get('name')


def test_inertias_are_computed_from_collision_geometry():
    """Recompute every inertia tensor from the collision primitive and mass."""
    robot = parse(URDF_PATH)
    links = robot.findall('link')
    assert len(links) == 16
    for link in links:
        name = link.get('name')
        collision = link.find('collision')
        inertial = link.find('inertial')
        assert inertial is not None, name
        mass = float(inertial.find('mass').get('value'))
        assert mass > 0.0, name
        c_xyz, c_rpy = origin_of(collision)
        i_xyz, i_rpy = origin_of(inertial)
        assert i_xyz == pytest.approx(c_xyz, abs=1e-9), name
        assert i_rpy == pytest.approx(c_rpy, abs=1e-9), name
        tensor = inertial.find('inertia')
        got = {k: float(tensor.get(k)) for k in ('ixx', 'iyy', 'izz', 'ixy', 'ixz', 'iyz')}
        want = expected_principal_inertia(collision.find('geometry'), mass)
        assert (got['ixx'], got['iyy'], got['izz']) == pytest.approx(want, rel=REL_TOL), name
        assert (got['ixy'], got['ixz'], got['iyz']) == (0.0, 0.0, 0.0), name


def test_no_inertia_is_identity():
    """Check no link keeps the classic's placeholder identity inertia."""
    for link in parse(URDF_PATH).findall('link'):
        tensor = link.find('inertial/inertia')
        diagonal = [float(tensor.get(k)) for k in ('ixx', 'iyy', 'izz')]
        assert diagonal != [1.0, 1.0, 1.0], link.get('name')


def test_joint_names_and_tree_match_classic():
    """Check the 15 joints, their order and parent/child links equal the classic model's."""
    ours = [(n, p, c) for n, _, p, c in joints_of(parse(URDF_PATH))]
    classic = [(n, p, c) for n, _, p, c in joints_of(parse(classic_urdf_path()))]
    assert len(classic) == 15
    assert ours == classic


def test_pybullet_joint_indices_match_classic():
    """Check PyBullet assigns each joint the same index as in the classic model."""
    client = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        ours = client.loadURDF(URDF_PATH)
        classic = client.loadURDF(classic_urdf_path(), [2, 0, 0])
        assert joint_indices(client, ours) == joint_indices(client, classic)
    finally:
        client.disconnect()


def test_joint_limits_and_wheel_types():
    """Check moving joints have positive effort/velocity limits and wheels are continuous."""
    robot = parse(URDF_PATH)
    types = {}
    for joint in robot.findall('joint'):
        name, kind = joint.get('name'), joint.get('type')
        types[name] = kind
        if kind == 'fixed':
            continue
        limit = joint.find('limit')
        assert limit is not None, name
        assert float(limit.get('effort')) > 0.0, name
        assert float(limit.get('velocity')) > 0.0, name
        if kind in ('revolute', 'prismatic'):
            assert float(limit.get('lower')) < float(limit.get('upper')), name
    for name in WHEEL_JOINTS:
        assert types[name] == 'continuous', name
        axis = robot.find("joint[@name='%s']/axis" % name)
        assert floats(axis.get('xyz'), []) == [0.0, 1.0, 0.0], name
    assert types['gripper_extension'] == 'prismatic'
    axis = robot.find("joint[@name='gripper_extension']/axis")
    assert floats(axis.get('xyz'), []) == [1.0, 0.0, 0.0]


def test_rests_level_on_its_four_wheels(sim):
    """Check the settled robot is level at 0.47 m, touching the plane only with its wheels."""
    client, robot, plane = sim
    (_, _, z), (roll, pitch, _) = base_pose(client, robot)
    assert abs(math.degrees(roll)) < 1.0
    assert abs(math.degrees(pitch)) < 1.0
    assert z == pytest.approx(BASE_HEIGHT, abs=0.01)
    indices = joint_indices(client, robot)
    wheels = {indices[name] for name in WHEEL_JOINTS}
    touching = {contact[3] for contact in client.getContactPoints(robot, plane)}
    assert touching == wheels
    for name, side in WHEEL_JOINTS.items():
        x, y, _ = client.getLinkState(robot, indices[name])[0]
        assert (y > 0.0) == (side == 'left'), name
        assert (x > 0.0) == ('front' in name), name


def test_positive_wheel_velocity_drives_forward(sim):
    """Check +5 rad/s on all wheels moves the base straight along +x."""
    client, robot, _ = sim
    dx, dy, dyaw = drive(client, robot, 5.0, 5.0, 480)
    assert dx > 0.2
    assert abs(dy) < 0.05 * dx
    assert abs(math.degrees(dyaw)) < 5.0


def test_left_forward_right_backward_turns_clockwise(sim):
    """Check left +5 / right -5 rad/s decreases yaw (clockwise seen from above)."""
    client, robot, _ = sim
    _, _, dyaw = drive(client, robot, 5.0, -5.0, 480)
    assert dyaw < -0.1
