"""
Which joints drive the robot: its wheels, their radius, the track between them, their limits.

No ROS here. The drive train is found by joint name in the URDF: which
joints are the left and right wheels, their radius, the track between them
and their limits, each from a parameter or else derived from the URDF (and
held to the parameter's bounds either way). Problems are one-line
:class:`~r2d2_sim.sim.settings.table.ConfigError` messages naming what to set.
"""

from dataclasses import dataclass
from typing import Callable, List, Optional, Tuple

from r2d2_sim.physics.body import Body, WorldError
from r2d2_sim.physics.records import GEOMETRY_CYLINDER, GEOMETRY_SPHERE, JointRecord
from r2d2_sim.model.kinematics import DiffDriveGeometry, TwistLimits
from r2d2_sim.sim.settings.table import (
    Bounds, ConfigError, WHEEL_FORCE, WHEEL_RADIUS, WHEEL_SEPARATION, WHEEL_VELOCITY)
from r2d2_sim.sim.settings.config import SimConfig

__all__ = ['DriveTrain', 'find_drive_train']


@dataclass(frozen=True)
class DriveTrain:
    """The wheel joints (left, then right) and the differential drive they make."""

    left_indices: Tuple[int, ...]
    right_indices: Tuple[int, ...]
    geometry: DiffDriveGeometry
    limits: TwistLimits
    max_force_n_m: float

    @property
    def wheel_indices(self) -> Tuple[int, ...]:
        """Return every wheel joint index, left wheels first."""
        return self.left_indices + self.right_indices


def _from_urdf(name: str, value: float, bounds: Bounds) -> float:
    """Hold a value derived from the URDF to the bounds of the parameter that overrides it."""
    try:
        return bounds.check(name, value)
    except ConfigError:
        raise ConfigError(f'the URDF gives {name.replace("_", " ")} {value:g} {bounds.unit}, '
                          f'outside {bounds.text()}: set {name}') from None


def find_drive_train(body: Body, config: SimConfig, source: str,
                     warn: Callable[[str], None]) -> Optional[DriveTrain]:
    """
    Find the wheels named in ``config`` and derive what the parameters leave at 0.

    Returns None for a robot without wheels: when it has none of the default
    wheel joints (with a warning that cmd_vel is ignored), or when both wheel
    lists are empty on a robot that has no joint named like a wheel.
    """
    wheels = _wheel_joints(body, config, source, warn)
    if wheels is None:
        return None
    left = tuple(body.joint(n).index for n in config.left_wheel_names)
    right = tuple(body.joint(n).index for n in config.right_wheel_names)
    radius = config.wheel_radius_m or _from_urdf(
        'wheel_radius', _wheel_radius_m(body, left[0]), WHEEL_RADIUS)
    separation = config.wheel_separation_m or _from_urdf(
        'wheel_separation', _track_m(body, left, right), WHEEL_SEPARATION)
    urdf_velocity = min(w.max_velocity for w in wheels)
    urdf_force = min(w.max_force for w in wheels)
    if not urdf_velocity > 0.0 and not config.max_wheel_velocity_rad_s:
        raise ConfigError('the URDF gives the wheels no velocity limit: set max_wheel_velocity')
    if not urdf_force > 0.0 and not config.max_wheel_force_n_m:
        raise ConfigError('the URDF gives the wheels no effort limit: set max_wheel_force')
    geometry = DiffDriveGeometry(
        wheel_radius_m=radius,
        wheel_separation_m=separation * config.wheel_separation_multiplier,
        max_wheel_velocity_rad_s=config.max_wheel_velocity_rad_s or _from_urdf(
            'max_wheel_velocity', urdf_velocity, WHEEL_VELOCITY))
    limits = TwistLimits(
        max_linear_m_s=config.max_linear_velocity_m_s,
        max_angular_rad_s=config.max_angular_velocity_rad_s,
        max_linear_acceleration_m_s2=config.max_linear_acceleration_m_s2,
        max_angular_acceleration_rad_s2=config.max_angular_acceleration_rad_s2)
    return DriveTrain(left, right, geometry, limits, config.max_wheel_force_n_m or _from_urdf(
        'max_wheel_force', urdf_force, WHEEL_FORCE))


def _wheel_joints(body: Body, config: SimConfig, source: str,
                  warn: Callable[[str], None]) -> Optional[List[JointRecord]]:
    """Return the wheel joints the configuration names (None: a robot without wheels)."""
    names = config.left_wheel_names + config.right_wheel_names
    missing = [n for n in names if n not in body.joints]
    if names and len(missing) == len(names) and config.wheel_names_are_default:
        warn(f'{source} has none of the default wheel joints: cmd_vel is ignored')
        return None
    if missing:
        raise ConfigError(
            f'wheel joint(s) {", ".join(missing)} not in the URDF; it has: '
            f'{", ".join(body.joints)}')
    if not names:
        wheel_names = [j.name for j in body.joints.values()
                       if j.type_name == 'revolute' and 'wheel' in j.name.lower()]
        if wheel_names:
            raise ConfigError(
                'left_wheel_names and right_wheel_names are empty, but the robot drives '
                f'on wheel joints {", ".join(wheel_names)}: list them as left and right wheels')
        return None
    wheels = [body.joint(n) for n in names]
    for wheel in wheels:
        if wheel.type_name != 'revolute':
            raise ConfigError(f'wheel joint {wheel.name} is {wheel.type_name}, '
                              'not a revolute/continuous joint')
    return wheels


def _track_m(body: Body, left: Tuple[int, ...], right: Tuple[int, ...]) -> float:
    """Track width: distance along the body y axis between left and right wheel centres."""
    positions = body.link_positions_in_base(left + right)
    left_y = [p[1] for p in positions[:len(left)]]
    right_y = [p[1] for p in positions[len(left):]]
    separation = sum(left_y) / len(left_y) - sum(right_y) / len(right_y)
    if separation <= 0.0:
        raise ConfigError(
            f'left wheels are not to the left of the right wheels (track {separation:.3f} m '
            'along base y): check left_wheel_names/right_wheel_names, and base_forward_axis '
            'for a URDF that faces another way than x (pybullet_data\'s r2d2.urdf faces y; '
            'package://r2d2_sim/urdf/r2d2.urdf faces x)')
    return separation


def _wheel_radius_m(body: Body, link: int) -> float:
    """Return the radius of a wheel from its collision shape (cylinder or sphere)."""
    for shape in body.collision_shapes(link):
        if shape.geometry == GEOMETRY_CYLINDER:
            return float(shape.dimensions[1])
        if shape.geometry == GEOMETRY_SPHERE:
            return float(shape.dimensions[0])
    raise WorldError(f'cannot derive a wheel radius: link {link} has no cylinder or sphere '
                     'collision shape (set wheel_radius)')
