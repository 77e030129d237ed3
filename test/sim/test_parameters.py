"""Parameter validation without ROS: every bad value is one readable ConfigError."""

import math
import re

import pytest

from r2d2_sim.sim.settings.readers import bound_text
from r2d2_sim.sim.settings.table import ConfigError, PARAMETERS, PARAMETERS_BY_NAME
from r2d2_sim.sim.settings.config import parse_config


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
    ('physics_rate', 0.0, 'must be in [10, 10000] Hz, got 0'),
    ('physics_rate', -240.0, 'must be in [10, 10000] Hz, got -240'),
    ('physics_rate', math.nan, 'finite'),
    ('physics_rate', 'fast', 'number'),
    ('publish_rate', -1.0, 'must be in [0.001, 10000] Hz (every step with 0), got -1'),
    ('publish_rate', 480.0, 'cannot exceed'),
    ('real_time_factor', -1.0, 'must be in [1e-06, 1000] (as fast as possible with 0), got -1'),
    ('real_time_factor', 1e-13, 'must be in [1e-06, 1000]'),  # the pacer could not sleep
    ('real_time_factor', math.inf, 'finite'),
    ('cmd_vel_timeout', -0.1, '>= 0'),
    ('wheel_separation_multiplier', 0.0, 'must be in [0.1, 10], got 0'),
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
    ('real_time_factor', 1e308, 'must be in [1e-06, 1000]'),
    ('wheel_separation_multiplier', 1e-3, 'must be in [0.1, 10]'),
    ('publish_rate', 1e-7, 'must be in [0.001, 10000] Hz (every step with 0)'),
    ('camera_rate', 1e-7, 'must be in [0.001, 10000] Hz (off with 0)'),
    ('scan_rate', 1e-7, 'scan_rate must be in'),
    ('imu_rate', 1e-7, 'imu_rate must be in'),
    ('scan_samples', 1, 'scan_samples must be in [2, 10000]'),
    ('model_paths', ['models', ''], 'model_paths must be a list of directories'),
    ('model_paths', 'models', 'model_paths must be a list of directories'),
    ('strict_worlds', 'yes', 'strict_worlds'),
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


def test_every_printed_bound_is_accepted():
    """
    A range printed (the docs, --help, an error) holds numbers its parameter accepts.

    Bounds print with 6 digits: pi / 2 printed as 1.5708 named a range that
    refused it ("must be in [-1.5708, 1.5708] rad, got -1.5708"). Each bound
    is now rounded toward the inside.
    """
    from r2d2_sim.sim.settings.reference import render_parameter_reference
    checked = 0
    for spec in PARAMETERS:
        if spec.bounds is None or spec.ros_type.startswith('integer'):
            continue
        low, high = (float(text) for text in spec.bounds.text()[1:-1].split(', '))
        for value in (low, high):
            assert spec.bounds.check(spec.name, value) == value, spec.name
        assert spec.bounds.text() in render_parameter_reference([spec])
        checked += 1
    assert checked > 50
    with pytest.raises(ConfigError, match=re.escape(
            'parameter lidar3d_angle_min must be in [-1.57079, 1.57079] rad, got -1.5708')):
        parse_config({'lidar3d_angle_min': -1.5708})
    assert parse_config({'lidar3d_angle_min': -1.57079}).lidar3d_angle_min_rad == -1.57079


@pytest.mark.parametrize('value, upward, text', [
    (math.pi / 2, False, '1.57079'), (-math.pi / 2, True, '-1.57079'),
    (2 * math.pi, False, '6.28318'), (math.pi, False, '3.14159'), (-math.pi, True, '-3.14159'),
    (10000.0, False, '10000'), (0.001, True, '0.001'), (1e-6, True, '1e-06'),
    (1.0e7 + 1.0, False, '1e+07'), (1.0e7 - 1.0, True, '1e+07'),
])
def test_a_bound_is_rounded_toward_the_inside_of_its_range(value, upward, text):
    assert bound_text(value, upward) == text
    assert (float(text) >= value) if upward else (float(text) <= value)


def test_a_physics_rate_below_the_imu_rate_says_how_to_run():
    """physics_rate 50 (documented range [10, 10000]) meets the IMU's default 100 Hz."""
    with pytest.raises(ConfigError, match=re.escape(
            'parameter imu_rate (100.0 Hz, its default) cannot exceed physics_rate (50.0 Hz): '
            'set imu_rate to 50 Hz or less (0: off)')):
        parse_config({'physics_rate': 50.0})
    assert 'imu_rate' in PARAMETERS_BY_NAME['physics_rate'].description
    for imu_rate in (50.0, 0.0):
        assert parse_config({'physics_rate': 50.0, 'imu_rate': imu_rate}).physics_rate_hz == 50.0
    with pytest.raises(ConfigError, match=re.escape(
            'parameter publish_rate (100.0 Hz) cannot exceed physics_rate (50.0 Hz): set '
            'publish_rate to 50 Hz or less (0: every step)')):
        parse_config({'physics_rate': 50.0, 'imu_rate': 0.0, 'publish_rate': 100.0})


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


# -- frames: what would break the TF tree is refused at start-up ----------------

@pytest.mark.parametrize('values, fragments', [
    ({'odom_frame_id': 'base_link'},
     ['parameters odom_frame_id and base_frame_id', "'base_link'"]),  # a cycle
    ({'footprint_frame_id': 'base_link'},
     ['parameters footprint_frame_id and base_frame_id', "'base_link'"]),  # base -> base
    ({'odom_frame_id': 'base_footprint'},
     ['parameters odom_frame_id and footprint_frame_id', "'base_footprint'"]),
    ({'world_frame_id': 'odom', 'publish_ground_truth_tf': True},
     ['parameters world_frame_id and odom_frame_id', "'odom'"]),  # odom -> odom
    ({'world_frame_id': 'base_link'}, ['parameters world_frame_id and base_frame_id']),
    ({'world_frame_id': 'base_footprint'},
     ['parameters world_frame_id and footprint_frame_id']),
    ({'frame_prefix': 'robot1/', 'world_frame_id': 'robot1/odom'},
     ["world_frame_id and odom_frame_id (with frame_prefix 'robot1/')", "'robot1/odom'"]),
    ({'frame_prefix': 'r', 'odom_frame_id': 'x', 'footprint_frame_id': 'x'}, ["'rx'"]),
    ({'base_frame_id': 'base_scan'}, ["base_frame_id names the laser's frame 'base_scan'",
                                      'scan_rate > 0']),
    ({'odom_frame_id': 'imu_link'}, ["odom_frame_id names the IMU's frame 'imu_link'"]),
    ({'footprint_frame_id': 'head_camera_optical', 'camera_rate': 10.0},
     ['footprint_frame_id names a head camera frame', 'camera_rate > 0']),
    ({'odom_frame_id': 'head', 'camera_rate': 10.0}, ["head camera frame 'head'"]),
    ({'world_frame_id': 'base_scan'}, ["world_frame_id names the laser's frame"]),
    ({'frame_prefix': 'r/', 'world_frame_id': 'r/imu_link'}, ["IMU's frame 'r/imu_link'"]),
])
def test_frames_that_collide_are_refused(values, fragments):
    """Two roles given one frame (after frame_prefix) would make a cycle or a self transform."""
    with pytest.raises(ConfigError) as info:
        parse_config(values)
    message = str(info.value)
    assert '\n' not in message and 'TF needs a distinct frame for each' in message
    for fragment in fragments:
        assert fragment in message


@pytest.mark.parametrize('values', [
    {'frame_prefix': 'robot1/', 'world_frame_id': 'odom'},  # robot1/odom is not odom
    {'frame_prefix': 'robot1/', 'world_frame_id': 'robot1/map'},
    {'base_frame_id': 'base_scan', 'scan_rate': 0.0},  # no laser, no laser frame
    {'odom_frame_id': 'head'},  # no camera: head is only a URDF link
    {'odom_frame_id': 'robot_1/odom.2-b', 'world_frame_id': 'map'},
    {'frame_prefix': 'fleet/robot1/'},
    {'frame_prefix': 'robot1_'},
])
def test_distinct_frames_are_accepted(values):
    """Frames that stay distinct, and tf2-valid names, pass."""
    parse_config(values)


@pytest.mark.parametrize('name, value, fragment', [
    ('odom_frame_id', '/odom', "must not start with '/' (tf2 refuses such frame ids)"),
    ('base_frame_id', '/base_link', "use 'base_link'"),
    ('world_frame_id', '/world', "must not start with '/'"),
    ('footprint_frame_id', '/base_footprint', "must not start with '/'"),
    ('frame_prefix', '/robot1/', "use 'robot1/'"),
    ('frame_prefix', '/', "must not start with '/'"),
    ('odom_frame_id', 'my odom', 'no spaces'),
    ('odom_frame_id', ' odom', 'no spaces'),
    ('base_frame_id', 'base_link\t', 'a tf2 frame id'),
    ('world_frame_id', 'world/', 'single / between names'),
    ('world_frame_id', 'a//b', 'single / between names'),
    ('odom_frame_id', 'odom:1', 'a tf2 frame id'),
    ('base_frame_id', 'base"link', 'a tf2 frame id'),
    ('frame_prefix', 'robot 1/', 'frame id prefix'),
    ('frame_prefix', 'robot1//', 'frame id prefix'),
    ('odom_frame_id', '   ', 'must not be empty'),
])
def test_frame_ids_tf2_refuses_are_refused(name, value, fragment):
    """A leading '/', whitespace and other characters are one line naming the parameter."""
    with pytest.raises(ConfigError) as info:
        parse_config({name: value})
    message = str(info.value)
    assert '\n' not in message and message.startswith(f'parameter {name} ')
    assert fragment in message and repr(value) in message


def test_sensor_frame_names_match_what_the_robot_publishes():
    """The frames checked here are the ones r2d2_sim.sim.robots.sensors puts on the sensors."""
    from r2d2_sim.sim.settings import table as parameters
    from r2d2_sim.sim.robots import sensors as sensor_mounts  # needs PyBullet, not ROS
    for name in ('LASER_FRAME_ID', 'IMU_FRAME_ID', 'HEAD_CAMERA_FRAME_ID', 'HEAD_CAMERA_LINK'):
        assert getattr(parameters, name) == getattr(sensor_mounts, name), name


def test_robots_get_the_world_settings_with_their_own_on_top():
    """NAME.parameter overrides one robot's; the frames of each get NAME/ (shared TF)."""
    from r2d2_sim.sim.settings.robots import parse_world
    config, robots = parse_world({
        'robots': ['a', 'b'], 'max_linear_velocity': 0.5, 'scan_rate': 5.0,
        'b.initial_pose': [2, 0, 3], 'b.max_linear_velocity': 0.2, 'b.namespace': '/fleet/b'})
    assert config.robots == ('a', 'b')
    a, b = robots
    assert (a.name, a.namespace, b.name, b.namespace) == ('a', 'a', 'b', '/fleet/b')
    assert a.config.max_linear_velocity_m_s == 0.5 and b.config.max_linear_velocity_m_s == 0.2
    assert a.config.initial_pose == (0.0, 0.0, 0.0) and b.config.initial_pose == (2.0, 0.0, 3.0)
    assert a.config.scan_rate_hz == b.config.scan_rate_hz == 5.0
    assert (a.config.frame_prefix, b.config.frame_prefix) == ('a/', 'b/')


def test_namespaced_tf_leaves_frames_unprefixed_and_a_robot_may_set_its_prefix():
    """tf_layout namespaced: frames as the world's prefix has them; NAME.frame_prefix wins."""
    from r2d2_sim.sim.settings.robots import parse_world
    _, robots = parse_world({'robots': ['a', 'b'], 'tf_layout': 'namespaced',
                             'b.frame_prefix': 'bee/'})
    assert [r.config.frame_prefix for r in robots] == ['', 'bee/']
    _, robots = parse_world({'robots': ['a'], 'frame_prefix': 'fleet/'})
    assert robots[0].config.frame_prefix == 'fleet/a/'


@pytest.mark.parametrize('values, fragment', [
    ({'robots': ['a'], 'a.physics_rate': 100.0}, "a.physics_rate: physics_rate is the world's"),
    ({'robots': ['a'], 'a.no_such': 1}, 'unknown parameter a.no_such'),
    ({'robots': ['a'], 'b.urdf': 'x'}, "robot 'b' that robots does not list"),
    ({'robots': ['a'], 'a.max_linear_velocity': -1.0}, 'parameter a.max_linear_velocity'),
    ({'robots': ['a'], 'a.scan_range_min': 20.0}, 'robot a: parameter scan_range_min'),
    ({'robots': ['a'], 'a.namespace': 'a//b'}, 'a.namespace must be a ROS namespace'),
    ({'robots': ['a-1']}, 'not a robot name'),
    ({'robots': ['a', 'a']}, 'lists a robot twice'),
    ({'robots': 'a'}, 'list of robot names'),
    ({'tf_layout': 'mixed'}, 'one of shared, namespaced'),
])
def test_bad_robot_parameters_are_one_line_naming_them(values, fragment):
    """Each mistake names the robot's parameter as the user wrote it."""
    from r2d2_sim.sim.settings.robots import parse_world
    with pytest.raises(ConfigError) as raised:
        parse_world(values)
    assert fragment in str(raised.value) and '\n' not in str(raised.value)


def test_the_config_fields_are_the_table_rendered():
    """The generated field block of SimConfig is today's table: its fields, in order, typed."""
    import dataclasses
    from r2d2_sim.sim.settings import config
    assert config.main([]) == 0, ('SimConfig is stale: '
                                  'python -m r2d2_sim.sim.settings.config --write')
    fields = dataclasses.fields(config.SimConfig)
    assert [f.name for f in fields] == [p.field for p in PARAMETERS]
    types = {'double': float, 'integer': int, 'bool': bool, 'string': str}
    for spec, field in zip(PARAMETERS, fields):
        if spec.ros_type in types and not spec.python_type:
            assert field.type == types[spec.ros_type], spec.name


def test_a_table_that_changed_makes_the_config_check_fail(monkeypatch, capsys):
    """A parameter added to the table (and not to SimConfig) fails the check, in one line."""
    from r2d2_sim.sim.settings import config
    extra = PARAMETERS[0]._replace(name='brand_new', field='brand_new_m')
    monkeypatch.setattr(config, 'PARAMETERS', PARAMETERS + [extra])
    assert 'brand_new_m: str' in config.render_fields()
    assert config.main([]) == 1
    assert capsys.readouterr().err.count('\n') == 1


@pytest.mark.parametrize('values, fragment', [
    ({'lidar3d_rate': 1.0, 'lidar3d_rings': 256, 'lidar3d_samples': 10000},
     '2,560,000 rays a scan, more than 131,072'),  # 12 s a scan
    ({'lidar3d_rate': 20.0, 'lidar3d_rings': 64, 'lidar3d_samples': 2048},
     '2,625,040 rays a simulated second'),  # with the default laser's 3,600
    ({'scan_rate': 240.0, 'scan_samples': 10000}, '2,400,000 rays a simulated second'),
    ({'camera_rate': 1.0, 'camera_width': 4096, 'camera_height': 4096},
     '16,777,216 pixels an image'),  # 1 % of real time
    ({'camera_rate': 30.0, 'camera_width': 1920, 'camera_height': 1080},
     '62,208,000 pixels a simulated second'),
], ids=['lidar scan', 'lidar rate', 'laser rate', 'camera image', 'camera rate'])
def test_sensors_that_would_stall_the_node_are_refused_by_their_cost(values, fragment):
    """A 256 x 10,000 lidar cost 12 s a scan, a 4096^2 camera ran at 1 % of real time."""
    with pytest.raises(ConfigError) as info:
        parse_config(values)
    assert fragment in str(info.value) and '\n' not in str(info.value)


@pytest.mark.parametrize('values', [
    {'lidar3d_rate': 10.0},  # 16 x 1800, sensors.md's
    {'lidar3d_rate': 10.0, 'lidar3d_rings': 64, 'lidar3d_samples': 2048},
    {'scan_rate': 240.0},  # 360 beams each physics step
    {'scan_rate': 60.0, 'scan_samples': 10000, 'lidar3d_rate': 10.0},
    {'camera_rate': 100.0},  # node.md's camera table: 320 x 240 up to 100 Hz
    {'camera_rate': 15.0, 'camera_width': 1920, 'camera_height': 1080},
    {'camera_rate': 30.0, 'camera_width': 1280, 'camera_height': 720},
    {'camera_rate': 0.0, 'camera_width': 4096, 'camera_height': 4096},  # off: costs nothing
], ids=['lidar default', 'lidar 64x2048', 'laser each step', 'laser and lidar',
        'camera 100 Hz', 'camera 1080p', 'camera 720p', 'camera off'])
def test_sensors_the_docs_and_tests_use_are_accepted(values):
    parse_config(values)
