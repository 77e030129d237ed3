"""
Any robot description in the node: package:// URIs, XML text, extra models, the classic R2D2.

The classic (pybullet_data/r2d2.urdf) drives along its base +y with negative
wheel velocities; with urdf/classic_r2d2.yaml it must answer cmd_vel exactly
like the package's own REP-103 robot. How descriptions are found and loaded
without ROS is in physics/test_robots_physics.py; the executable's refusals in
system/test_robots_system.py.
"""

import json
import math
import os

from helpers import latest_truth, make_sim, Probe
import pytest
from std_srvs.srv import Trigger

from common import classic_params
from r2d2_sim.physics.description import default_urdf_path, resolve_description_path
from r2d2_sim.ros.joint_info import joint_info
from r2d2_sim.ros.node import StartupError
from r2d2_sim.physics.world import SimWorld


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
