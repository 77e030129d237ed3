"""
What r2d2_sim's two simulations for scenario_execution share: the tick, the logger, reset.

scenario_execution calls ``reset(**parameters)`` with the scenario's
parameters that the class's ``reset`` names (it reads the signature), so
the one signature here, the names of :data:`~.parameters.DEFAULTS`, is what
both :class:`~.in_process.R2D2Simulation` (the core, no ROS) and
:class:`~.over_ros.StandardSimulation` (any simulator of the standard)
accept; each starts its run in :meth:`ScenarioSimulation.start`.
"""

from typing import Any, Dict, Optional

from scenario_execution.simulation import SimulationInterface

from r2d2_sim.errors import RefusedError, ScenarioError
from r2d2_sim.osc.parameters import DEFAULTS
from r2d2_sim.osc.port import STATES

__all__ = ['ScenarioSimulation', 'CONTROL_PERIOD_S', 'steps_per_period']

# One tick of the behaviour tree: 12 physics steps at 240 Hz (the farm's stopper's rate).
CONTROL_PERIOD_S = 0.05


def steps_per_period(rate_hz: float, which: str) -> int:
    """
    Return how many physics steps at ``rate_hz`` make one control period.

    ScenarioError (one line naming ``which`` rate) unless they are a whole
    number: the scenario's clock advances a control period a tick, and the
    simulated time must advance exactly as much.
    """
    steps = CONTROL_PERIOD_S * rate_hz
    whole = round(steps)
    if whole < 1 or abs(steps - whole) > 1e-6:
        raise ScenarioError(
            f'{which} {rate_hz:g} Hz: a control period of {CONTROL_PERIOD_S:g} s would be '
            f'{steps:g} physics steps, not a whole number; use a rate that is a multiple of '
            f'{1.0 / CONTROL_PERIOD_S:g} Hz (100, 200, 240, 500, 1000...)')
    return whole


class ScenarioSimulation(SimulationInterface):
    """A step-based simulation of scenario_execution whose runs start from DEFAULTS' names."""

    logger: Any = None
    # A mistake found at reset, one line: every action fails with it.
    error: Optional[str] = None
    # True while the scenario's ticks step the physics (set_simulation_state: playing).
    playing: bool = True

    @property
    def dt(self) -> float:
        """Return the control period (s): the tick of the behaviour tree, in simulated time."""
        return CONTROL_PERIOD_S

    def setup(self, **kwargs: Any) -> None:
        """Keep scenario_execution's logger; each run is made at its reset."""
        self.logger = kwargs.get('logger')

    def reset(self, world: str = DEFAULTS['world'], robot: str = DEFAULTS['robot'],
              start_x: float = DEFAULTS['start_x'], start_y: float = DEFAULTS['start_y'],
              start_yaw: float = DEFAULTS['start_yaw'],
              start_pose: str = DEFAULTS['start_pose'], goal_x: float = DEFAULTS['goal_x'],
              goal_y: float = DEFAULTS['goal_y'],
              goal_tolerance: float = DEFAULTS['goal_tolerance'],
              goal_pose: str = DEFAULTS['goal_pose'], obstacles: str = DEFAULTS['obstacles'],
              seed: int = DEFAULTS['seed'], scan_noise_std: float = DEFAULTS['scan_noise_std'],
              limits: str = DEFAULTS['limits'], parameters: str = DEFAULTS['parameters'],
              simulator_namespace: str = DEFAULTS['simulator_namespace']) -> None:
        """Start a run of the scenario's parameters (see :mod:`.parameters`)."""
        values = dict(locals())
        del values['self']
        self.start(values)

    def start(self, values: Dict[str, Any]) -> None:
        """Start a run of these parameters (every DEFAULTS name, each with its value)."""
        raise NotImplementedError

    def _fail(self, line: str) -> None:
        """Note a scenario author's mistake: one line, logged, and every action fails with it."""
        self.error = line
        if self.logger is not None:
            self.logger.error(f'r2d2_sim: {line}')

    def set_state(self, state: str) -> None:
        """'playing': step with the scenario; 'paused': hold; 'stopped': reset ALL and hold."""
        if state not in STATES:
            raise RefusedError('INCORRECT_TRANSITION', f'no state {state!r}: one of '
                                                       f'{", ".join(STATES)}')
        self._check_world()
        if state == 'stopped':
            self.reset_simulation()
        self.playing = state == 'playing'

    def _check_paused(self) -> None:
        """Refuse a StepSimulation while the scenario plays (the standard steps a paused one)."""
        self._check_world()
        if self.playing:
            raise RefusedError('OPERATION_FAILED', 'step_simulation steps a paused simulation: '
                                                   'set_simulation_state(paused) first')

    def _check_world(self) -> None:
        """Refuse (INCORRECT_STATE) when no world is loaded."""
        raise NotImplementedError

    def reset_simulation(self) -> None:
        """Reset the whole simulation (ResetSimulation ALL), as the standard's STOPPED does."""
        raise NotImplementedError
