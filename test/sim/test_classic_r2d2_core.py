"""
The tutorial's classic R2D2 with urdf/classic_r2d2.yaml stays on its wheels at its limits.

No ROS. Its wheels' inertia tensors are the identity (1 kg m^2 on a 0.035 m
wheel), so speeding up pitches the body against the wheels' motors: without a
speed limit, the wheel limit let it take 0.5 m/s, and it pitched over within
2 s. Driving at full speed forward, then at full speed backward (the hardest
case: a full reversal), then stopping, it must stay upright and keep its speed.
"""

import math

import pytest

from common import classic_params

SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'scan_rate': 0.0}
MAX_TILT_RAD = math.radians(3.0)


def tilt_rad(orientation):
    """Return the angle between the body's z axis and the world's: 0 upright, pi upside down."""
    x, y, _, _ = orientation
    return math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (x * x + y * y))))


def drive(simulation, linear_m_s, seconds):
    """Command ``linear_m_s`` (beyond the limit: held to it); return the worst tilt, last base."""
    simulation.robot.command(linear_m_s, 0.0)
    worst = 0.0
    for _ in range(round(seconds * 240)):
        base = simulation.step().measurements[0].frame.base
        worst = max(worst, tilt_rad(base.orientation))
    return worst, base


def test_the_classic_stays_upright_at_its_speed_limit_forward_backward_and_stopping(make):
    simulation = make(**classic_params())
    limit_m_s = simulation.robot.controller.limits.max_linear_m_s
    for command_m_s in (10.0, -10.0):  # far beyond the wheels' limit: held to the speed limit
        worst, base = drive(simulation, command_m_s, 5.0)
        assert worst < MAX_TILT_RAD
        assert base.linear_velocity[0] == pytest.approx(math.copysign(limit_m_s, command_m_s),
                                                        rel=0.05)
    worst, base = drive(simulation, 0.0, 3.0)
    assert worst < MAX_TILT_RAD
    assert abs(base.linear_velocity[0]) < 0.01


@pytest.mark.parametrize('sign', [1.0, -1.0])
def test_the_classic_stays_upright_turning_at_full_speed(make, sign):
    """Tight arcs at the speed and turn rate limits (3 rad/s), forward and backward, and a spin."""
    simulation = make(**classic_params())
    limits = simulation.robot.controller.limits
    angular_rad_s = sign * limits.max_angular_rad_s
    worst = 0.0
    for linear_m_s in (limits.max_linear_m_s, -limits.max_linear_m_s, 0.0):
        verdict = simulation.robot.command(linear_m_s, angular_rad_s)
        assert verdict.accepted is not None and not verdict.clamped
        for _ in range(3 * 240):
            base = simulation.step().measurements[0].frame.base
            worst = max(worst, tilt_rad(base.orientation))
    assert worst < MAX_TILT_RAD
