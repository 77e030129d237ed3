"""
The node's parameters: names, defaults, descriptions and validation.

No ROS here: :func:`parse_config` turns a plain ``{name: value}`` mapping into a
validated :class:`SimConfig` or raises :class:`ConfigError` with one readable
line, so a bad parameter is a clear start-up error rather than a traceback.
"""

from dataclasses import dataclass
import math
from typing import Any, Dict, List, Mapping, NamedTuple, Tuple


class ConfigError(ValueError):
    """A parameter value the simulator cannot run with."""


# Measured on the package's own R2D2 (four wheels skid-steering, lateral
# friction ratio 0.35): it turns at 90-95 % of an ideal differential drive's
# yaw rate for wheel speeds of 1 to 10 rad/s; an effective track of 1.1 x the
# geometric 0.44 m makes a 0.5 rad/s command turn at 0.5 rad/s.
DEFAULT_WHEEL_SEPARATION_MULTIPLIER = 1.1


class ParameterSpec(NamedTuple):
    """One ROS parameter: its name, default value and description."""

    name: str
    default: Any
    description: str


PARAMETERS: List[ParameterSpec] = [
    ParameterSpec('urdf', '',
                  'Robot description file; empty means the package\'s own urdf/r2d2.urdf.'),
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
    ParameterSpec('odom_frame_id', 'odom', 'Frame of the wheel odometry.'),
    ParameterSpec('base_frame_id', 'base_link', 'Child frame of both odometry topics.'),
    ParameterSpec('world_frame_id', 'world', 'Frame of the ground_truth odometry.'),
    ParameterSpec('initial_pose', [0.0, 0.0, 0.0],
                  'Spawn pose [x (m), y (m), yaw (rad)] in the world frame.'),
    ParameterSpec('pose_covariance_diagonal', [0.001, 0.001, 1.0e6, 1.0e6, 1.0e6, 0.01],
                  'Diagonal of the odom pose covariance (x, y, z, roll, pitch, yaw).'),
    ParameterSpec('twist_covariance_diagonal', [0.001, 1.0e6, 1.0e6, 1.0e6, 1.0e6, 0.01],
                  'Diagonal of the odom twist covariance (vx, vy, vz, wx, wy, wz).'),
]


@dataclass(frozen=True)
class SimConfig:
    """Validated simulator settings, in SI units."""

    urdf: str
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
    odom_frame_id: str
    base_frame_id: str
    world_frame_id: str
    initial_pose: Tuple[float, float, float]
    pose_covariance_diagonal: Tuple[float, ...]
    twist_covariance_diagonal: Tuple[float, ...]

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


def _strings(name: str, value: Any) -> Tuple[str, ...]:
    if isinstance(value, str) or not all(isinstance(v, str) for v in value):
        raise ConfigError(f'parameter {name} must be a list of joint names, got {value!r}')
    names = tuple(value)
    if len(set(names)) != len(names):
        raise ConfigError(f'parameter {name} lists a joint twice: {list(names)}')
    return names


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

    physics_rate = _positive('physics_rate', raw['physics_rate'])
    publish_rate = _non_negative('publish_rate', raw['publish_rate'])
    if publish_rate > physics_rate:
        raise ConfigError(
            f'parameter publish_rate ({publish_rate} Hz) cannot exceed physics_rate '
            f'({physics_rate} Hz)')
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
    return SimConfig(
        urdf=_string('urdf', raw['urdf'], allow_empty=True),
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
        odom_frame_id=_string('odom_frame_id', raw['odom_frame_id']),
        base_frame_id=_string('base_frame_id', raw['base_frame_id']),
        world_frame_id=_string('world_frame_id', raw['world_frame_id']),
        initial_pose=_numbers('initial_pose', raw['initial_pose'], 3),
        pose_covariance_diagonal=covariance['pose_covariance_diagonal'],
        twist_covariance_diagonal=covariance['twist_covariance_diagonal'],
    )
