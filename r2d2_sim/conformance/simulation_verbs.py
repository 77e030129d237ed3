"""
Driving the simulation under test: its state, stepping (by service or action), reset.

:class:`TargetSimulation` is a part of :class:`~r2d2_sim.conformance.target.Target`
(``t.sim``): changing the simulation's state (SetSimulationState, with the
route to PAUSED that every simulator takes), stepping it (StepSimulation, or
the SimulateSteps action where only that is declared) and resetting it. It
owns the action's feedback, kept per goal; the calls go through the
Target's (``ok``, ``expect``, ``call``) and its client's action.
"""

from typing import Any, List, Optional, Tuple, TYPE_CHECKING

from r2d2_sim.conformance.calls import TargetCalls
from r2d2_sim.conformance.clause import ClauseFailed, ClauseSkipped

if TYPE_CHECKING:
    from rclpy.action.client import ClientGoalHandle


class TargetSimulation:
    """The simulation's state, its steps and the SimulateSteps action, on ``target``."""

    def __init__(self, target: TargetCalls) -> None:
        from action_msgs.msg import GoalStatus
        self.target = target
        self.GoalStatus = GoalStatus
        self._feedback: List[Tuple[bytes, int, int]] = []  # (goal id, completed, remaining)

    # -- the simulation's state ---------------------------------------------------------

    @property
    def S(self) -> Any:
        """Return SimulationState (its ``STATE_*`` constants)."""
        return self.target.msg.SimulationState

    def state_name(self, value: int) -> str:
        """Name a SimulationState value: PLAYING (1)."""
        for name in dir(self.S):
            if name.startswith('STATE_') and getattr(self.S, name) == value:
                return f'{name[6:]} ({value})'
        return f'undefined state {value}'

    def state(self) -> int:
        """Return the simulation state GetSimulationState gives."""
        t = self.target
        return t.ok('GetSimulationState', t.srv.GetSimulationState.Request(),
                    'GetSimulationState').state.state

    def state_request(self, state: int) -> Any:
        """Return a SetSimulationState request for ``state``."""
        return self.target.client.state_request(state)

    def request_state(self, state: int) -> Any:
        """Ask SetSimulationState for ``state``; return the reply, whatever its result."""
        return self.target.call('SetSimulationState', self.state_request(state))

    def set_state(self, state: int) -> None:
        """Go to ``state``: OK or ALREADY_IN_TARGET_STATE, else ClauseFailed."""
        t = self.target
        codes = (t.msg.Result.RESULT_OK, t.srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE)
        t.expect('SetSimulationState', self.state_request(state), codes,
                 f'SetSimulationState {self.state_name(state)}')

    def expect_state(self, state: int, after: str) -> None:
        """Raise ClauseFailed unless the state reads ``state`` (unchecked if not declared)."""
        if not self.target.declared('SIMULATION_STATE_GETTING'):
            return
        now = self.state()
        if now != state:
            raise ClauseFailed(f'after {after} the state reads {self.state_name(now)}, '
                               f'not {self.state_name(state)}')

    def stop(self) -> None:
        """Go to STOPPED."""
        self.set_state(self.S.STATE_STOPPED)

    def play(self) -> None:
        """Go to PLAYING."""
        self.set_state(self.S.STATE_PLAYING)

    def pause(self) -> None:
        """
        Go to PAUSED by a route every simulator takes: from STOPPED through PLAYING.

        The standard disagrees with itself on pausing a stopped simulation
        (SimulationState.msg allows it, SetSimulationState.srv calls it an
        incorrect transition), so the kit plays first.
        """
        S = self.S
        if self.target.declared('SIMULATION_STATE_GETTING'):
            now = self.state()
            if now == S.STATE_PAUSED:
                return
            if now != S.STATE_PLAYING:
                self.play()
        else:
            self.play()
        self.set_state(S.STATE_PAUSED)

    # -- steps and resets ---------------------------------------------------------------

    def step(self, steps: int) -> None:
        """Step ``steps`` times through StepSimulation (OK expected)."""
        t = self.target
        t.ok('StepSimulation', t.srv.StepSimulation.Request(steps=steps),
             f'StepSimulation of {steps}')

    def advance(self, steps: int) -> None:
        """Step a paused simulation: StepSimulation where declared, else the action."""
        t = self.target
        single = steps == 1 and t.declared('STEP_SIMULATION_SINGLE')
        multiple = steps > 1 and t.declared('STEP_SIMULATION_MULTIPLE')
        if (single or multiple) and 'StepSimulation' in t.interfaces:
            self.step(steps)
            return
        if t.declared('STEP_SIMULATION_ACTION'):
            _, result = self.run_goal(steps)
            if result.result.result != t.msg.Result.RESULT_OK:
                raise ClauseFailed(f'SimulateSteps of {steps}: {t.describe(None, result)}')
            return
        raise ClauseSkipped('the simulator declares no way to step this many steps')

    def reset(self, scope: int) -> None:
        """Reset with ``scope`` (OK expected)."""
        t = self.target
        t.ok('ResetSimulation', t.srv.ResetSimulation.Request(scope=scope),
             f'ResetSimulation scope {scope}')

    # -- the action --------------------------------------------------------------------

    def _keep_feedback(self, message: Any) -> None:
        self._feedback.append((bytes(message.goal_id.uuid), message.feedback.completed_steps,
                               message.feedback.remaining_steps))

    def forget_feedback(self) -> None:
        """Forget the feedback of earlier goals (a new clause begins)."""
        self._feedback.clear()

    def feedback_of(self, handle: 'ClientGoalHandle') -> List[Tuple[int, int]]:
        """Return the (completed, remaining) feedback seen for a goal, in order."""
        uuid = bytes(handle.goal_id.uuid)
        return [(done, left) for goal, done, left in self._feedback if goal == uuid]

    def send_goal(self, steps: int) -> 'ClientGoalHandle':
        """Send a SimulateSteps goal; return its handle (``accepted`` says whether it was)."""
        from r2d2_sim.testing.standard import StandardError
        try:
            return self.target.client.send_goal(steps, self._keep_feedback)
        except StandardError as exc:
            raise ClauseFailed(exc.message) from None

    def goal_result(self, handle: 'ClientGoalHandle', timeout_s: Optional[float] = None
                    ) -> Tuple[int, Any]:
        """Wait for a goal's end; return (status, SimulateSteps.Result)."""
        from r2d2_sim.testing.standard import StandardError
        try:
            return self.target.client.goal_result(handle, timeout_s)
        except StandardError as exc:
            raise ClauseFailed(exc.message) from None

    def run_goal(self, steps: int) -> Tuple[int, Any]:
        """Run a SimulateSteps goal to its end; return (status, result); a refusal fails."""
        handle = self.send_goal(steps)
        if not handle.accepted:
            raise ClauseFailed(f'a SimulateSteps goal of {steps} was rejected (a rejected goal '
                               'carries no Result)')
        return self.goal_result(handle)

    def status_name(self, status: int) -> str:
        """Name a GoalStatus value: CANCELED (5)."""
        for name in dir(self.GoalStatus):
            if name.startswith('STATUS_') and getattr(self.GoalStatus, name) == status:
                return f'{name[7:]} ({status})'
        return f'status {status}'
