"""
The node's parameters: names, defaults, descriptions and validation.

No ROS here: :func:`parse_config` turns a plain ``{name: value}`` mapping into a
validated :class:`SimConfig` or raises :class:`ConfigError` with one readable
line, so a bad parameter is a clear start-up error rather than a traceback.
"""

from dataclasses import dataclass
import math
from typing import Any, Dict, List, Mapping, NamedTuple, Sequence, Tuple


class ConfigError(ValueError):
    """A parameter value the simulator cannot run with."""


# Measured on the package's own R2D2 (four wheels skid-steering, lateral
# friction ratio 0.35): it turns at 90-95 % of an ideal differential drive's
# yaw rate for wheel speeds of 1 to 10 rad/s; an effective track of 1.1 x the
# geometric 0.44 m makes a 0.5 rad/s command turn at 0.5 rad/s.
DEFAULT_WHEEL_SEPARATION_MULTIPLIER = 1.1

# Measured on the package's R2D2 (tall, 0.44 m track): a step to full speed
# (1.75 m/s, the wheels' 50 rad/s) tips it over at 3 m/s^2 and above, but not at
# 2; spinning in place it stays upright up to about 3 rad/s (7 degrees of
# wobble) and falls over at 5. The defaults keep any command on its wheels.
DEFAULT_MAX_LINEAR_ACCELERATION_M_S2 = 1.0
DEFAULT_MAX_ANGULAR_ACCELERATION_RAD_S2 = 2.0
DEFAULT_MAX_ANGULAR_VELOCITY_RAD_S = 3.0


class ParameterSpec(NamedTuple):
    """One ROS parameter: its name, default value and description."""

    name: str
    default: Any
    description: str


PARAMETERS: List[ParameterSpec] = [
    ParameterSpec('urdf', '',
                  'Robot description: a file path, a package://pkg/path URI or a name in '
                  'pybullet_data (r2d2.urdf); empty means the package\'s own urdf/r2d2.urdf.'),
    ParameterSpec('robot_description', '',
                  'URDF XML text (as robot_state_publisher takes it); overrides urdf.'),
    ParameterSpec('base_forward_axis', 'x',
                  'Axis of the URDF base frame the robot drives along: x, y, -x or -y.'),
    ParameterSpec('wheel_velocity_sign', 1,
                  '1, or -1 when a negative wheel velocity drives the robot forward.'),
    ParameterSpec('gravity', [0.0, 0.0, -9.8], 'Gravity [x, y, z] in m/s^2.'),
    ParameterSpec('ground_plane', True, 'Load pybullet_data\'s plane.urdf as the ground.'),
    ParameterSpec('extra_models', [],
                  'Other bodies, each "description x y z" (description resolved like urdf).'),
    ParameterSpec('gui', False, 'Open the PyBullet window (needs a display).'),
    ParameterSpec('physics_rate', 240.0, 'Physics steps per simulated second (Hz).'),
    ParameterSpec('real_time_factor', 1.0,
                  'Simulated seconds per wall-clock second; 0 runs as fast as possible.'),
    ParameterSpec('publish_rate', 0.0,
                  'State publishing rate in simulated Hz; 0 publishes after every physics step.'),
    ParameterSpec('cmd_vel_timeout', 0.5,
                  'Simulated seconds without cmd_vel before the wheels are braked; 0 disables.'),
    ParameterSpec('start_paused', False,
                  'Start with physics stopped, waiting for ~/pause false or ~/step.'),
    ParameterSpec('wheel_radius', 0.0,
                  'Wheel radius in metres; 0 derives it from the wheels\' collision shapes.'),
    ParameterSpec('wheel_separation', 0.0,
                  'Distance between left and right wheels in metres; 0 derives it from the URDF.'),
    ParameterSpec('wheel_separation_multiplier', DEFAULT_WHEEL_SEPARATION_MULTIPLIER,
                  'Effective/nominal track ratio used by commands and odometry (skid steering).'),
    ParameterSpec('wheel_lateral_friction_ratio', 0.35,
                  'Wheel grip along the axle relative to rolling grip, in (0, 1].'),
    ParameterSpec('left_wheel_names', ['left_front_wheel_joint', 'left_back_wheel_joint'],
                  'Joints driven as the left side.'),
    ParameterSpec('right_wheel_names', ['right_front_wheel_joint', 'right_back_wheel_joint'],
                  'Joints driven as the right side.'),
    ParameterSpec('max_wheel_velocity', 0.0,
                  'Wheel speed limit in rad/s; 0 takes the URDF joint velocity limit.'),
    ParameterSpec('max_wheel_force', 0.0,
                  'Wheel motor torque limit in N m; 0 takes the URDF joint effort limit.'),
    ParameterSpec('max_linear_velocity', 0.0,
                  'Forward speed limit in m/s; 0 leaves only the wheel speed limit.'),
    ParameterSpec('max_angular_velocity', DEFAULT_MAX_ANGULAR_VELOCITY_RAD_S,
                  'Turn rate limit in rad/s; 0 leaves only the wheel speed limit.'),
    ParameterSpec('max_linear_acceleration', DEFAULT_MAX_LINEAR_ACCELERATION_M_S2,
                  'Forward acceleration and braking limit in m/s^2; 0 means none.'),
    ParameterSpec('max_angular_acceleration', DEFAULT_MAX_ANGULAR_ACCELERATION_RAD_S2,
                  'Turn rate acceleration limit in rad/s^2; 0 means none.'),
    ParameterSpec('odom_frame_id', 'odom', 'Frame of the wheel odometry.'),
    ParameterSpec('base_frame_id', 'base_link', 'Child frame of both odometry topics.'),
    ParameterSpec('world_frame_id', 'world', 'Frame of the ground_truth odometry.'),
    ParameterSpec('initial_pose', [0.0, 0.0, 0.0],
                  'Spawn pose [x (m), y (m), yaw (rad)] in the world frame.'),
    ParameterSpec('pose_covariance_diagonal', [0.001, 0.001, 1.0e6, 1.0e6, 1.0e6, 0.01],
                  'Diagonal of the odom pose covariance (x, y, z, roll, pitch, yaw).'),
    ParameterSpec('twist_covariance_diagonal', [0.001, 1.0e6, 1.0e6, 1.0e6, 1.0e6, 0.01],
                  'Diagonal of the odom twist covariance (vx, vy, vz, wx, wy, wz).'),
    ParameterSpec('camera_rate', 0.0,
                  'Head camera images per simulated second (Hz); 0 turns the camera off.'),
    ParameterSpec('camera_width', 320, 'Head camera image width in pixels.'),
    ParameterSpec('camera_height', 240, 'Head camera image height in pixels.'),
    ParameterSpec('camera_fov', 60.0, 'Head camera vertical field of view in degrees.'),
]

# Physics steps outside this range are too coarse to be stable or too fine to
# be useful; gravity beyond this flings any robot apart.
MIN_PHYSICS_RATE_HZ = 10.0
MAX_PHYSICS_RATE_HZ = 10000.0
MAX_GRAVITY_M_S2 = 1000.0

# Yaw from the URDF base frame to the REP-103 body frame for each forward axis.
FORWARD_AXIS_YAW_RAD = {'x': 0.0, 'y': math.pi / 2, '-x': math.pi, '-y': -math.pi / 2}


@dataclass(frozen=True)
class SimConfig:
    """Validated simulator settings, in SI units."""

    urdf: str
    robot_description: str
    base_forward_axis: str
    wheel_velocity_sign: int
    gravity_m_s2: Tuple[float, float, float]
    ground_plane: bool
    extra_models: Tuple[Tuple[str, Tuple[float, float, float]], ...]
    gui: bool
    physics_rate_hz: float
    real_time_factor: float
    publish_rate_hz: float
    cmd_vel_timeout_s: float
    start_paused: bool
    wheel_radius_m: float
    wheel_separation_m: float
    wheel_separation_multiplier: float
    wheel_lateral_friction_ratio: float
    left_wheel_names: Tuple[str, ...]
    right_wheel_names: Tuple[str, ...]
    max_wheel_velocity_rad_s: float
    max_wheel_force_n_m: float
    max_linear_velocity_m_s: float
    max_angular_velocity_rad_s: float
    max_linear_acceleration_m_s2: float
    max_angular_acceleration_rad_s2: float
    odom_frame_id: str
    base_frame_id: str
    world_frame_id: str
    initial_pose: Tuple[float, float, float]
    pose_covariance_diagonal: Tuple[float, ...]
    twist_covariance_diagonal: Tuple[float, ...]
    camera_rate_hz: float
    camera_width_px: int
    camera_height_px: int
    camera_fov_deg: float

    @property
    def body_yaw_offset_rad(self) -> float:
        """Return the yaw from the URDF base frame to the REP-103 body frame."""
        return FORWARD_AXIS_YAW_RAD[self.base_forward_axis]

    @property
    def wheel_names_are_default(self) -> bool:
        """Return True when the wheel joint names were left at their defaults."""
        defaults = {spec.name: spec.default for spec in PARAMETERS}
        return (list(self.left_wheel_names) == defaults['left_wheel_names']
                and list(self.right_wheel_names) == defaults['right_wheel_names'])


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f'parameter {name} must be a number, got {value!r}')
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(f'parameter {name} must be finite, got {value}')
    return value


def _positive(name: str, value: Any) -> float:
    value = _number(name, value)
    if value <= 0.0:
        raise ConfigError(f'parameter {name} must be > 0, got {value}')
    return value


def _non_negative(name: str, value: Any) -> float:
    value = _number(name, value)
    if value < 0.0:
        raise ConfigError(f'parameter {name} must be >= 0, got {value}')
    return value


def _limit(name: str, value: Any) -> float:
    """Read a limit where 0 means none: math.inf."""
    return _non_negative(name, value) or math.inf


def _event_rate(name: str, value: Any, physics_rate: float) -> float:
    """Validate a rate of something done between physics steps: 0 <= rate <= physics."""
    value = _non_negative(name, value)
    if value > physics_rate:
        raise ConfigError(
            f'parameter {name} ({value} Hz) cannot exceed physics_rate ({physics_rate} Hz)')
    return value


def _ratio(name: str, value: Any) -> float:
    value = _positive(name, value)
    if value > 1.0:
        raise ConfigError(f'parameter {name} must be in (0, 1], got {value}')
    return value


def _boolean(name: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(f'parameter {name} must be true or false, got {value!r}')
    return value


def _string(name: str, value: Any, allow_empty: bool = False) -> str:
    if not isinstance(value, str):
        raise ConfigError(f'parameter {name} must be a string, got {value!r}')
    if not allow_empty and not value.strip():
        raise ConfigError(f'parameter {name} must not be empty')
    return value


def _is_string_list(value: Any) -> bool:
    return (isinstance(value, (list, tuple))
            and all(isinstance(v, str) for v in value))


def _strings(name: str, value: Any) -> Tuple[str, ...]:
    if not _is_string_list(value):
        raise ConfigError(f'parameter {name} must be a list of joint names, got {value!r}')
    names = tuple(value)
    if len(set(names)) != len(names):
        raise ConfigError(f'parameter {name} lists a joint twice: {list(names)}')
    return names


def _integer(name: str, value: Any, low: int, high: int) -> int:
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or (isinstance(value, float) and not value.is_integer())):
        raise ConfigError(f'parameter {name} must be an integer, got {value!r}')
    if not low <= value <= high:
        raise ConfigError(f'parameter {name} must be in [{low}, {high}], got {value}')
    return int(value)


def _choice(name: str, value: Any, choices: Sequence[Any]) -> Any:
    if isinstance(value, bool) or value not in choices:
        # ROS parameter files read a bare y, n, yes, on... as booleans.
        hint = ' (quote the value in YAML files)' if isinstance(value, bool) else ''
        raise ConfigError(f'parameter {name} must be one of '
                          f'{", ".join(str(c) for c in choices)}; got {value!r}{hint}')
    return value


def _extra_models(value: Any) -> Tuple[Tuple[str, Tuple[float, float, float]], ...]:
    if not _is_string_list(value):
        raise ConfigError(f'parameter extra_models must be a list of strings, got {value!r}')
    models = []
    for entry in value:
        parts = entry.rsplit(None, 3)
        try:
            if len(parts) != 4:
                raise ValueError
            position = tuple(float(p) for p in parts[1:])
        except ValueError:
            raise ConfigError(f'parameter extra_models: entry {entry!r} is not '
                              '"description x y z"') from None
        if not all(math.isfinite(p) for p in position):
            raise ConfigError(f'parameter extra_models: entry {entry!r} has a non-finite '
                              'position')
        models.append((parts[0], position))
    return tuple(models)


def _numbers(name: str, value: Any, length: int) -> Tuple[float, ...]:
    if isinstance(value, (str, bytes)) or not hasattr(value, '__len__') or len(value) != length:
        raise ConfigError(f'parameter {name} must be a list of {length} numbers, got {value!r}')
    return tuple(_number(name, v) for v in value)


def parse_config(values: Mapping[str, Any]) -> SimConfig:
    """Validate raw parameter values (defaults filled in) into a SimConfig."""
    unknown = set(values) - {spec.name for spec in PARAMETERS}
    if unknown:
        raise ConfigError(f'unknown parameter(s): {", ".join(sorted(unknown))}')
    raw: Dict[str, Any] = {spec.name: spec.default for spec in PARAMETERS}
    raw.update(values)
    for spec in PARAMETERS:
        # ROS cannot tell the type of an empty list (-p names:=[]): it arrives as None.
        if raw[spec.name] is None and isinstance(spec.default, list):
            raw[spec.name] = []

    physics_rate = _positive('physics_rate', raw['physics_rate'])
    if not MIN_PHYSICS_RATE_HZ <= physics_rate <= MAX_PHYSICS_RATE_HZ:
        raise ConfigError(f'parameter physics_rate must be in [{MIN_PHYSICS_RATE_HZ:g}, '
                          f'{MAX_PHYSICS_RATE_HZ:g}] Hz, got {physics_rate}')
    gravity = _numbers('gravity', raw['gravity'], 3)
    if max(map(abs, gravity)) > MAX_GRAVITY_M_S2:
        raise ConfigError(f'parameter gravity must be within +-{MAX_GRAVITY_M_S2:g} m/s^2 '
                          f'on each axis, got {list(gravity)}')
    publish_rate = _event_rate('publish_rate', raw['publish_rate'], physics_rate)
    left = _strings('left_wheel_names', raw['left_wheel_names'])
    right = _strings('right_wheel_names', raw['right_wheel_names'])
    if bool(left) != bool(right):
        raise ConfigError('left_wheel_names and right_wheel_names must both list wheels '
                          'or both be empty')
    both = set(left) & set(right)
    if both:
        raise ConfigError(
            f'joint(s) {", ".join(sorted(both))} listed as both left and right wheels')
    covariance = {}
    for name in ('pose_covariance_diagonal', 'twist_covariance_diagonal'):
        covariance[name] = _numbers(name, raw[name], 6)
        if min(covariance[name]) < 0.0:
            raise ConfigError(f'parameter {name} must not contain negative variances')
    camera_rate = _event_rate('camera_rate', raw['camera_rate'], physics_rate)
    camera_fov = _positive('camera_fov', raw['camera_fov'])
    if camera_fov >= 180.0:
        raise ConfigError(f'parameter camera_fov must be below 180 degrees, got {camera_fov}')
    return SimConfig(
        urdf=_string('urdf', raw['urdf'], allow_empty=True),
        robot_description=_string('robot_description', raw['robot_description'],
                                  allow_empty=True),
        base_forward_axis=_choice('base_forward_axis', raw['base_forward_axis'],
                                  list(FORWARD_AXIS_YAW_RAD)),
        wheel_velocity_sign=int(_choice('wheel_velocity_sign', raw['wheel_velocity_sign'],
                                        [1, -1])),
        gravity_m_s2=gravity,
        ground_plane=_boolean('ground_plane', raw['ground_plane']),
        extra_models=_extra_models(raw['extra_models']),
        gui=_boolean('gui', raw['gui']),
        physics_rate_hz=physics_rate,
        real_time_factor=_non_negative('real_time_factor', raw['real_time_factor']),
        publish_rate_hz=publish_rate or physics_rate,
        cmd_vel_timeout_s=_non_negative('cmd_vel_timeout', raw['cmd_vel_timeout']),
        start_paused=_boolean('start_paused', raw['start_paused']),
        wheel_radius_m=_non_negative('wheel_radius', raw['wheel_radius']),
        wheel_separation_m=_non_negative('wheel_separation', raw['wheel_separation']),
        wheel_separation_multiplier=_positive('wheel_separation_multiplier',
                                              raw['wheel_separation_multiplier']),
        wheel_lateral_friction_ratio=_ratio('wheel_lateral_friction_ratio',
                                            raw['wheel_lateral_friction_ratio']),
        left_wheel_names=left,
        right_wheel_names=right,
        max_wheel_velocity_rad_s=_non_negative('max_wheel_velocity', raw['max_wheel_velocity']),
        max_wheel_force_n_m=_non_negative('max_wheel_force', raw['max_wheel_force']),
        max_linear_velocity_m_s=_limit('max_linear_velocity', raw['max_linear_velocity']),
        max_angular_velocity_rad_s=_limit('max_angular_velocity', raw['max_angular_velocity']),
        max_linear_acceleration_m_s2=_limit('max_linear_acceleration',
                                            raw['max_linear_acceleration']),
        max_angular_acceleration_rad_s2=_limit('max_angular_acceleration',
                                               raw['max_angular_acceleration']),
        odom_frame_id=_string('odom_frame_id', raw['odom_frame_id']),
        base_frame_id=_string('base_frame_id', raw['base_frame_id']),
        world_frame_id=_string('world_frame_id', raw['world_frame_id']),
        initial_pose=_numbers('initial_pose', raw['initial_pose'], 3),
        pose_covariance_diagonal=covariance['pose_covariance_diagonal'],
        twist_covariance_diagonal=covariance['twist_covariance_diagonal'],
        camera_rate_hz=camera_rate,
        camera_width_px=_integer('camera_width', raw['camera_width'], 1, 4096),
        camera_height_px=_integer('camera_height', raw['camera_height'], 1, 4096),
        camera_fov_deg=camera_fov,
    )
