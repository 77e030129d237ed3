"""The extra_models parameter (ros/test_robots.py loads them), validated up front."""

import pytest


@pytest.mark.parametrize('value, fragment', [
    (['cube.urdf 0 0'], 'is not "description x y z"'),
    (['cube.urdf 0 zero 1'], 'is not "description x y z"'),
    (['cube.urdf 0 0 inf'], 'non-finite'),
    ('cube.urdf 0 0 1', 'list of strings'),
])
def test_bad_extra_models_are_one_line(value, fragment):
    """Each malformed extra_models entry is one ConfigError line quoting it."""
    from r2d2_sim.sim.settings.table import ConfigError
    from r2d2_sim.sim.settings.config import parse_config
    with pytest.raises(ConfigError, match=fragment) as info:
        parse_config({'extra_models': value})
    assert '\n' not in str(info.value)
