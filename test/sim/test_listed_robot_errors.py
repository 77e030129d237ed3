"""A listed robot that cannot be built is named in the one line that refuses it."""

import pytest

from r2d2_sim.sim.settings.table import ConfigError


def test_a_sensor_a_listed_robot_cannot_carry_names_the_robot(make):
    """Built fine by parse_world, refused while building robot b: the line says which robot."""
    with pytest.raises(ConfigError) as raised:
        make(robots=['a', 'b'], **{'b.initial_pose': [3.0, 0.0, 0.0], 'b.urdf': 'cube.urdf',
                                   'b.camera_rate': 10.0})
    assert str(raised.value).startswith("robot b: camera_rate > 0 needs a link named 'head'")
    with pytest.raises(ConfigError) as raised:  # the one robot of a world is not named
        make(urdf='cube.urdf', camera_rate=10.0)
    assert str(raised.value).startswith("camera_rate > 0 needs a link named 'head'")
