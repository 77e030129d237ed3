"""
The simulator's settings as one declared, frozen dataclass (:class:`SimConfig`), and reading them.

No ROS. The fields are the parameter table's (:data:`~r2d2_sim.sim.settings.table.PARAMETERS`),
one per parameter in its order, in SI units: the block between the two
``generated`` lines below is written from the table by
``python -m r2d2_sim.sim.settings.config --write`` and a test fails when the
two differ (as ``docs/parameters.md`` is checked), so an editor and the type
checker see every field. :func:`parse_config` reads raw values into one,
checking each value (its reader, its bounds) and what no single value shows
(:func:`check_fields`): one :class:`ConfigError` line for the first problem.
"""

from dataclasses import dataclass
import math
import sys
from typing import Any, Dict, Mapping, Optional, Tuple

from r2d2_sim.model.noise import NoiseSpec
from r2d2_sim.sim.settings.readers import ConfigError
from r2d2_sim.sim.settings.table import (
    FORWARD_AXIS_YAW_RAD, HEAD_CAMERA_FRAME_ID, HEAD_CAMERA_LINK, IMU_FRAME_ID, LASER_FRAME_ID,
    LIDAR3D_FRAME_ID, MAX_CAMERA_PIXELS, MAX_CAMERA_PIXELS_PER_SECOND, MAX_LIDAR3D_RAYS_PER_SCAN,
    MAX_RAYS_PER_SECOND, NOISE_FAMILIES, NOISE_PARTS, Parameter, PARAMETERS, PARAMETERS_BY_NAME)

__all__ = ['SimConfig', 'parse_config', 'read_value', 'check_fields', 'render_fields',
           'ConfigError']

# Python types of the SimConfig fields, by ROS type.
FIELD_TYPES = {'double': 'float', 'integer': 'int', 'bool': 'bool', 'string': 'str',
               'double_array': 'Tuple[float, ...]', 'string_array': 'Tuple[str, ...]'}
BEGIN = '    # -- generated from PARAMETERS: python -m r2d2_sim.sim.settings.config --write --\n'
END = '    # -- end of the generated fields --\n'


def render_fields() -> str:
    """Return the SimConfig field block as the table gives it (between BEGIN and END)."""
    lines = []
    for spec in PARAMETERS:
        line = f'    {spec.field}: {spec.python_type or FIELD_TYPES[spec.ros_type]}'
        if spec.field != spec.name:
            line = f'{line:<60}# {spec.name}'
        lines.append(line.rstrip() + '\n')
    return BEGIN + ''.join(lines) + END


@dataclass(frozen=True)
class SimConfig:
    """Validated simulator settings in SI units, one field per parameter (docs/parameters.md)."""

    # -- generated from PARAMETERS: python -m r2d2_sim.sim.settings.config --write --
    urdf: str
    robot_description: str
    base_forward_axis: str
    wheel_velocity_sign: int
    gravity_m_s2: Tuple[float, float, float]                # gravity
    ground_plane: bool
    extra_models: Tuple[Tuple[str, Tuple[float, float, float]], ...]
    gui: bool
    physics_rate_hz: float                                  # physics_rate
    real_time_factor: float
    publish_rate_hz: float                                  # publish_rate
    ray_threads: int
    outputs_process: bool
    cmd_vel_timeout_s: float                                # cmd_vel_timeout
    start_paused: bool
    wheel_radius_m: float                                   # wheel_radius
    wheel_separation_m: float                               # wheel_separation
    wheel_separation_multiplier: float
    wheel_lateral_friction_ratio: float
    left_wheel_names: Tuple[str, ...]
    right_wheel_names: Tuple[str, ...]
    max_wheel_velocity_rad_s: float                         # max_wheel_velocity
    max_wheel_force_n_m: float                              # max_wheel_force
    max_linear_velocity_m_s: float                          # max_linear_velocity
    max_angular_velocity_rad_s: float                       # max_angular_velocity
    max_linear_acceleration_m_s2: float                     # max_linear_acceleration
    max_angular_acceleration_rad_s2: float                  # max_angular_acceleration
    odom_frame_id: str
    base_frame_id: str
    world_frame_id: str
    initial_pose: Tuple[float, float, float]
    tags: Tuple[str, ...]
    pose_covariance_diagonal: Tuple[float, ...]
    twist_covariance_diagonal: Tuple[float, ...]
    camera_rate_hz: float                                   # camera_rate
    camera_width_px: int                                    # camera_width
    camera_height_px: int                                   # camera_height
    camera_fov_deg: float                                   # camera_fov
    camera_depth: bool
    camera_point_cloud: bool
    camera_self_filter: bool
    depth_noise_mean: float
    depth_noise_std: float
    depth_noise_bias_mean: float
    depth_noise_bias_std: float
    depth_noise_dynamic_bias_std: float
    depth_noise_dynamic_bias_correlation_time: float
    depth_noise_precision: float
    world: str
    world_paths: Tuple[str, ...]
    model_paths: Tuple[str, ...]
    strict_worlds: bool
    publish_tf: bool
    publish_link_tf: bool
    publish_ground_truth_tf: bool
    publish_contacts: bool
    footprint_frame_id: str
    frame_prefix: str
    scan_rate_hz: float                                     # scan_rate
    scan_samples: int
    scan_angle_min_rad: float                               # scan_angle_min
    scan_angle_max_rad: float                               # scan_angle_max
    scan_range_min_m: float                                 # scan_range_min
    scan_range_max_m: float                                 # scan_range_max
    scan_noise_mean: float
    scan_noise_std_m: float                                 # scan_noise_std
    scan_noise_bias_mean: float
    scan_noise_bias_std: float
    scan_noise_dynamic_bias_std: float
    scan_noise_dynamic_bias_correlation_time: float
    scan_noise_precision: float
    imu_rate_hz: float                                      # imu_rate
    lidar3d_rate_hz: float                                  # lidar3d_rate
    lidar3d_rings: int
    lidar3d_samples: int
    lidar3d_angle_min_rad: float                            # lidar3d_angle_min
    lidar3d_angle_max_rad: float                            # lidar3d_angle_max
    lidar3d_range_min_m: float                              # lidar3d_range_min
    lidar3d_range_max_m: float                              # lidar3d_range_max
    lidar3d_height_m: float                                 # lidar3d_height
    lidar3d_noise_mean: float
    lidar3d_noise_std: float
    lidar3d_noise_bias_mean: float
    lidar3d_noise_bias_std: float
    lidar3d_noise_dynamic_bias_std: float
    lidar3d_noise_dynamic_bias_correlation_time: float
    lidar3d_noise_precision: float
    imu_orientation_noise_mean: float
    imu_orientation_noise_std_rad: float                    # imu_orientation_noise_std
    imu_orientation_noise_bias_mean: float
    imu_orientation_noise_bias_std: float
    imu_orientation_noise_dynamic_bias_std: float
    imu_orientation_noise_dynamic_bias_correlation_time: float
    imu_orientation_noise_precision: float
    imu_angular_velocity_noise_mean: float
    imu_angular_velocity_noise_std_rad_s: float             # imu_angular_velocity_noise_std
    imu_angular_velocity_noise_bias_mean: float
    imu_angular_velocity_noise_bias_std: float
    imu_angular_velocity_noise_dynamic_bias_std: float
    imu_angular_velocity_noise_dynamic_bias_correlation_time: float
    imu_angular_velocity_noise_precision: float
    imu_linear_acceleration_noise_mean: float
    imu_linear_acceleration_noise_std_m_s2: float           # imu_linear_acceleration_noise_std
    imu_linear_acceleration_noise_bias_mean: float
    imu_linear_acceleration_noise_bias_std: float
    imu_linear_acceleration_noise_dynamic_bias_std: float
    imu_linear_acceleration_noise_dynamic_bias_correlation_time: float
    imu_linear_acceleration_noise_precision: float
    encoder_noise_mean: float
    encoder_noise_std: float
    encoder_noise_bias_mean: float
    encoder_noise_bias_std: float
    encoder_noise_dynamic_bias_std: float
    encoder_noise_dynamic_bias_correlation_time: float
    encoder_noise_precision: float
    noise_seed: int
    battery_rate_hz: float                                  # battery_rate
    battery_capacity_ah: float                              # battery_capacity
    battery_initial_charge: float
    battery_voltage_empty_v: float                          # battery_voltage_empty
    battery_voltage_full_v: float                           # battery_voltage_full
    battery_idle_current_a: float                           # battery_idle_current
    battery_current_per_effort_a_n_m: float                 # battery_current_per_effort
    battery_current_per_speed_a_rad_s: float                # battery_current_per_speed
    battery_charge_current_a: float                         # battery_charge_current
    battery_dock_pose: Tuple[float, ...]
    battery_dock: str
    battery_dock_tolerance: Tuple[float, ...]
    battery_empty_behaviour: str
    battery_empty_speed: float
    enable_stamped_cmd_vel: bool
    foxglove_port: int
    foxglove_host: str
    record: str
    robots: Tuple[str, ...]
    tf_layout: str
    # -- end of the generated fields --

    @property
    def body_yaw_offset_rad(self) -> float:
        """Return the yaw from the URDF base frame to the REP-103 body frame."""
        return FORWARD_AXIS_YAW_RAD[self.base_forward_axis]

    def frame(self, name: str) -> str:
        """Return a frame id of this robot with ``frame_prefix`` in front."""
        return self.frame_prefix + name

    @property
    def wheel_names_are_default(self) -> bool:
        """Return True when the wheel joint names were left at their defaults."""
        return (list(self.left_wheel_names) == PARAMETERS_BY_NAME['left_wheel_names'].default
                and list(self.right_wheel_names)
                == PARAMETERS_BY_NAME['right_wheel_names'].default)

    def noise(self, prefix: str) -> NoiseSpec:
        """Return the Gazebo noise of the sensor ``prefix`` names (``scan``, ``encoder``...)."""
        family = NOISE_FAMILIES[prefix]
        values = [getattr(self, family.field(part)) for part in NOISE_PARTS]
        return NoiseSpec(*values)


def read_value(spec: Parameter, value: Any, label: Optional[str] = None) -> Any:
    """Read one raw value; ``label`` names it in messages (default: the parameter's name)."""
    label = label or spec.name
    # ROS cannot tell the type of an empty list (-p names:=[]): it arrives as None.
    if value is None and spec.ros_type.endswith('_array'):
        value = []
    try:
        result = spec.read(label, value)
    except ConfigError:
        # A number the reader refuses for its sign (-5 for a rate): the range says more
        # ("must be in [10, 10000] Hz", not "must be > 0", then 5 refused in turn).
        if (spec.bounds is not None and isinstance(value, (int, float))
                and not isinstance(value, bool) and math.isfinite(value)):
            spec.bounds.check(label, float(value))
        raise
    if spec.bounds is not None:
        values = result if isinstance(result, tuple) else (result,)
        for v in values:
            if math.isfinite(v):  # inf is how read.limit says "none"
                spec.bounds.check(label, v)
    return result


def parse_config(values: Mapping[str, Any]) -> 'SimConfig':
    """Validate raw parameter values (defaults filled in) into a SimConfig."""
    unknown = set(values) - set(PARAMETERS_BY_NAME)
    if unknown:
        raise ConfigError(f'unknown parameter(s): {", ".join(sorted(unknown))}')
    fields = {}
    for spec in PARAMETERS:
        fields[spec.field] = read_value(spec, values.get(spec.name, spec.default))
    check_fields(fields)
    fields['publish_rate_hz'] = fields['publish_rate_hz'] or fields['physics_rate_hz']
    return SimConfig(**fields)


def check_fields(fields: Mapping[str, Any]) -> None:
    """Check what no single value shows: rates against physics, wheel lists, ranges, frames."""
    physics_rate = fields['physics_rate_hz']
    for name, field in (('publish_rate', 'publish_rate_hz'), ('camera_rate', 'camera_rate_hz'),
                        ('scan_rate', 'scan_rate_hz'), ('imu_rate', 'imu_rate_hz'),
                        ('lidar3d_rate', 'lidar3d_rate_hz'), ('battery_rate', 'battery_rate_hz')):
        if fields[field] > physics_rate:
            # imu_rate's default (100 Hz) is above physics_rate's lower bound: name the cure.
            spec = PARAMETERS_BY_NAME[name]
            default = ', its default' if fields[field] == spec.default else ''
            zero = spec.bounds.zero if spec.bounds is not None else None
            raise ConfigError(f'parameter {name} ({fields[field]} Hz{default}) cannot exceed '
                              f'physics_rate ({physics_rate} Hz): set {name} to '
                              f'{physics_rate:g} Hz or less' + (f' (0: {zero})' if zero else ''))
    left, right = fields['left_wheel_names'], fields['right_wheel_names']
    if bool(left) != bool(right):
        raise ConfigError('left_wheel_names and right_wheel_names must both list wheels '
                          'or both be empty')
    both = set(left) & set(right)
    if both:
        raise ConfigError(
            f'joint(s) {", ".join(sorted(both))} listed as both left and right wheels')
    if not fields['scan_angle_min_rad'] < fields['scan_angle_max_rad']:
        raise ConfigError('parameter scan_angle_min must be below scan_angle_max, got '
                          f'{fields["scan_angle_min_rad"]} >= {fields["scan_angle_max_rad"]}')
    for family in NOISE_FAMILIES.values():
        drift, time = family.name('dynamic_bias_std'), family.name('dynamic_bias_correlation_time')
        if fields[family.field('dynamic_bias_std')] > 0.0 and fields[family.field(
                'dynamic_bias_correlation_time')] == 0.0:
            raise ConfigError(f'parameter {drift} needs {time} > 0 (the drifting bias\'s '
                              'correlation time), got 0')
    if not fields['scan_range_min_m'] < fields['scan_range_max_m']:
        raise ConfigError('parameter scan_range_min must be below scan_range_max, got '
                          f'{fields["scan_range_min_m"]} >= {fields["scan_range_max_m"]}')
    if not fields['lidar3d_range_min_m'] < fields['lidar3d_range_max_m']:
        raise ConfigError('parameter lidar3d_range_min must be below lidar3d_range_max, got '
                          f'{fields["lidar3d_range_min_m"]} >= {fields["lidar3d_range_max_m"]}')
    if not fields['battery_voltage_empty_v'] < fields['battery_voltage_full_v']:
        raise ConfigError('parameter battery_voltage_empty must be below battery_voltage_full, '
                          f'got {fields["battery_voltage_empty_v"]} >= '
                          f'{fields["battery_voltage_full_v"]}')
    if fields['battery_dock'] and fields['battery_dock_pose']:
        raise ConfigError('parameters battery_dock and battery_dock_pose both give the dock: '
                          'set one')
    low, high = fields['lidar3d_angle_min_rad'], fields['lidar3d_angle_max_rad']
    if not (low < high or (low == high and fields['lidar3d_rings'] == 1)):
        raise ConfigError('parameter lidar3d_angle_min must be below lidar3d_angle_max (equal '
                          f'only with one ring), got {low} and {high}')
    _check_sensor_costs(fields)
    _check_frames(fields)


def _check_sensor_costs(fields: Mapping[str, Any]) -> None:
    """Refuse sensors whose rays or pixels would stall the node (see MAX_RAYS_PER_SECOND)."""
    lidar = fields['lidar3d_rings'] * fields['lidar3d_samples']
    lidar_rate, scan_rate = fields['lidar3d_rate_hz'], fields['scan_rate_hz']
    if lidar_rate > 0.0 and lidar > MAX_LIDAR3D_RAYS_PER_SCAN:
        raise ConfigError(f'parameters lidar3d_rings x lidar3d_samples: {lidar:,} rays a scan, '
                          f'more than {MAX_LIDAR3D_RAYS_PER_SCAN:,} (about 0.25 s each, with '
                          'nothing else answered meanwhile)')
    rays = lidar * lidar_rate + fields['scan_samples'] * scan_rate
    if rays > MAX_RAYS_PER_SECOND:
        raise ConfigError(f'parameters scan_samples x scan_rate + lidar3d_rings x '
                          f'lidar3d_samples x lidar3d_rate: {rays:,.0f} rays a simulated '
                          f'second, more than {MAX_RAYS_PER_SECOND:,} (about 2.5 s of '
                          'casting each): lower a rate or the beams')
    if fields['camera_rate_hz'] <= 0.0:
        return
    pixels = fields['camera_width_px'] * fields['camera_height_px']
    if pixels > MAX_CAMERA_PIXELS:
        raise ConfigError(f'parameters camera_width x camera_height: {pixels:,} pixels an '
                          f'image, more than {MAX_CAMERA_PIXELS:,} (1920 x 1080: about 0.3 s '
                          'each, with nothing else answered meanwhile)')
    if pixels * fields['camera_rate_hz'] > MAX_CAMERA_PIXELS_PER_SECOND:
        raise ConfigError(f'parameters camera_width x camera_height x camera_rate: '
                          f'{pixels * fields["camera_rate_hz"]:,.0f} pixels a simulated '
                          f'second, more than {MAX_CAMERA_PIXELS_PER_SECOND:,} (about 5 s of '
                          'rendering each): lower the rate or the size')


def _check_frames(fields: Mapping[str, Any]) -> None:
    """
    Refuse frame ids that would break the TF tree: any two of the robot's frames alike.

    TF is one tree: odom -> footprint -> base -> sensors, under world when
    publish_ground_truth_tf is on. Two roles given one frame make a cycle
    (odom_frame_id base_link) or a transform from a frame to itself
    (footprint_frame_id base_link), which tf2 refuses. frame_prefix goes in
    front of every robot frame but not of world_frame_id, so world is
    compared with the prefixed names.
    """
    prefix = fields['frame_prefix']
    parameters = [(name, fields[name])
                  for name in ('odom_frame_id', 'footprint_frame_id', 'base_frame_id')]
    sensors = []
    for rate, frames, what, switch in (
            ('scan_rate_hz', (LASER_FRAME_ID,), "the laser's frame", 'scan_rate > 0'),
            ('lidar3d_rate_hz', (LIDAR3D_FRAME_ID,), "the 3D lidar's frame", 'lidar3d_rate > 0'),
            ('imu_rate_hz', (IMU_FRAME_ID,), "the IMU's frame", 'imu_rate > 0'),
            ('camera_rate_hz', (HEAD_CAMERA_FRAME_ID, HEAD_CAMERA_LINK),
             "a head camera frame", 'camera_rate > 0')):
        if fields[rate] > 0.0:
            sensors += [(frame, what, switch) for frame in frames]
    distinct = ': TF needs a distinct frame for each'
    seen: Dict[str, str] = {}
    for name, frame in parameters:
        if frame in seen:
            raise ConfigError(f'parameters {seen[frame]} and {name} both name the frame '
                              f'{prefix + frame!r}{distinct}')
        seen[frame] = name
    for frame, what, switch in sensors:
        if frame in seen:
            raise ConfigError(f'parameter {seen[frame]} names {what} {prefix + frame!r} '
                              f'({switch}){distinct}')
    world = fields['world_frame_id']
    if not world.startswith(prefix):
        return
    local = world[len(prefix):]
    with_prefix = f' (with frame_prefix {prefix!r})' if prefix else ''
    if local in seen:
        raise ConfigError(f'parameters world_frame_id and {seen[local]}{with_prefix} both name '
                          f'the frame {world!r}{distinct}')
    for frame, what, switch in sensors:
        if frame == local:
            raise ConfigError(f'parameter world_frame_id names {what} {world!r} '
                              f'({switch}){distinct}')


def main(argv: Optional[list] = None) -> int:
    """Check (or with ``--write``, rewrite) the SimConfig field block of this file."""
    args = sys.argv[1:] if argv is None else argv
    path = __file__
    with open(path, encoding='utf-8') as handle:
        text = handle.read()
    start, end = text.index(BEGIN), text.index(END) + len(END)
    fresh = text[:start] + render_fields() + text[end:]
    if fresh == text:
        return 0
    if '--write' not in args:
        print('r2d2_sim/sim/settings/config.py: the SimConfig fields differ from the table: '
              'python -m r2d2_sim.sim.settings.config --write', file=sys.stderr)
        return 1
    with open(path, 'w', encoding='utf-8') as handle:
        handle.write(fresh)
    return 0


if __name__ == '__main__':
    sys.exit(main())
