"""The head camera's parameters, validated up front."""

import re

import pytest

from r2d2_sim.sim.settings.table import ConfigError
from r2d2_sim.sim.settings.config import parse_config


@pytest.mark.parametrize('name, value, fragment', [
    ('camera_rate', 480.0, 'cannot exceed'),
    ('camera_rate', -1.0, 'must be in [0.001, 10000] Hz (off with 0), got -1'),
    ('camera_width', 0, 'camera_width'),
    ('camera_height', 1.5, 'integer'),
    ('camera_fov', 180.0, 'below 180'),
])
def test_bad_camera_parameters(name, value, fragment):
    """Camera parameters are validated up front, one line each."""
    with pytest.raises(ConfigError, match=re.escape(fragment)):
        parse_config({name: value})
