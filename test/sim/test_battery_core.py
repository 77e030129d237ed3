"""
The battery on a robot in the physics: its drain from the wheels, its dock, running empty.

No ROS. The drain is checked against the documented model fed with the
wheel torques and speeds the physics applied at each step (the efforts are
known, read from the same joint readout); a robot resting on its dock
charges and reads FULL once full; an empty robot stops, slows or goes on as
configured; a reset fills the battery again.
"""

import pytest

from r2d2_sim.model.battery import CHARGING, DISCHARGING, FULL

SIMULATION_DEFAULTS = {'battery_rate': 10.0, 'cmd_vel_timeout': 0.0}


def expected_charge(robot, frames, initial_ah, dt_s):
    """Integrate the documented current over ``frames``, each held for ``dt_s``."""
    config = robot.config
    charge = initial_ah
    for frame in frames:
        efforts = [abs(frame.joints.efforts[s]) for s in robot._wheel_slots]
        speeds = [abs(frame.joints.velocities[s]) for s in robot._wheel_slots]
        draw = (config.battery_idle_current_a + config.battery_current_per_effort_a_n_m
                * sum(efforts) + config.battery_current_per_speed_a_rad_s * sum(speeds))
        charge -= draw * dt_s / 3600.0
    return charge


def run(simulation, steps):
    """Step ``steps`` times; return each step's frame and the battery readings published."""
    frames, readings = [], []
    for _ in range(steps):
        measurement = simulation.step().measurements[0]
        frames.append(measurement.frame)
        if measurement.battery is not None:
            readings.append(measurement.battery)
    return frames, readings


def test_driving_drains_what_the_model_says_of_the_wheels_efforts_and_speeds(make):
    simulation = make(battery_capacity=1.0, battery_initial_charge=0.8)
    robot = simulation.robot
    robot.command(0.5, 0.3)
    frames, readings = run(simulation, 480)
    expected = expected_charge(robot, frames, 0.8, 1.0 / 240.0)
    assert robot.battery.charge_ah == pytest.approx(expected, rel=1e-12)
    assert 0.8 - expected > 1e-4  # the wheels drew something
    assert len(readings) == 20 and all(r.status == DISCHARGING for r in readings)
    last = readings[-1]
    assert last.current_a < -robot.config.battery_idle_current_a
    assert last.voltage_v == pytest.approx(12.8 + 4.0 * last.charge_ah / 1.0)


def test_a_robot_resting_on_its_dock_charges(make):
    simulation = make(battery_dock_pose=[1.0, -0.5, 0.4], initial_pose=[1.0, -0.5, 0.4],
                      battery_initial_charge=0.5)
    robot = simulation.robot
    frames, readings = run(simulation, 240)
    last = readings[-1]
    assert last.status == CHARGING
    assert last.current_a > 0.5  # Nav2 docking's charging_threshold
    config = robot.config
    settled = frames[-1]
    draw = (config.battery_idle_current_a + config.battery_current_per_effort_a_n_m * sum(
        abs(settled.joints.efforts[s]) for s in robot._wheel_slots))
    assert last.current_a == pytest.approx(config.battery_charge_current_a - draw, abs=0.05)
    assert last.charge_ah > 1.0


def test_a_full_battery_on_the_dock_reads_full(make):
    simulation = make(battery_dock_pose=[0.0, 0.0, 0.0])
    _, readings = run(simulation, 48)
    assert readings[-1].status == FULL and readings[-1].percentage == 1.0
    assert readings[-1].current_a == 0.0


def test_driving_off_the_dock_discharges_again(make):
    simulation = make(battery_dock_pose=[0.0, 0.0, 0.0], battery_initial_charge=0.5)
    _, resting = run(simulation, 120)
    simulation.robot.command(0.4, 0.0)
    _, driving = run(simulation, 480)
    assert resting[-1].status == CHARGING and driving[-1].status == DISCHARGING


def last_second_speed(make, behaviour):
    """Drive 3 s at 0.4 m/s on a battery that empties after about 1 s; return the last 1 s's."""
    simulation = make(battery_capacity=0.0005, battery_initial_charge=1.0,
                      battery_empty_behaviour=behaviour, battery_empty_speed=0.25)
    robot = simulation.robot
    robot.command(0.4, 0.0)
    frames, _ = run(simulation, 720)
    assert robot.battery.empty
    return frames[-1].base.position[0] - frames[-241].base.position[0]


def test_an_empty_robot_stops_slows_or_goes_on_as_configured(make):
    assert last_second_speed(make, 'continue') == pytest.approx(0.4, abs=0.01)
    assert last_second_speed(make, 'slow') == pytest.approx(0.25 * 0.4, abs=0.01)
    assert abs(last_second_speed(make, 'stop')) < 0.01


def test_a_reset_fills_the_battery_again(make):
    simulation = make(battery_initial_charge=0.7)
    simulation.robot.command(0.5, 0.0)
    run(simulation, 240)
    assert simulation.robot.battery.charge_ah < 1.4
    simulation.reset(state=True)
    assert simulation.robot.battery.charge_ah == pytest.approx(1.4)


def test_no_battery_unless_asked(make):
    assert make(battery_rate=0.0).robot.battery is None


def test_a_reading_between_state_publications_is_of_its_own_step(make):
    # battery_rate 20 Hz, publish_rate 5 Hz: three readings of four fall between two state
    # publications. Each must integrate up to its own step with the wheels of that step.
    simulation = make(publish_rate=5.0, battery_rate=20.0, battery_capacity=1.0,
                      battery_initial_charge=0.8)
    robot = simulation.robot
    robot.command(0.5, 0.0)
    readings = []  # (step, state published, reading, the wheels' joints after that step)
    for _ in range(240):
        result = simulation.step()
        measurement = result.measurements[0] if result is not None else None
        if measurement is not None and measurement.battery is not None:
            joints = robot.body.joint_states(robot.movable_indices)
            readings.append((result.step, result.state_due, measurement.battery, joints))
    assert len(readings) == 20 and sum(1 for r in readings if not r[1]) == 15
    config = robot.config
    for _, _, reading, joints in readings:
        draw = (config.battery_idle_current_a + config.battery_current_per_effort_a_n_m
                * sum(abs(joints.efforts[s]) for s in robot._wheel_slots)
                + config.battery_current_per_speed_a_rad_s
                * sum(abs(joints.velocities[s]) for s in robot._wheel_slots))
        assert reading.current_a == pytest.approx(-draw, rel=1e-12)
    for (step0, _, before, _), (step1, _, after, _) in zip(readings, readings[1:]):
        # Each reading's current held over the steps since the one before.
        held = after.current_a * (step1 - step0) / 240.0 / 3600.0
        assert after.charge_ah == pytest.approx(before.charge_ah + held, rel=1e-12)
        assert after.charge_ah < before.charge_ah
