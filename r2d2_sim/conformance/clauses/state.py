"""STATE: STOPPED, PLAYING, PAUSED and the transitions between them."""

from typing import List

from r2d2_sim.conformance.clause import Clause, clause, ClauseFailed
from r2d2_sim.conformance.target import Target

CLAUSES: List[Clause] = []

GET = 'SIMULATION_STATE_GETTING'
SET = 'SIMULATION_STATE_SETTING'
PAUSE = 'SIMULATION_STATE_PAUSE'
STEP = 'STEP_SIMULATION_SINGLE|STEP_SIMULATION_MULTIPLE|STEP_SIMULATION_ACTION'
PLAYING_QUOTE = 'STATE_PLAYING = 1 # Simulation is playing, can be either paused or stopped.'
PAUSED_QUOTE = ('STATE_PAUSED = 2 # Simulation is paused, can be either stopped (which will '
                'reset it) or played.')
ALREADY_QUOTE = ('ALREADY_IN_TARGET_STATE = 101 # Additional result type for this call, which '
                 'means simulation was already in the target state (e.g. was already stopped '
                 'when STATE_STOPPED was requested).')
# The steps run before STOPPED, and how many may run while the kit plays to pause after it.
RUN = 480
SLACK = RUN // 10
STOPPED_QUOTE = ('STATE_STOPPED = 0 # Simulation is stopped, which is equivalent to pausing and '
                 'resetting with ALL_PAUSED.')


@clause(CLAUSES, 'STATE-01', 'GetSimulationState gives one of the defined states', (GET,),
        'GetSimulationState.srv', 'Gets the simulation state (paused, playing, stopped)')
def defined_state(t: Target) -> None:
    """Read the state: one of SimulationState's six values."""
    value = t.sim.state()
    if value not in range(6):
        raise ClauseFailed(f'GetSimulationState gave {value}, no SimulationState constant')


def _transition(t: Target, start: str, target: int) -> None:
    """From STOPPED, go to ``start`` ('stopped', 'playing', 'paused'), then ask for ``target``."""
    S = t.sim.S
    if start == 'playing':
        t.sim.play()
    elif start == 'paused':
        t.sim.pause()
    else:
        t.sim.stop()
    t.ok('SetSimulationState', t.sim.state_request(target), f'from {start.upper()}, '
         f'SetSimulationState {t.sim.state_name(target)}')
    t.sim.expect_state(target,
                       f'SetSimulationState {t.sim.state_name(target)} from {start.upper()}')
    if target != S.STATE_STOPPED:
        t.undo.on_cleanup(t.sim.stop)


@clause(CLAUSES, 'STATE-02', 'STOPPED, once set, reads STOPPED', (SET, GET),
        'SimulationState.msg', STOPPED_QUOTE)
def stopped_reads_stopped(t: Target) -> None:
    """Every clause starts with SetSimulationState STOPPED: the state reads STOPPED."""
    t.sim.expect_state(t.sim.S.STATE_STOPPED, 'SetSimulationState STOPPED')


@clause(CLAUSES, 'STATE-03', 'STOPPED -> PLAYING', (SET, GET), 'SimulationState.msg',
        'Stopped simulation can be played.')
def stopped_to_playing(t: Target) -> None:
    """OK, and the state reads PLAYING."""
    _transition(t, 'stopped', t.sim.S.STATE_PLAYING)


@clause(CLAUSES, 'STATE-04', 'PLAYING -> PAUSED', (SET, PAUSE, GET), 'SimulationState.msg',
        PLAYING_QUOTE)
def playing_to_paused(t: Target) -> None:
    """OK, and the state reads PAUSED."""
    _transition(t, 'playing', t.sim.S.STATE_PAUSED)


@clause(CLAUSES, 'STATE-05', 'PLAYING -> STOPPED', (SET, GET), 'SimulationState.msg',
        PLAYING_QUOTE)
def playing_to_stopped(t: Target) -> None:
    """OK, and the state reads STOPPED."""
    _transition(t, 'playing', t.sim.S.STATE_STOPPED)


@clause(CLAUSES, 'STATE-06', 'PAUSED -> PLAYING', (SET, PAUSE, GET), 'SimulationState.msg',
        PAUSED_QUOTE)
def paused_to_playing(t: Target) -> None:
    """OK, and the state reads PLAYING."""
    _transition(t, 'paused', t.sim.S.STATE_PLAYING)


@clause(CLAUSES, 'STATE-07', 'PAUSED -> STOPPED', (SET, PAUSE, GET), 'SimulationState.msg',
        PAUSED_QUOTE)
def paused_to_stopped(t: Target) -> None:
    """OK, and the state reads STOPPED."""
    _transition(t, 'paused', t.sim.S.STATE_STOPPED)


def _twice(t: Target, state: int) -> None:
    already = t.srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    t.expect('SetSimulationState', t.sim.state_request(state), (already,),
             f'SetSimulationState {t.sim.state_name(state)} a second time')


@clause(CLAUSES, 'STATE-08', 'STOPPED when stopped is ALREADY_IN_TARGET_STATE', (SET,),
        'SetSimulationState.srv', ALREADY_QUOTE)
def stopped_twice(t: Target) -> None:
    """Ask for STOPPED in the start state, STOPPED: 101."""
    _twice(t, t.sim.S.STATE_STOPPED)


@clause(CLAUSES, 'STATE-09', 'PLAYING when playing is ALREADY_IN_TARGET_STATE', (SET,),
        'SetSimulationState.srv', ALREADY_QUOTE)
def playing_twice(t: Target) -> None:
    """Play, then ask for PLAYING again: 101."""
    t.sim.play()
    t.undo.on_cleanup(t.sim.stop)
    _twice(t, t.sim.S.STATE_PLAYING)


@clause(CLAUSES, 'STATE-10', 'PAUSED when paused is ALREADY_IN_TARGET_STATE', (SET, PAUSE),
        'SetSimulationState.srv', ALREADY_QUOTE)
def paused_twice(t: Target) -> None:
    """Pause, then ask for PAUSED again: 101."""
    t.sim.pause()
    t.undo.on_cleanup(t.sim.stop)
    _twice(t, t.sim.S.STATE_PAUSED)


@clause(CLAUSES, 'STATE-11', 'STOPPED -> PAUSED is INCORRECT_TRANSITION, or really pauses',
        (SET, PAUSE, GET), 'SetSimulationState.srv',
        'INCORRECT_TRANSITION = 103 # Incorrect transition (pausing when in stopped state). '
        '(SimulationState.msg: "It can also be paused, which means starting simulation in a '
        'paused state immediately")')
def stopped_to_paused(t: Target) -> None:
    """
    Pause a stopped simulation: 103 passes, and so does OK with PAUSED read after.

    OK while the state stays STOPPED (a silent no-op) fails, as does any other code.
    """
    S = t.sim.S
    incorrect = t.srv.SetSimulationState.Response.INCORRECT_TRANSITION
    reply = t.expect('SetSimulationState', t.sim.state_request(S.STATE_PAUSED),
                     (incorrect, t.msg.Result.RESULT_OK),
                     'from STOPPED, SetSimulationState PAUSED')
    if reply.result.result == t.msg.Result.RESULT_OK:
        t.undo.on_cleanup(t.sim.stop)
        t.sim.expect_state(S.STATE_PAUSED, 'an OK to PAUSED from STOPPED')
    else:
        t.sim.expect_state(S.STATE_STOPPED, 'INCORRECT_TRANSITION from STOPPED to PAUSED')


@clause(CLAUSES, 'STATE-12', 'an undefined state is refused and changes nothing', (SET, GET),
        'SetSimulationState.srv',
        'INCORRECT_TRANSITION = 103 # Incorrect transition (pausing when in stopped state).')
def undefined_state(t: Target) -> None:
    """
    State 200 is no state: any refusal but 0, and the state still reads STOPPED.

    The sentence names one incorrect transition (pausing a stopped
    simulation), so 103 is not required here: any refusal will do.
    """
    reply = t.call('SetSimulationState', t.sim.state_request(200))
    code = reply.result.result
    if code in (t.msg.Result.RESULT_OK, t.msg.Result.RESULT_FEATURE_UNSUPPORTED):
        raise ClauseFailed('SetSimulationState 200 answered '
                           f'{t.describe("SetSimulationState", reply)}')
    t.sim.expect_state(t.sim.S.STATE_STOPPED, 'SetSimulationState 200')


@clause(CLAUSES, 'STATE-13', 'STOPPED removes spawned entities', (SET, 'SPAWNING'),
        'SimulationState.msg', STOPPED_QUOTE, services=('GetEntities',))
def stopped_despawns(t: Target) -> None:
    """Spawn, play, stop: the spawned entity is gone (a reset with ALL de-spawns)."""
    name = t.entities.spawn(0)
    t.sim.play()
    t.sim.stop()
    if name in t.entities.names():
        raise ClauseFailed(f'{name} is still listed after STOPPED')


@clause(CLAUSES, 'STATE-14', 'STOPPED puts the time back to the start', (SET, PAUSE, STEP),
        'SimulationState.msg', STOPPED_QUOTE)
def stopped_resets_time(t: Target) -> None:
    """Paused, step 480; stop, pause, step once: /clock reads one step from 0."""
    t.clock.need()
    t.sim.pause()
    t.undo.on_cleanup(t.sim.stop)
    _, step_ns = t.clock.step_ns()
    t.clock.after(lambda: t.sim.advance(RUN), f'{RUN} steps')
    t.sim.stop()
    t.clock.expect_start(step_ns, 'STOPPED', SLACK, RUN)
