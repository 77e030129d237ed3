"""
Has the physics blown up? Plain checks on a body's state, run every step.

No ROS, no PyBullet: the checks take numbers and return None (healthy) or a
one-line reason. Beyond these limits a state is absurd rather than physical:
the robot was flung off the world or the solver diverged. R2D2 drives at
1.75 m/s at most, and Bullet caps body speeds at 100 (m/s or rad/s), so an
explosion saturates there: a limit of 1e3 never fired.
"""

import math
from typing import Optional, Sequence

__all__ = ['MAX_DISTANCE_M', 'MAX_LINEAR_SPEED_M_S', 'MAX_ANGULAR_SPEED_RAD_S',
           'base_problem', 'twist_problem', 'joint_problem', 'joints_finite']

MAX_DISTANCE_M = 1.0e4
MAX_LINEAR_SPEED_M_S = 50.0
MAX_ANGULAR_SPEED_RAD_S = 50.0


def _format(values: Sequence[float]) -> str:
    return '(' + ', '.join(f'{v:.4g}' for v in values) + ')'


def base_problem(position: Sequence[float], orientation: Sequence[float],
                 linear: Sequence[float], angular: Sequence[float]) -> Optional[str]:
    """
    Return None if a base's pose and twist are finite and in bounds, else what is wrong.

    Speeds are frame-independent, so the centre of mass's world twist and
    the body frame's twist pass the same test.
    """
    # The usual case in one expression (NaN and inf fail every comparison);
    # a norm under a limit implies every axis under it. Else find out what.
    (x, y, z), (vx, vy, vz), (wx, wy, wz) = position, linear, angular
    if (x * x + y * y + z * z < MAX_DISTANCE_M ** 2
            and vx * vx + vy * vy + vz * vz < MAX_LINEAR_SPEED_M_S ** 2
            and wx * wx + wy * wy + wz * wz < MAX_ANGULAR_SPEED_RAD_S ** 2
            and math.isfinite(sum(orientation))):
        return None
    for label, values in (('position', position), ('orientation', orientation),
                          ('linear velocity', linear), ('angular velocity', angular)):
        if not all(map(math.isfinite, values)):
            return f'base {label} is not finite: {_format(values)}'
    if max(map(abs, position)) > MAX_DISTANCE_M:
        return f'base left the world: position {_format(position)} m'
    # Spin first: a body spun about a far axis also moves its centre fast.
    spin = math.sqrt(angular[0] ** 2 + angular[1] ** 2 + angular[2] ** 2)
    if spin > MAX_ANGULAR_SPEED_RAD_S:
        return f'base spinning at {spin:.3g} rad/s'
    speed = math.sqrt(linear[0] ** 2 + linear[1] ** 2 + linear[2] ** 2)
    if speed > MAX_LINEAR_SPEED_M_S:
        return f'base flung at {speed:.3g} m/s'
    return None


def twist_problem(linear: Sequence[float], angular: Sequence[float]) -> Optional[str]:
    """
    Return None if a base's twist is finite and in bounds, else what is wrong.

    The check of the steps that measure nothing: a body blowing up shows in
    its velocity at once (a NaN or a runaway pose comes from it), and the
    whole state is checked before anything is read for publishing.
    """
    (vx, vy, vz), (wx, wy, wz) = linear, angular
    if (vx * vx + vy * vy + vz * vz < MAX_LINEAR_SPEED_M_S ** 2
            and wx * wx + wy * wy + wz * wz < MAX_ANGULAR_SPEED_RAD_S ** 2):
        return None
    return base_problem((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0), linear, angular)


def joints_finite(positions: Sequence[float], velocities: Sequence[float]) -> bool:
    """Return True when every value is finite: the usual case, in one expression."""
    return math.isfinite(sum(positions) + sum(velocities))  # False too on an overflowed sum


def joint_problem(names: Sequence[str], positions: Sequence[float],
                  velocities: Sequence[float]) -> Optional[str]:
    """Return None if the joints' readout is finite, else which joints are not."""
    if joints_finite(positions, velocities):
        return None  # a sum of finite values that overflowed is looked at below
    for values in (positions, velocities):
        bad = [name for name, v in zip(names, values) if not math.isfinite(v)]
        if bad:
            return f'joint state not finite: {", ".join(bad)}'
    return None
