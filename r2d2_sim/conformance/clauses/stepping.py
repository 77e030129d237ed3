"""STEP: StepSimulation, counted against /clock; ACTION: SimulateSteps, its feedback, cancel."""

from typing import List, Optional

from r2d2_sim.conformance.clause import Clause, clause, ClauseFailed
from r2d2_sim.conformance.target import Target

CLAUSES: List[Clause] = []

SET, PAUSE, GET = ('SIMULATION_STATE_SETTING', 'SIMULATION_STATE_PAUSE',
                   'SIMULATION_STATE_GETTING')
SINGLE, MULTIPLE, ACTION = ('STEP_SIMULATION_SINGLE', 'STEP_SIMULATION_MULTIPLE',
                            'STEP_SIMULATION_ACTION')
EITHER = f'{SINGLE}|{MULTIPLE}'
PAUSED_STEPS = ('Assuming the simulation is paused, simulate a finite number of steps and return '
                'to paused state.')
NOT_PAUSED = ('Result result # Calling with simulation not paused will return '
              'RESULT_OPERATION_FAILED and error message.')
LOOP = 'uint64 steps 1 # Step through the simulation loop this many times.'
SERVICE = ('StepSimulation',)


def _some_steps(t: Target) -> int:
    return 1 if t.declared(SINGLE) else 2


@clause(CLAUSES, 'STEP-01', 'one step of a paused simulation answers OK', (SINGLE, SET, PAUSE),
        'StepSimulation.srv', PAUSED_STEPS)
def one_step(t: Target) -> None:
    """Pause, step 1: OK."""
    t.sim.pause()
    t.sim.step(1)


@clause(CLAUSES, 'STEP-02', 'several steps of a paused simulation answer OK',
        (MULTIPLE, SET, PAUSE), 'StepSimulation.srv', PAUSED_STEPS, services=SERVICE)
def several_steps(t: Target) -> None:
    """Pause, step 5: OK."""
    t.sim.pause()
    t.sim.step(5)


@clause(CLAUSES, 'STEP-03', 'after stepping the simulation is still PAUSED',
        (EITHER, SET, PAUSE, GET), 'StepSimulation.srv', PAUSED_STEPS, services=SERVICE)
def paused_after_steps(t: Target) -> None:
    """Pause, step: the state reads PAUSED."""
    t.sim.pause()
    t.sim.step(_some_steps(t))
    t.sim.expect_state(t.sim.S.STATE_PAUSED, 'StepSimulation')


@clause(CLAUSES, 'STEP-04', 'stepping while PLAYING is OPERATION_FAILED with a message',
        (EITHER, SET), 'StepSimulation.srv', NOT_PAUSED, services=SERVICE)
def step_while_playing(t: Target) -> None:
    """Play, step: OPERATION_FAILED (not OK, not INCORRECT_STATE) and an error_message."""
    t.sim.play()
    t.undo.on_cleanup(t.sim.stop)
    reply = t.expect('StepSimulation', t.srv.StepSimulation.Request(steps=_some_steps(t)),
                     (t.msg.Result.RESULT_OPERATION_FAILED,), 'StepSimulation while PLAYING')
    if not reply.result.error_message.strip():
        raise ClauseFailed('StepSimulation while PLAYING gave OPERATION_FAILED without an '
                           'error_message')


@clause(CLAUSES, 'STEP-05', 'a step refused while PLAYING leaves it PLAYING', (EITHER, SET, GET),
        'StepSimulation.srv', NOT_PAUSED, services=SERVICE)
def refused_step_keeps_playing(t: Target) -> None:
    """Play, step (refused): the state still reads PLAYING, not PAUSED."""
    t.sim.play()
    t.undo.on_cleanup(t.sim.stop)
    t.call('StepSimulation', t.srv.StepSimulation.Request(steps=_some_steps(t)))
    t.sim.expect_state(t.sim.S.STATE_PLAYING, 'a StepSimulation while PLAYING')


@clause(CLAUSES, 'STEP-06', 'each single step advances /clock by the same step',
        (SINGLE, SET, PAUSE), 'StepSimulation.srv', LOOP)
def single_steps_on_clock(t: Target) -> None:
    """Paused: single steps move /clock forward, each by the same length."""
    t.clock.need()
    t.sim.pause()
    now, step_ns = t.clock.step_ns()
    if step_ns <= 0:
        raise ClauseFailed(f'one step moved the clock by {step_ns} ns')
    t.sim.step(1)
    t.clock.expect(now + step_ns, 1, 'one more step', step_ns)


@clause(CLAUSES, 'STEP-07', 'N steps advance /clock by N steps', (MULTIPLE, SET, PAUSE),
        'StepSimulation.srv', LOOP, services=SERVICE)
def many_steps_on_clock(t: Target) -> None:
    """Paused: StepSimulation(10) moves /clock by ten single steps, exactly."""
    t.clock.need()
    t.sim.pause()
    now, step_ns = t.clock.step_ns()
    t.sim.step(10)
    t.clock.expect(now + 10 * step_ns, 10, 'StepSimulation of 10', step_ns)


# -- ACTION -----------------------------------------------------------------------------

ACTION_PAUSED = ('Assuming the simulation is paused, simulate a finite number of steps and '
                 'return to paused state.')


@clause(CLAUSES, 'ACTION-01', 'a SimulateSteps goal of a paused simulation succeeds with OK',
        (ACTION, SET, PAUSE), 'SimulateSteps.action', ACTION_PAUSED)
def goal_succeeds(t: Target) -> None:
    """Pause, a goal of 5: SUCCEEDED with RESULT_OK."""
    t.sim.pause()
    status, result = t.sim.run_goal(5)
    succeeded = status == t.sim.GoalStatus.STATUS_SUCCEEDED
    if not succeeded or result.result.result != t.msg.Result.RESULT_OK:
        raise ClauseFailed(f'a goal of 5 ended {t.sim.status_name(status)} with '
                           f'{t.describe(None, result)}')


@clause(CLAUSES, 'ACTION-02', 'feedback comes after each step, counting up to (N, 0)',
        (ACTION, SET, PAUSE), 'SimulateSteps.action',
        'The action returns feedback after each complete step.')
def feedback_counts(t: Target) -> None:
    """
    Send a goal of 20: several feedback messages, the last (20, 0), each adding up to 20.

    After each complete step means one message a step: not every one need
    arrive (feedback is a topic whose history the server keeps short), but
    more than one must, completed_steps rising, completed + remaining = 20,
    and the last one after the last step, (20, 0).
    """
    t.sim.pause()
    steps = 20
    handle = t.sim.send_goal(steps)
    if not handle.accepted:
        raise ClauseFailed('a goal of 20 steps of a paused simulation was rejected')
    # The last feedback first: rclpy drops a goal's feedback once its result is in, and
    # the result is asked for (goal_result) only then.
    t.wait(lambda: (steps, 0) in t.sim.feedback_of(handle))
    t.sim.goal_result(handle)
    seen = t.sim.feedback_of(handle)
    if len(seen) < 2:
        raise ClauseFailed(f'a goal of 20 steps gave {len(seen)} feedback message(s) '
                           f'{seen[:1]}: one after each complete step makes 20')
    done = [d for d, _ in seen]
    bad = [(d, r) for d, r in seen if d + r != steps or not 1 <= d <= steps]
    if bad:
        raise ClauseFailed(f'feedback (completed, remaining) {bad[:3]} for a goal of {steps}')
    if done != sorted(set(done)):
        raise ClauseFailed(f'completed_steps did not rise step by step: {done[:10]}')
    if seen[-1] != (steps, 0):
        raise ClauseFailed(f'the last feedback of a goal of {steps} was {seen[-1]}, not '
                           f'({steps}, 0) after the last step')


@clause(CLAUSES, 'ACTION-03', 'a goal while PLAYING ends with OPERATION_FAILED and a message',
        (ACTION, SET), 'SimulateSteps.action',
        'Result result # Calling with simulation unpaused will return OPERATION_FAILED and '
        'error message.')
def goal_while_playing(t: Target) -> None:
    """Play, a goal: its Result is OPERATION_FAILED (a rejected goal has no Result)."""
    t.sim.play()
    t.undo.on_cleanup(t.sim.stop)
    handle = t.sim.send_goal(5)
    if not handle.accepted:
        raise ClauseFailed('the goal was rejected: a rejected goal carries no Result, the '
                           'standard wants OPERATION_FAILED in it')
    status, result = t.sim.goal_result(handle)
    if result.result.result != t.msg.Result.RESULT_OPERATION_FAILED:
        raise ClauseFailed(f'a goal while PLAYING ended {t.sim.status_name(status)} with '
                           f'{t.describe(None, result)}, not OPERATION_FAILED')
    if not result.result.error_message.strip():
        raise ClauseFailed('OPERATION_FAILED without an error_message')


@clause(CLAUSES, 'ACTION-04', 'a goal whose cancel is accepted ends CANCELED',
        (ACTION, SET, PAUSE), 'SimulateSteps.action',
        'uint64 remaining_steps # number of steps remaining to be completed in this action.')
def goal_cancelled(t: Target) -> Optional[str]:
    """
    Pause, a goal of 100,000 steps, cancel at once: if the cancel is accepted, status CANCELED.

    SimulateSteps.action says nothing of cancelling, and a ROS 2 action
    server may reject a cancel: a rejected one passes, with a note, and the
    kit stops the simulation (a reset with ALL) to end the goal.
    """
    t.sim.pause()
    handle = t.sim.send_goal(100_000)
    if not handle.accepted:
        raise ClauseFailed('a goal of 100000 steps of a paused simulation was rejected')
    cancel = handle.cancel_goal_async()
    if not t.wait(cancel.done):
        raise ClauseFailed(f'the cancel request was not answered within {t.timeout_s:g} s')
    if not cancel.result().goals_canceling:
        t.sim.stop()
        try:
            status, _ = t.sim.goal_result(handle)
            ended = f'; STOPPED ended the goal {t.sim.status_name(status)}'
        except ClauseFailed:
            ended = '; the goal still ran after STOPPED'
        return ('note: the cancel was rejected, as an action server may (SimulateSteps.action '
                f'says nothing of cancelling): not checked further{ended}')
    status, _ = t.sim.goal_result(handle)
    if status != t.sim.GoalStatus.STATUS_CANCELED:
        raise ClauseFailed(f'the goal whose cancel was accepted ended {t.sim.status_name(status)}')
    return None


@clause(CLAUSES, 'ACTION-05', 'after a goal the simulation is still PAUSED',
        (ACTION, SET, PAUSE, GET), 'SimulateSteps.action', ACTION_PAUSED)
def paused_after_goal(t: Target) -> None:
    """Pause, a goal of 5: the state reads PAUSED."""
    t.sim.pause()
    t.sim.run_goal(5)
    t.sim.expect_state(t.sim.S.STATE_PAUSED, 'a SimulateSteps goal')


@clause(CLAUSES, 'ACTION-06', 'a goal of N steps advances /clock by N steps',
        (ACTION, SET, PAUSE), 'SimulateSteps.action',
        'uint64 steps # Action goal: step through the simulation loop this many times.')
def goal_on_clock(t: Target) -> None:
    """Paused: a goal of 10 moves /clock by ten single steps, exactly."""
    t.clock.need()
    t.sim.pause()
    now, step_ns = t.clock.step_ns()
    t.sim.run_goal(10)
    t.clock.expect(now + 10 * step_ns, 10, 'a SimulateSteps goal of 10', step_ns)
