"""
A URDF given as text that PyBullet refuses: the error names where the text came from.

No ROS. Text is written to a temporary file PyBullet can load, deleted when
the load fails: an error naming that file named one the user never wrote and
could no longer find. PyBullet's own lines about the text (its link names,
the user's) still show on stdout.
"""

import pytest

from r2d2_sim.errors import RefusedError, WorldError
from r2d2_sim.sim.simulation import SpawnRequest

SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'scan_rate': 0.0, 'imu_rate': 0.0}
# Well-formed, past the checks of a spawn, and refused by PyBullet: a <geometry> of no shape.
NO_SHAPE = ('<robot name="t"><link name="a"><inertial><mass value="1"/><inertia ixx="0.01" '
            'ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial><collision><geometry/>'
            '</collision></link></robot>')


def assert_named(message, where, capfd):
    assert message == f'PyBullet cannot load {where}: Cannot load URDF file.'
    assert 'Geometry tag contains no child element' in capfd.readouterr().out


def test_a_refused_spawn_of_text_names_the_resource_string(make, capfd):
    simulation = make()
    with pytest.raises(RefusedError) as refused:
        simulation.spawn(SpawnRequest('t', resource_string=NO_SHAPE, position=(1.0, 1.0, 0.5)))
    assert refused.value.code == 'RESOURCE_PARSE_ERROR'
    assert_named(refused.value.message, 'the resource_string', capfd)
    assert 't' not in simulation.world.bodies


def test_a_refused_robot_description_names_the_parameter(make, capfd):
    with pytest.raises(WorldError) as refused:
        make(robot_description=NO_SHAPE, left_wheel_names=[], right_wheel_names=[])
    assert_named(str(refused.value), 'the robot_description parameter', capfd)


def test_a_refused_world_of_urdf_text_names_the_resource_string(make, capfd):
    simulation = make()
    with pytest.raises(RefusedError) as refused:
        simulation.load_world('', NO_SHAPE)
    assert refused.value.code == 'RESOURCE_PARSE_ERROR'
    assert_named(refused.value.message, 'the resource_string', capfd)
