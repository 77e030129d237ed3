"""
The battery model (r2d2_sim.model.battery) against its documented arithmetic.

Known wheel torques and speeds for a known time drain the documented
charge; a robot resting on the dock charges at the charger's current less
its draw, reads FULL once full, and the voltage follows the charge linearly.
"""

import math

import pytest

from r2d2_sim.model.battery import (
    Battery, BatteryConfigError, BatterySpec, CHARGING, DISCHARGING, Dock, FULL)

SPEC = BatterySpec(capacity_ah=2.0, initial_charge=0.5, voltage_empty_v=12.0,
                   voltage_full_v=16.0, idle_current_a=0.5, current_per_effort_a_n_m=1.0,
                   current_per_speed_a_rad_s=0.02, charge_current_a=3.0)
DOCK = Dock(1.0, 2.0, math.pi / 2, 0.1, 0.2)
AWAY = (0.0, 0.0, 0.0)
ON_DOCK = (1.05, 2.0, math.pi / 2 + 0.1)


def test_known_effort_and_time_drain_the_documented_charge():
    """4 wheels at 0.5 N m and 10 rad/s: I = 0.5 + 1.0 * 2 + 0.02 * 40 = 3.3 A; 360 s: 0.33 Ah."""
    battery = Battery(SPEC)
    for _ in range(3600):
        battery.update(0.1, [0.5, -0.5, 0.5, -0.5], [10.0, -10.0, 10.0, 10.0], AWAY, 1.0)
    reading = battery.reading()
    assert reading.current_a == pytest.approx(-3.3)
    assert reading.charge_ah == pytest.approx(1.0 - 0.33)
    assert reading.percentage == pytest.approx(0.67 / 2.0)
    assert reading.voltage_v == pytest.approx(12.0 + 4.0 * 0.67 / 2.0)
    assert reading.status == DISCHARGING and reading.capacity_ah == 2.0


def test_resting_on_the_dock_charges_at_the_charger_current_less_the_draw():
    """Idle on the dock: 3.0 - 0.5 = 2.5 A (Nav2 wants > 0.5); 1440 s fill the missing 1 Ah."""
    battery = Battery(SPEC, DOCK)
    battery.update(0.0, [], [], ON_DOCK, 0.0)
    assert battery.reading().current_a == pytest.approx(2.5)
    assert battery.reading().status == CHARGING
    for _ in range(1440):  # 1440 s at 2.5 A: exactly 1 Ah
        battery.update(1.0, [0.0] * 4, [0.0] * 4, ON_DOCK, 0.0)
    assert battery.full and battery.reading().percentage == pytest.approx(1.0)
    battery.update(1.0, [0.0] * 4, [0.0] * 4, ON_DOCK, 0.0)
    reading = battery.reading()
    assert (reading.status, reading.current_a, reading.charge_ah) == (FULL, 0.0, 2.0)
    assert reading.voltage_v == 16.0


@pytest.mark.parametrize('pose, speed', [
    ((1.2, 2.0, math.pi / 2), 0.0),          # 0.2 m away: beyond 0.1
    ((1.0, 2.0, math.pi / 2 + 0.3), 0.0),    # turned 0.3 rad: beyond 0.2
    ((1.0, 2.0, math.pi / 2), 0.2),          # on it, but driving across
])
def test_near_the_dock_but_not_resting_on_it_discharges(pose, speed):
    battery = Battery(SPEC, DOCK)
    battery.update(1.0, [], [], pose, speed)
    assert battery.reading().status == DISCHARGING and battery.reading().current_a == -0.5


def test_the_yaw_tolerance_wraps_round():
    dock = Dock(0.0, 0.0, math.pi - 0.05, 0.1, 0.2)
    assert dock.holds(0.0, 0.0, -math.pi + 0.05, 0.0)


def test_the_charge_stays_within_empty_and_full():
    battery = Battery(BatterySpec(capacity_ah=0.001, initial_charge=0.1))
    battery.update(3600.0, [10.0], [10.0], AWAY, 0.0)
    assert battery.empty and battery.charge_ah == 0.0 and battery.reading().percentage == 0.0
    battery.reset()
    assert battery.charge_ah == pytest.approx(0.0001)


@pytest.mark.parametrize('kwargs, message', [
    ({'capacity_ah': 0.0}, 'capacity_ah must be > 0'),
    ({'initial_charge': 1.5}, r'initial_charge must be in \[0, 1\]'),
    ({'voltage_empty_v': 17.0}, 'voltage_empty_v .* must be below voltage_full_v'),
    ({'idle_current_a': -1.0}, 'idle_current_a must be a finite number >= 0'),
    ({'charge_current_a': math.nan}, 'charge_current_a must be a finite number'),
])
def test_bad_battery_settings_are_refused_in_one_line(kwargs, message):
    with pytest.raises(BatteryConfigError, match=message):
        BatterySpec(**kwargs)
