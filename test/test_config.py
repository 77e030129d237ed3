"""Parameter validation without ROS: every bad value is one readable ConfigError."""

import math

import pytest

from r2d2_sim.config import ConfigError, PARAMETERS, parse_config


def test_defaults_are_valid():
    """The declared defaults parse; publish_rate 0 means every physics step."""
    config = parse_config({})
    assert config.physics_rate_hz == 240.0
    assert config.publish_rate_hz == 240.0
    assert config.cmd_vel_timeout_s == 0.5
    assert config.real_time_factor == 1.0
    assert config.wheel_names_are_default


def test_every_parameter_has_a_description():
    """Each declared parameter says what it is for."""
    for spec in PARAMETERS:
        assert len(spec.description) > 10, spec.name


@pytest.mark.parametrize('name, value, fragment', [
    ('physics_rate', 0.0, '> 0'),
    ('physics_rate', -240.0, '> 0'),
    ('physics_rate', math.nan, 'finite'),
    ('physics_rate', 'fast', 'number'),
    ('publish_rate', -1.0, '>= 0'),
    ('publish_rate', 480.0, 'cannot exceed'),
    ('real_time_factor', -1.0, '>= 0'),
    ('real_time_factor', math.inf, 'finite'),
    ('cmd_vel_timeout', -0.1, '>= 0'),
    ('wheel_separation_multiplier', 0.0, '> 0'),
    ('wheel_lateral_friction_ratio', 1.5, '(0, 1]'),
    ('gui', 'yes', 'true or false'),
    ('initial_pose', [1.0], '3 numbers'),
    ('left_wheel_names', 'left_front_wheel_joint', 'list of joint names'),
    ('left_wheel_names', ['a', 'a'], 'twice'),
    ('right_wheel_names', ['left_front_wheel_joint'], 'both left and right'),
    ('right_wheel_names', [], 'both be empty'),
    ('pose_covariance_diagonal', [-1.0] * 6, 'negative'),
    ('odom_frame_id', '', 'empty'),
    ('no_such_parameter', 1, 'unknown'),
    ('left_wheel_names', 5, 'list of joint names'),
    ('extra_models', 3, 'list of strings'),
    ('physics_rate', None, 'number'),
    ('right_wheel_names', None, 'both be empty'),
    ('gravity', None, '3 numbers'),
])
def test_bad_values_raise_one_line(name, value, fragment):
    """Each invalid value raises ConfigError naming the parameter or the problem."""
    with pytest.raises(ConfigError) as info:
        parse_config({name: value})
    message = str(info.value)
    assert fragment in message
    assert '\n' not in message


def test_integers_are_accepted_as_numbers():
    """240 given as an integer is the same as 240.0."""
    assert parse_config({'physics_rate': 120, 'publish_rate': 60}).publish_rate_hz == 60.0


def test_booleans_are_not_numbers():
    """Refuse a boolean where a rate is expected."""
    with pytest.raises(ConfigError):
        parse_config({'physics_rate': True})


def test_empty_lists_from_the_command_line_mean_empty():
    """ROS hands ``-p names:=[]`` over as None (no type); list parameters read it as []."""
    config = parse_config({'left_wheel_names': None, 'right_wheel_names': None,
                           'extra_models': None})
    assert config.left_wheel_names == () and config.extra_models == ()


@pytest.mark.parametrize('spec', PARAMETERS, ids=lambda spec: spec.name)
def test_any_value_of_any_type_is_accepted_or_one_config_error(spec):
    """No value of a wrong type gets past validation as a crash: ConfigError or a config."""
    for value in (None, True, 0, -1, 0.0, -1.0, math.nan, math.inf, 1e308, '', 'x',
                  [], [''], ['x'], [1.0], [True], [math.nan] * 3, [1.0] * 6, [1, 2, 3]):
        try:
            parse_config({spec.name: value})
        except ConfigError as exc:
            assert '\n' not in str(exc) and spec.name.split('_')[0] in str(exc), exc
