"""
A robot that is never commanded stays where it stands: ten simulated minutes, to the 0.1 mm.

No ROS. Bullet's velocity motor holds a wheel's speed at 0, never its
angle, and its sequential solver leaves a residue in the order of the
wheels' links: R2D2 used to roll backwards at about 0.2 mm/s (-12 mm after
a minute, -0.12 m after ten) and left a dock it rested on. A parked robot's
wheels are braked now; once commanded they drive as before.
"""

import math

import pytest

from r2d2_sim.model.battery import CHARGING
from r2d2_sim.model.transforms import yaw_of

PHYSICS_RATE_HZ = 240
TEN_MINUTES_STEPS = 600 * PHYSICS_RATE_HZ
# The bound on the base's travel: what Bullet's contacts settle by (about 10 um) with room.
HOLD_M = 1e-4
HOLD_RAD = 1e-4

# Physics alone decides where the robot goes: sensors off, the state read once a second.
SIMULATION_DEFAULTS = {'scan_rate': 0.0, 'imu_rate': 0.0, 'camera_rate': 0.0,
                       'publish_rate': 1.0}


def farthest(simulation, steps):
    """Step ``steps`` times; return the base's farthest distance and turn from its start pose."""
    robot = simulation.robot
    x0, y0, yaw0 = robot.config.initial_pose
    distance = turn = 0.0
    for _ in range(steps):
        result = simulation.step()
        if result is not None and result.state_due:
            base = result.measurements[0].frame.base
            distance = max(distance, math.hypot(base.position[0] - x0, base.position[1] - y0))
            turn = max(turn, abs(yaw_of(base.orientation) - yaw0))
    return distance, turn


@pytest.mark.slow
def test_a_robot_never_commanded_stays_on_its_dock_for_ten_minutes(make):
    """144,000 steps at rest: within 0.1 mm and 1e-4 rad, odometry at 0, charging throughout."""
    simulation = make(battery_rate=1.0, battery_dock_pose=[0.0, 0.0, 0.0],
                      battery_dock_tolerance=[0.002, 0.01], battery_initial_charge=0.2)
    robot = simulation.robot
    distance, turn = farthest(simulation, TEN_MINUTES_STEPS)
    assert distance < HOLD_M, f'the parked robot moved {distance * 1e3:.3f} mm'
    assert turn < HOLD_RAD, f'the parked robot turned {turn:.2e} rad'
    odometry = robot.controller.odometry_state()
    assert math.hypot(odometry.x_m, odometry.y_m) < HOLD_M
    assert robot.battery.reading().status == CHARGING


def test_a_robot_stopped_after_driving_stays_where_it_stopped(make):
    """Driven, then a zero command: once the ramp has stopped it, ten seconds add nothing."""
    simulation = make()
    robot = simulation.robot
    robot.command(0.3, 0.2)
    for _ in range(PHYSICS_RATE_HZ):
        simulation.step()
    robot.command(0.0, 0.0)
    for _ in range(PHYSICS_RATE_HZ):
        simulation.step()
    stopped = robot.body.base_state()
    for _ in range(10 * PHYSICS_RATE_HZ):
        simulation.step()
    now = robot.body.base_state()
    moved = math.hypot(now.position[0] - stopped.position[0],
                       now.position[1] - stopped.position[1])
    assert moved < HOLD_M, f'the stopped robot moved {moved * 1e3:.3f} mm in 10 s'


def test_a_parked_robot_drives_off_when_commanded(make):
    """The brake lets go: a second at 0.3 m/s (its ramp) covers 0.2548 m, as before the brake."""
    simulation = make(cmd_vel_timeout=0.0)
    robot = simulation.robot
    for _ in range(PHYSICS_RATE_HZ):
        simulation.step()
    robot.command(0.3, 0.0)
    for _ in range(PHYSICS_RATE_HZ):
        simulation.step()
    assert robot.body.base_state().position[0] == pytest.approx(0.2548, abs=0.001)
