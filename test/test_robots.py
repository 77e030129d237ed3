"""
Any robot description: files, package:// URIs, pybullet_data names, XML text, the classic R2D2.

The classic (pybullet_data/r2d2.urdf) drives along its base +y with negative
wheel velocities; with urdf/classic_r2d2.yaml it must answer cmd_vel exactly
like the package's own REP-103 robot.
"""

import json
import math
import os

from helpers import (
    drive_forward_until, latest_truth, make_sim, next_domain_id, Probe, RemoteProbe, REPO,
    start_sim_process, stop_process)
import pybullet_data
import pytest
from std_srvs.srv import Trigger
import yaml

from r2d2_sim.physics.description import (
    default_urdf_path, DescriptionError, resolve_description_path)
from r2d2_sim.ros.joint_info import joint_info
from r2d2_sim.physics.world import SimWorld, WorldError
from r2d2_sim.ros.node import StartupError
from r2d2_sim.sim.parameters import parse_config
from r2d2_sim.sim.simulation import Simulation

CLASSIC_YAML = os.path.join(REPO, 'urdf', 'classic_r2d2.yaml')


def classic_params():
    """Return the parameters of urdf/classic_r2d2.yaml as a dict."""
    with open(CLASSIC_YAML, encoding='utf-8') as handle:
        return yaml.safe_load(handle)['r2d2_sim']['ros__parameters']


@pytest.fixture
def fake_package(tmp_path, monkeypatch):
    """Install a package 'fake_robots' with urdf/robot.urdf in a temporary ament prefix."""
    index = tmp_path / 'share' / 'ament_index' / 'resource_index' / 'packages'
    index.mkdir(parents=True)
    (index / 'fake_robots').write_text('')
    urdf_dir = tmp_path / 'share' / 'fake_robots' / 'urdf'
    urdf_dir.mkdir(parents=True)
    with open(default_urdf_path(), encoding='utf-8') as handle:
        (urdf_dir / 'robot.urdf').write_text(handle.read())
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    return urdf_dir / 'robot.urdf'


def test_bare_names_resolve_in_pybullet_data():
    """'cube.urdf' is pybullet_data's cube."""
    assert resolve_description_path('cube.urdf') == os.path.join(
        pybullet_data.getDataPath(), 'cube.urdf')


def test_file_paths_win_over_pybullet_data(tmp_path, monkeypatch):
    """A relative path that exists is used as a file, made absolute."""
    (tmp_path / 'cube.urdf').write_text('<robot name="mine"/>')
    monkeypatch.chdir(tmp_path)
    assert resolve_description_path('cube.urdf') == str(tmp_path / 'cube.urdf')


def test_package_uri_resolves_through_the_ament_index(fake_package):
    """package://fake_robots/urdf/robot.urdf is the file in its share directory."""
    assert resolve_description_path('package://fake_robots/urdf/robot.urdf') == \
        str(fake_package)


@pytest.mark.parametrize('spec, fragment', [
    ('package://no_such_package/urdf/x.urdf', "'no_such_package' is not in the ament index"),
    ('package://fake_robots/urdf/missing.urdf', 'not found'),
    ('package://fake_robots', 'malformed package URI'),
    ('no_such_robot.urdf', 'not found'),
])
def test_unresolvable_descriptions_name_the_problem(fake_package, spec, fragment):
    """Unknown packages, files and names give one line naming them."""
    with pytest.raises(DescriptionError, match=fragment) as info:
        resolve_description_path(spec)
    assert '\n' not in str(info.value)


def test_a_robot_without_joints_is_simulated():
    """pybullet_data's cube: no joints, empty joint readouts, a sane base state."""
    with SimWorld() as world:
        robot = world.load_robot(resolve_description_path('cube.urdf'), (0.0, 0.0, 0.0))
        assert robot.joints == {} and robot.movable_joints() == []
        assert robot.joint_states([]).positions == []
        assert joint_info(robot) == []
        world.step(24)
        assert robot.state_problem() is None
        assert robot.base_state().position[2] == pytest.approx(0.5, abs=0.01)


def test_body_yaw_offset_reports_the_rep103_frame():
    """The classic with +pi/2: body yaw = spawn heading, URDF base turned by -pi/2."""
    with SimWorld() as world:
        robot = world.load_robot(resolve_description_path('r2d2.urdf'), (0.0, 0.0, 0.3),
                                 math.pi / 2)
        base = robot.base_state()
        client = world.client
        body_yaw = client.getEulerFromQuaternion(base.orientation)[2]
        urdf_orientation = client.getBasePositionAndOrientation(robot.id)[1]
        assert body_yaw == pytest.approx(0.3, abs=1e-6)
        assert client.getEulerFromQuaternion(urdf_orientation)[2] == \
            pytest.approx(0.3 - math.pi / 2, abs=1e-6)
        # The left leg is at URDF x = -0.22: body y = +0.22.
        left_leg = robot.joint('base_to_left_leg').index
        left = robot.link_positions_in_base([left_leg])[0]
        assert left[1] == pytest.approx(0.22, abs=1e-3)


def test_node_with_cube_ignores_cmd_vel_without_crashing(ros):
    """A robot with none of the wheel joints: empty joint_states, cmd_vel ignored."""
    sim = make_sim(ros, urdf='cube.urdf')
    probe = Probe(ros, sim)
    assert not sim.has_wheels
    probe.send(0.3, 0.5)
    sim.advance(24)
    probe.wait_count('ground_truth', 24)
    assert list(probe.messages['joint_states'][-1].name) == []
    assert probe.messages['odom'] == []
    truth = probe.messages['ground_truth'][-1].pose.pose.position
    assert (truth.x, truth.y) == pytest.approx((0.0, 0.0), abs=1e-3)
    response = probe.call(Trigger, '/r2d2_sim/get_joint_info', Trigger.Request())
    info = json.loads(response.message)
    assert info['joints'] == [] and info['robot'] == 'baseLink'


def test_node_loads_a_package_uri(ros, fake_package):
    """urdf:=package://fake_robots/urdf/robot.urdf loads and drives."""
    sim = make_sim(ros, urdf='package://fake_robots/urdf/robot.urdf')
    assert sim.simulation.robot.source == str(fake_package)
    assert sim.has_wheels


def test_robot_description_overrides_urdf_and_is_published(ros):
    """URDF text in robot_description is loaded, published, and its temp file removed."""
    with open(default_urdf_path(), encoding='utf-8') as handle:
        text = handle.read().replace('<robot name="', '<robot name="from_text_')
    sim = make_sim(ros, urdf='cube.urdf', robot_description=text)
    probe = Probe(ros, sim)
    probe.wait_count('robot_description', 1)
    assert probe.messages['robot_description'][0].data == text
    assert sim.has_wheels and len(sim.simulation.robot.body.joints) == 15
    temp_path = sim.simulation.robot.body.source
    assert os.path.isfile(temp_path)
    sim.destroy_node()
    ros.nodes.remove(sim)
    assert not os.path.exists(temp_path)
    assert not os.path.exists(os.path.dirname(temp_path))


@pytest.mark.parametrize('params, fragment', [
    ({'robot_description': '<robot name="x"><link name="a"></robot'}, 'not well-formed XML'),
    ({'robot_description': '<sdf version="1.6"/>'}, 'not <robot>'),
    ({'robot_description': '<robot name="x"><joint name="j" type="fixed"/></robot>'},
     'cannot load'),
    ({'urdf': 'package://no_such_package/robot.urdf'}, 'no_such_package'),
    ({'base_forward_axis': 'z'}, 'base_forward_axis'),
    ({'base_forward_axis': True}, 'quote the value'),
    ({'wheel_velocity_sign': 2}, 'wheel_velocity_sign'),
])
def test_bad_descriptions_refuse_to_start(ros, params, fragment):
    """Malformed or unloadable descriptions are one-line start-up errors."""
    with pytest.raises(StartupError, match=fragment) as info:
        make_sim(ros, **params)
    assert '\n' not in str(info.value)


def test_unreadable_file_is_a_world_error(tmp_path):
    """A file that is not text gives 'cannot read' naming it."""
    bad = tmp_path / 'binary.urdf'
    bad.write_bytes(b'\xff\xfe\x00robot')
    with pytest.raises(WorldError, match='cannot read .*binary.urdf'):
        Simulation(parse_config({'urdf': str(bad)}))


def test_classic_drives_like_ours(ros):
    """Classic with its params file: +x at 0.3 m/s, CCW for angular.z > 0, odom agrees."""
    sim = make_sim(ros, **classic_params())
    probe = Probe(ros, sim)
    probe.drive(0.3, 0.0, 1.0)
    x0, y0, yaw0 = latest_truth(sim)
    probe.drive(0.3, 0.0, 1.5)
    x1, y1, yaw1 = latest_truth(sim)
    assert (x1 - x0) / 1.5 == pytest.approx(0.3, rel=0.05)  # forward is +x (REP-103)
    assert abs(y1 - y0) < 0.02 and abs(yaw1 - yaw0) < math.radians(2)
    probe.wait_count('ground_truth', 10)
    assert probe.messages['ground_truth'][-1].twist.twist.linear.x == pytest.approx(0.3, rel=0.05)
    odom = sim.simulation.robot.controller.odometry
    assert math.hypot(odom.x_m - x1, odom.y_m - y1) < 0.05 * odom.distance_m
    assert abs(math.remainder(odom.yaw_rad - yaw1, 2 * math.pi)) < math.radians(3)

    probe.drive(0.0, 0.5, 0.5)
    _, _, yaw2 = latest_truth(sim)
    probe.drive(0.0, 0.5, 2.0)
    _, _, yaw3 = latest_truth(sim)
    rate = math.remainder(yaw3 - yaw2, 2 * math.pi) / 2.0
    assert rate == pytest.approx(0.5, rel=0.10)  # counter-clockwise, calibrated
    assert abs(math.remainder(odom.yaw_rad - yaw3, 2 * math.pi)) < math.radians(8)


def test_classic_params_file_cross_process():
    """The real executable with --params-file urdf/classic_r2d2.yaml drives +x on cmd_vel."""
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry
    domain = next_domain_id()
    process = start_sim_process(domain, '--params-file', CLASSIC_YAML)
    probe = RemoteProbe(domain, 'classic_probe')
    try:
        truth = []
        probe.node.create_subscription(Odometry, 'ground_truth', truth.append, 10)
        pub = probe.node.create_publisher(Twist, 'cmd_vel', 10)
        spin_until = probe.spin_until
        assert spin_until(lambda: truth, 20.0), 'no ground_truth from sim_node'
        start = truth[-1].pose.pose.position
        assert drive_forward_until(spin_until, pub, truth, 0.15, 15.0), \
            'classic did not move forward'
        assert abs(truth[-1].pose.pose.position.y - start.y) < 0.05
    finally:
        code, out, err = stop_process(process)
        probe.close()
    assert code == 0, err
    assert 'Traceback' not in err + out


@pytest.mark.parametrize('value, fragment', [
    (['cube.urdf 0 0'], 'is not "description x y z"'),
    (['cube.urdf 0 zero 1'], 'is not "description x y z"'),
    (['cube.urdf 0 0 inf'], 'non-finite'),
    ('cube.urdf 0 0 1', 'list of strings'),
])
def test_bad_extra_models_are_one_line(value, fragment):
    """Each malformed extra_models entry is one ConfigError line quoting it."""
    from r2d2_sim.sim.parameters import ConfigError, parse_config
    with pytest.raises(ConfigError, match=fragment) as info:
        parse_config({'extra_models': value})
    assert '\n' not in str(info.value)


def test_unknown_extra_model_refuses_to_start(ros):
    """An extra model that resolves nowhere names itself."""
    with pytest.raises(StartupError, match='no_such_box.urdf'):
        make_sim(ros, extra_models=['no_such_box.urdf 1 0 0.5'])


def test_world_settings_reach_the_node(ros):
    """gravity, ground_plane and extra_models (names with spaces kept) configure the world."""
    sim = make_sim(ros, gravity=[0.0, 0.0, 0.0], ground_plane=False,
                   extra_models=['cube_small.urdf 0.6 0 1.0', 'cube.urdf -2 0 0.5'])
    world = sim.world
    models = sim.simulation.models
    assert 'ground_plane' not in world.bodies and len(models) == 2
    sim.advance(120)
    position = models[0].world_state().position
    assert position == pytest.approx((0.6, 0.0, 1.0), abs=1e-6)  # weightless: it floats


def test_extra_cube_falls_onto_the_plane():
    """A 5 cm cube dropped from 0.5 m comes to rest on the ground (centre at 2.5 cm)."""
    with SimWorld() as world:
        world.load_robot(default_urdf_path(), (0.0, 0.0, 0.0))
        cube = world.load('cube_small.urdf', (0.6, 0.0, 0.5)).id
        world.step(240)
        position = world.client.getBasePositionAndOrientation(cube)[0]
        assert position[2] == pytest.approx(0.025, abs=0.003)
        assert position[0] == pytest.approx(0.6, abs=0.01)
        world.reset()  # the saved state includes the extra models
        position = world.client.getBasePositionAndOrientation(cube)[0]
        assert position[2] == pytest.approx(0.5)


def test_driving_into_a_cube_collides(ros):
    """Driving at pybullet_data's 1 m, 1 kg cube: contact, and the cube is shoved along +x."""
    sim = make_sim(ros, extra_models=['cube.urdf 1.0 0 0.5'])
    probe = Probe(ros, sim)
    cube = sim.simulation.models[0].id
    client = sim.world.client
    probe.drive(0.3, 0.0, 2.0)
    touching = client.getContactPoints(sim.simulation.robot.body.id, cube)
    x0 = client.getBasePositionAndOrientation(cube)[0][0]
    probe.drive(0.3, 0.0, 2.0)
    x1 = client.getBasePositionAndOrientation(cube)[0][0]
    robot_x = latest_truth(sim)[0]
    assert touching
    assert x1 - x0 > 0.2
    assert robot_x < x1 - 0.5  # the robot stayed outside the cube


@pytest.mark.parametrize('args, fragment', [
    (['-p', 'robot_description:=<robot name="x"><link name="a"></robot'], 'not well-formed'),
    (['-p', 'urdf:=package://no_such_package/urdf/robot.urdf'], 'no_such_package'),
    (['-p', 'extra_models:=["cube.urdf 0 0"]'], 'extra_models'),
])
def test_bad_description_is_one_line_and_exit_2(args, fragment):
    """The executable refuses bad descriptions with one error line and exit code 2."""
    process = start_sim_process(next_domain_id(), *args)
    out, err = process.communicate(timeout=30.0)
    assert process.returncode == 2, err
    assert 'Traceback' not in err
    lines = [line for line in err.splitlines() if 'error' in line]
    assert len(lines) == 1 and fragment in lines[0], err


def test_robot_without_wheels_warns_once_at_start_up():
    """urdf:=cube.urdf runs, warns once that cmd_vel is ignored, and stops cleanly."""
    from nav_msgs.msg import Odometry
    domain = next_domain_id()
    process = start_sim_process(domain, '-p', 'urdf:=cube.urdf')
    probe = RemoteProbe(domain, 'cube_probe')
    try:
        truth = []
        probe.node.create_subscription(Odometry, 'ground_truth', truth.append, 10)
        assert probe.spin_until(lambda: len(truth) > 5, 20.0), 'no ground_truth from the cube'
    finally:
        code, out, err = stop_process(process)
        probe.close()
    assert code == 0, err
    assert (out + err).count('none of the default wheel joints') == 1, out + err
