"""Parameter validation without ROS: every bad value is one readable ConfigError."""

import math

import pytest

from r2d2_sim.parameters import ConfigError, PARAMETERS, parse_config


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
    ('wheel_radius', 1e308, 'must be in [0.001, 10] m (derive it from the URDF with 0)'),
    ('wheel_radius', 1e-9, 'must be in [0.001, 10] m'),
    ('wheel_separation', 1e308, 'must be in [0.001, 100] m'),
    ('max_wheel_force', 1e308, 'must be in [0.001, 100000] N m'),
    ('max_wheel_velocity', 1e-6, 'must be in [0.001, 10000] rad/s'),
    ('max_linear_velocity', 1e308, 'must be in [0.001, 50] m/s'),
    ('max_angular_acceleration', 1e9, 'must be in [0.001, 1000] rad/s^2'),
    ('real_time_factor', 1e308, 'must be in [0, 1000]'),
    ('wheel_separation_multiplier', 1e-3, 'must be in [0.1, 10]'),
    ('publish_rate', 1e-7, 'must be in [0.001, 10000] Hz (every step with 0)'),
    ('camera_rate', 1e-7, 'must be in [0.001, 10000] Hz (off with 0)'),
    ('scan_rate', 1e-7, 'scan_rate must be in'),
    ('imu_rate', 1e-7, 'imu_rate must be in'),
    ('scan_samples', 1, 'scan_samples must be in [2, 10000]'),
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


@pytest.mark.parametrize('name', ['wheel_radius', 'wheel_separation', 'max_wheel_force',
                                  'max_wheel_velocity', 'max_linear_velocity'])
def test_zero_keeps_its_meaning_outside_the_bounds(name):
    """0 still means "derive it" or "no limit", although it is below each range."""
    parse_config({name: 0.0})


def test_every_bounded_default_is_inside_its_bounds():
    """The table's own defaults satisfy its bounds (or are the documented 0)."""
    for spec in PARAMETERS:
        if spec.bounds is not None:
            for value in spec.default if isinstance(spec.default, list) else [spec.default]:
                assert value == 0.0 and spec.bounds.zero or \
                    spec.bounds.low <= value <= spec.bounds.high, spec.name


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
