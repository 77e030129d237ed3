"""
Any robot description, without ROS: files, package:// URIs, pybullet_data names, the classic.

The classic (pybullet_data/r2d2.urdf) drives along its base +y: the world
reports its body in the REP-103 frame. The node's side is ros/test_robots.py.
"""

import math
import os

import pybullet_data
import pytest

from r2d2_sim.physics.description import (
    default_urdf_path, DescriptionError, resolve_description_path)
from r2d2_sim.physics.world import SimWorld, WorldError
from r2d2_sim.sim.settings.config import parse_config
from r2d2_sim.sim.simulation import Simulation


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


def test_unreadable_file_is_a_world_error(tmp_path):
    """A file that is not text gives 'cannot read' naming it."""
    bad = tmp_path / 'binary.urdf'
    bad.write_bytes(b'\xff\xfe\x00robot')
    with pytest.raises(WorldError, match='cannot read .*binary.urdf'):
        Simulation(parse_config({'urdf': str(bad)}))


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
