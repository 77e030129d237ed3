"""
Driving the simulation under test: its state, stepping (by service or action), reset.

:class:`SimulationVerbs` is mixed into :class:`~r2d2_sim.conformance.target.Target`:
the verbs that change the simulation's state (SetSimulationState, with the
route to PAUSED that every simulator takes), step it (StepSimulation, or the
SimulateSteps action where only that is declared, with its feedback kept per
goal) and reset it. They call through the Target's typed calls (``ok``,
``expect``, ``call``, ``declared``) and read what its ``__init__`` sets.
"""

from typing import List, Optional, Tuple

from r2d2_sim.conformance.clause import ClauseFailed, ClauseSkipped
from r2d2_sim.conformance.discovery import ACTION


class SimulationVerbs:
    """The Target's verbs for the simulation's state, its steps and the SimulateSteps action."""

    # -- the simulation's state ---------------------------------------------------------

    @property
    def S(self):
        """Return SimulationState (its ``STATE_*`` constants)."""
        return self.msg.SimulationState

    def state_name(self, value: int) -> str:
        """Name a SimulationState value: PLAYING (1)."""
        for name in dir(self.S):
            if name.startswith('STATE_') and getattr(self.S, name) == value:
                return f'{name[6:]} ({value})'
        return f'undefined state {value}'

    def state(self) -> int:
        """Return the simulation state GetSimulationState gives."""
        return self.ok('GetSimulationState', self.srv.GetSimulationState.Request(),
                       'GetSimulationState').state.state

    def request_state(self, state: int):
        """Ask SetSimulationState for ``state``; return the reply, whatever its result."""
        request = self.srv.SetSimulationState.Request()
        request.state.state = state
        return self.call('SetSimulationState', request)

    def set_state(self, state: int) -> None:
        """Go to ``state``: OK or ALREADY_IN_TARGET_STATE, else ClauseFailed."""
        codes = (self.msg.Result.RESULT_OK,
                 self.srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE)
        request = self.srv.SetSimulationState.Request()
        request.state.state = state
        self.expect('SetSimulationState', request, codes,
                    f'SetSimulationState {self.state_name(state)}')

    def expect_state(self, state: int, after: str) -> None:
        """Raise ClauseFailed unless the state reads ``state`` (unchecked if not declared)."""
        if not self.declared('SIMULATION_STATE_GETTING'):
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
        if self.declared('SIMULATION_STATE_GETTING'):
            now = self.state()
            if now == S.STATE_PAUSED:
                return
            if now != S.STATE_PLAYING:
                self.play()
        else:
            self.play()
        self.set_state(S.STATE_PAUSED)

    def step(self, steps: int) -> None:
        """Step ``steps`` times through StepSimulation (OK expected)."""
        self.ok('StepSimulation', self.srv.StepSimulation.Request(steps=steps),
                f'StepSimulation of {steps}')

    def advance(self, steps: int) -> None:
        """Step a paused simulation: StepSimulation where declared, else the action."""
        single = steps == 1 and self.declared('STEP_SIMULATION_SINGLE')
        multiple = steps > 1 and self.declared('STEP_SIMULATION_MULTIPLE')
        if (single or multiple) and 'StepSimulation' in self.interfaces:
            return self.step(steps)
        if self.declared('STEP_SIMULATION_ACTION'):
            status, result = self.run_goal(steps)
            if result.result.result != self.msg.Result.RESULT_OK:
                raise ClauseFailed(f'SimulateSteps of {steps}: {self.describe(None, result)}')
            return None
        raise ClauseSkipped('the simulator declares no way to step this many steps')

    def reset(self, scope: int) -> None:
        """Reset with ``scope`` (OK expected)."""
        self.ok('ResetSimulation', self.srv.ResetSimulation.Request(scope=scope),
                f'ResetSimulation scope {scope}')

    # -- the action --------------------------------------------------------------------

    def action_client(self):
        """Return a ready client of the SimulateSteps action, with feedback kept."""
        from rclpy.action import ActionClient
        if self._action_client is None:
            name = self.interfaces.get(ACTION)
            if name is None:
                raise ClauseFailed(f'no SimulateSteps action under {self.prefix!r}')
            self._action_client = ActionClient(self.node, self.action.SimulateSteps, name)
            feedback = self.action.SimulateSteps.Impl.FeedbackMessage
            self._feedback_subscription = self.node.create_subscription(
                feedback, f'{name}/_action/feedback', self._keep_feedback, 1000)
        client = self._action_client
        if not self.probe.spin_until(
                lambda: client.server_is_ready()
                and self._feedback_subscription.get_publisher_count() > 0, self.timeout_s):
            raise ClauseFailed(f'the SimulateSteps action was not ready within '
                               f'{self.timeout_s:g} s')
        return client

    def _keep_feedback(self, message) -> None:
        self._feedback.append((bytes(message.goal_id.uuid), message.feedback.completed_steps,
                               message.feedback.remaining_steps))

    def feedback_of(self, handle) -> List[Tuple[int, int]]:
        """Return the (completed, remaining) feedback seen for a goal, in order."""
        uuid = bytes(handle.goal_id.uuid)
        return [(done, left) for goal, done, left in self._feedback if goal == uuid]

    def send_goal(self, steps: int):
        """Send a SimulateSteps goal; return its handle (``accepted`` says whether it was)."""
        client = self.action_client()
        sent = client.send_goal_async(self.action.SimulateSteps.Goal(steps=steps))
        if not self.probe.spin_until(sent.done, self.timeout_s):
            raise ClauseFailed('a SimulateSteps goal was not answered within '
                               f'{self.timeout_s:g} s')
        return sent.result()

    def goal_result(self, handle, timeout_s: Optional[float] = None):
        """Wait for a goal's end; return (status, SimulateSteps.Result)."""
        future = handle.get_result_async()
        timeout = timeout_s or self.timeout_s
        if not self.probe.spin_until(future.done, timeout):
            raise ClauseFailed(f'a SimulateSteps goal did not end within {timeout:g} s')
        return future.result().status, future.result().result

    def run_goal(self, steps: int):
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
