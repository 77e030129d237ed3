"""
A battery for a robot that drives: charge drawn by the wheels and an idle load, refilled on a dock.

No ROS and no PyBullet here. The model, simple on purpose so a test (or a
user) can compute what it reports:

- **current drawn** I = idle + per_effort * sum|tau_i| + per_speed * sum|omega_i| (A),
  tau_i the torque each wheel motor applies (N m) and omega_i its speed
  (rad/s): a DC motor's current follows its torque, and the losses that
  grow with speed (friction, the drive's electronics) follow its speed;
- **on the dock** (its pose within tolerance, the base slower than
  :data:`RESTING_SPEED_M_S`) a charger feeds ``charge_current`` (A); the
  battery's current is then charge_current - I while it is not full, and 0
  once full (the charger carries the load). Off the dock it is -I;
- **charge** integrates the current: q += current * dt / 3600 (Ah), held
  within [0, capacity]; **percentage** = q / capacity;
- **voltage** is the open-circuit voltage, linear in the charge:
  v_empty + (v_full - v_empty) * percentage;
- **status**: CHARGING on the dock below full, FULL on the dock at full,
  DISCHARGING off it (sensor_msgs/BatteryState's power_supply_status).

Signs follow sensor_msgs/BatteryState: the current is negative when
discharging, so Nav2's docking (``current > charging_threshold``) sees a
robot on its dock charging.
"""

from dataclasses import dataclass, fields
import math
import numbers
from typing import NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.errors import SetupError

__all__ = ['BatteryConfigError', 'BatterySpec', 'Battery', 'BatteryReading', 'Dock',
           'CHARGING', 'DISCHARGING', 'FULL', 'RESTING_SPEED_M_S']

# sensor_msgs/BatteryState's power_supply_status values.
CHARGING, DISCHARGING, FULL = 1, 2, 4
# A robot rests on its dock when its base moves slower than this.
RESTING_SPEED_M_S = 0.05


class BatteryConfigError(SetupError, ValueError):
    """An impossible battery setting; the message names the field."""


@dataclass(frozen=True)
class BatterySpec:
    """The battery's numbers (see the module's model); each field's unit is in its name."""

    capacity_ah: float = 2.0
    initial_charge: float = 1.0          # fraction of the capacity at start-up and reset
    voltage_empty_v: float = 12.8
    voltage_full_v: float = 16.8
    idle_current_a: float = 0.5
    current_per_effort_a_n_m: float = 1.0
    current_per_speed_a_rad_s: float = 0.02
    charge_current_a: float = 2.0

    def __post_init__(self) -> None:
        """Check every field: finite, not negative, capacity and the voltages in order."""
        for field in fields(self):
            value = getattr(self, field.name)
            if isinstance(value, bool) or not isinstance(value, numbers.Real) \
                    or not math.isfinite(value) or value < 0.0:
                raise BatteryConfigError(f'{field.name} must be a finite number >= 0, '
                                         f'got {value!r}')
            object.__setattr__(self, field.name, float(value))
        if self.capacity_ah <= 0.0:
            raise BatteryConfigError(f'capacity_ah must be > 0, got {self.capacity_ah!r}')
        if self.initial_charge > 1.0:
            raise BatteryConfigError(f'initial_charge must be in [0, 1], got '
                                     f'{self.initial_charge!r}')
        if not self.voltage_empty_v < self.voltage_full_v:
            raise BatteryConfigError(f'voltage_empty_v ({self.voltage_empty_v}) must be below '
                                     f'voltage_full_v ({self.voltage_full_v})')


class Dock(NamedTuple):
    """Where the robot charges: a pose in the world and how close counts."""

    x_m: float
    y_m: float
    yaw_rad: float
    position_tolerance_m: float
    yaw_tolerance_rad: float

    def holds(self, x_m: float, y_m: float, yaw_rad: float, speed_m_s: float) -> bool:
        """Return True when a robot at (x, y, yaw), moving at ``speed_m_s``, rests on it."""
        return (math.hypot(x_m - self.x_m, y_m - self.y_m) <= self.position_tolerance_m
                and abs(math.remainder(yaw_rad - self.yaw_rad, 2.0 * math.pi))
                <= self.yaw_tolerance_rad
                and speed_m_s < RESTING_SPEED_M_S)


class BatteryReading(NamedTuple):
    """What sensor_msgs/BatteryState carries of the battery, in its units and signs."""

    voltage_v: float
    current_a: float        # negative when discharging
    charge_ah: float
    capacity_ah: float
    percentage: float       # 0 .. 1
    status: int             # CHARGING, DISCHARGING or FULL


class Battery:
    """One robot's battery (see the module's model), starting at ``initial_charge``."""

    def __init__(self, spec: BatterySpec, dock: Optional[Dock] = None) -> None:
        self.spec = spec
        self.dock = dock
        self.charge_ah = 0.0
        self.current_a = 0.0
        self.draw_a = 0.0
        self.on_dock = False
        self.reset()

    def reset(self) -> None:
        """Back to the initial charge, drawing nothing yet (a start-up, a reset)."""
        self.charge_ah = self.spec.initial_charge * self.spec.capacity_ah
        self.current_a = 0.0
        self.draw_a = self.spec.idle_current_a
        self.on_dock = False

    @property
    def empty(self) -> bool:
        """Return True when no charge is left."""
        return self.charge_ah <= 0.0

    @property
    def full(self) -> bool:
        """Return True when the battery holds its whole capacity."""
        return self.charge_ah >= self.spec.capacity_ah

    def draw(self, efforts_n_m: Sequence[float], speeds_rad_s: Sequence[float]) -> float:
        """Return the current the robot draws (A) with these wheel torques and speeds."""
        spec = self.spec
        return (spec.idle_current_a
                + spec.current_per_effort_a_n_m * sum(abs(e) for e in efforts_n_m)
                + spec.current_per_speed_a_rad_s * sum(abs(w) for w in speeds_rad_s))

    def update(self, dt_s: float, efforts_n_m: Sequence[float], speeds_rad_s: Sequence[float],
               pose: Tuple[float, float, float], speed_m_s: float) -> None:
        """
        Run the battery for ``dt_s`` seconds with these wheels, the robot at ``pose`` (x, y, yaw).

        The current is the one of the state at the end of the interval, held
        over it (the wheels' readout after a physics step).
        """
        spec = self.spec
        self.draw_a = self.draw(efforts_n_m, speeds_rad_s)
        self.on_dock = self.dock is not None and self.dock.holds(*pose, speed_m_s)
        if self.on_dock:
            self.current_a = 0.0 if self.full else spec.charge_current_a - self.draw_a
        else:
            self.current_a = -self.draw_a
        if dt_s > 0.0:
            self.charge_ah = min(spec.capacity_ah,
                                 max(0.0, self.charge_ah + self.current_a * dt_s / 3600.0))

    def reading(self) -> BatteryReading:
        """Return the battery as a BatteryState would report it now."""
        spec = self.spec
        percentage = self.charge_ah / spec.capacity_ah
        voltage = spec.voltage_empty_v + (spec.voltage_full_v - spec.voltage_empty_v) * percentage
        if self.on_dock:
            status = FULL if self.full else CHARGING
        else:
            status = DISCHARGING
        return BatteryReading(voltage, self.current_a, self.charge_ah, spec.capacity_ah,
                              percentage, status)
