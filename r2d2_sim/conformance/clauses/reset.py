"""RESET: ResetSimulation's scopes, a bit field (TIME, STATE, SPAWNED; DEFAULT = ALL)."""

from typing import List, Tuple

from r2d2_sim.conformance.clause import Clause, clause, ClauseFailed
from r2d2_sim.conformance.entity_verbs import Point
from r2d2_sim.conformance.target import Target
from r2d2_sim.conformance.values import close, fmt, vector

CLAUSES: List[Clause] = []

RESET = 'SIMULATION_RESET'
TIME, STATE, SPAWNED = ('SIMULATION_RESET_TIME', 'SIMULATION_RESET_STATE',
                        'SIMULATION_RESET_SPAWNED')
SET, PAUSE = 'SIMULATION_STATE_SETTING', 'SIMULATION_STATE_PAUSE'
STEP = 'STEP_SIMULATION_SINGLE|STEP_SIMULATION_MULTIPLE|STEP_SIMULATION_ACTION'
MOVE = ('SPAWNING', 'ENTITY_STATE_SETTING', 'ENTITY_STATE_GETTING', SET, PAUSE)
# The clauses that ask whether an entity is there list them: GetEntities, which no feature
# stands for, must be served.
LISTED = ('GetEntities',)
DEFAULT_QUOTE = 'SCOPE_DEFAULT = 0 # same as SCOPE_ALL.'
DESPAWN_QUOTE = 'Objects that were dynamically spawned are de-spawned.'
BITS = ('uint8 scope # ... This is a bit field which may be checked for each scope e.g. '
        'scope & SCOPE_TIME.')
STATE_QUOTE = 'SCOPE_STATE = 2 # Reset state such as poses and velocities.'
SPAWNED_QUOTE = 'SCOPE_SPAWNED = 4 # De-spawns all spawned entities.'
# The steps run before a reset of the time, and how many of them may run while the kit
# plays to pause afterwards (from STOPPED): back at the start is back within a tenth.
RUN = 480
SLACK = RUN // 10


def _scope(t: Target, name: str) -> int:
    return getattr(t.srv.ResetSimulation.Request, f'SCOPE_{name}')


def _despawns(t: Target, scope: int) -> None:
    name = t.entities.spawn(0)
    t.sim.reset(scope)
    if name in t.entities.names():
        raise ClauseFailed(f'{name} is still listed after ResetSimulation scope {scope}')


def _time_back(t: Target, scope: int) -> None:
    """Paused, RUN steps on, reset with ``scope``, one step: one step from the start (0)."""
    t.clock.need()
    t.sim.pause()
    t.undo.on_cleanup(t.sim.stop)
    _, step_ns = t.clock.step_ns()
    t.clock.after(lambda: t.sim.advance(RUN), f'{RUN} steps')
    t.sim.reset(scope)
    t.clock.expect_start(step_ns, f'ResetSimulation scope {scope}', SLACK, RUN)


def _moved(t: Target, linear: Point = (0.0, 0.0, 0.0)
           ) -> Tuple[str, Tuple[float, float, float], Tuple[float, float, float]]:
    """Pause, spawn at slot 0, move 1 m along y (with ``linear``); return (name, start, moved)."""
    t.sim.pause()
    t.undo.on_cleanup(t.sim.stop)
    name = t.entities.spawn(0)
    start = t.entities.slot(0)
    moved = (start[0], start[1] + 1.0, start[2])
    t.entities.place(name, moved, linear=linear)
    return name, start, moved


@clause(CLAUSES, 'RESET-01', 'SCOPE_DEFAULT answers OK', (RESET,), 'ResetSimulation.srv',
        DEFAULT_QUOTE)
def default_ok(t: Target) -> None:
    """Reset with scope 0: OK."""
    t.sim.reset(0)


@clause(CLAUSES, 'RESET-02', 'SCOPE_DEFAULT removes spawned entities', (RESET, 'SPAWNING'),
        'ResetSimulation.srv', DESPAWN_QUOTE, services=LISTED)
def default_despawns(t: Target) -> None:
    """Spawn, reset with 0: gone."""
    _despawns(t, 0)


@clause(CLAUSES, 'RESET-03', 'SCOPE_ALL removes spawned entities', (RESET, 'SPAWNING'),
        'ResetSimulation.srv', 'SCOPE_ALL = 255 # Fully resets simulation to the start, as if it '
        'was closed and launched again.', services=LISTED)
def all_despawns(t: Target) -> None:
    """Spawn, reset with 255: gone."""
    _despawns(t, _scope(t, 'ALL'))


@clause(CLAUSES, 'RESET-04', 'SCOPE_DEFAULT puts the time back to the start',
        (RESET, SET, PAUSE, STEP), 'ResetSimulation.srv',
        'Reset the simulation to the start, including the entire scene and the simulation time.')
def default_resets_time(t: Target) -> None:
    """Paused, 480 steps, reset with 0, one step: /clock reads one step from 0."""
    _time_back(t, 0)


@clause(CLAUSES, 'RESET-05', 'SCOPE_TIME puts the time back to the start',
        (TIME, SET, PAUSE, STEP), 'ResetSimulation.srv',
        'SCOPE_TIME = 1 # Reset simulation time to start.')
def time_resets_time(t: Target) -> None:
    """Paused, 480 steps, reset with TIME, one step: /clock reads one step from 0."""
    _time_back(t, _scope(t, 'TIME'))


@clause(CLAUSES, 'RESET-06', 'SCOPE_TIME leaves entities where they are', (TIME,) + MOVE,
        'ResetSimulation.srv', BITS, services=LISTED)
def time_keeps_entities(t: Target) -> None:
    """Reset TIME: a spawned, moved entity is still listed, still where it was moved."""
    name, _, moved = _moved(t)
    t.sim.reset(_scope(t, 'TIME'))
    if name not in t.entities.names():
        raise ClauseFailed(f'{name} is gone after ResetSimulation SCOPE_TIME')
    position = t.entities.position(name)
    if not close(position, moved):
        raise ClauseFailed(f'{name} is at {fmt(position)} after SCOPE_TIME, moved to {fmt(moved)}')


@clause(CLAUSES, 'RESET-07', 'SCOPE_STATE puts a moved entity back where it started',
        (STATE,) + MOVE, 'ResetSimulation.srv', STATE_QUOTE)
def state_puts_back(t: Target) -> None:
    """
    Move a spawned entity 1 m, reset STATE: it is at its spawn pose again.

    ResetSimulation.srv lets SCOPE_STATE include "state randomization if
    such feature is available and turned on": a simulator that randomizes
    fails here while it is on, and the reason says so.
    """
    name, start, _ = _moved(t)
    t.sim.reset(_scope(t, 'STATE'))
    position = t.entities.position(name)
    if not close(position, start):
        raise ClauseFailed(f'{name} is at {fmt(position)} after SCOPE_STATE, spawned at '
                           f'{fmt(start)} (where the simulator randomizes the state on a reset, '
                           'as SCOPE_STATE allows, turn that off for this clause)')


@clause(CLAUSES, 'RESET-08', 'SCOPE_STATE stops what moves', (STATE,) + MOVE,
        'ResetSimulation.srv', STATE_QUOTE)
def state_stops(t: Target) -> None:
    """Give a spawned entity 1 m/s, reset STATE: its twist is zero."""
    name, _, _ = _moved(t, linear=(1.0, 0.0, 0.0))
    t.sim.reset(_scope(t, 'STATE'))
    twist = t.entities.state(name).twist
    speeds = vector(twist.linear) + vector(twist.angular)
    if not close(speeds, (0.0,) * 6):
        raise ClauseFailed(f'{name} moves at {fmt(speeds)} (linear, angular) after SCOPE_STATE')


@clause(CLAUSES, 'RESET-09', 'SCOPE_STATE keeps spawned entities', (STATE, 'SPAWNING'),
        'ResetSimulation.srv', BITS, services=LISTED)
def state_keeps_spawned(t: Target) -> None:
    """Spawn, reset with STATE: still listed (RobotecAI's example then moves its cubes)."""
    name = t.entities.spawn(0)
    t.sim.reset(_scope(t, 'STATE'))
    if name not in t.entities.names():
        raise ClauseFailed(f'{name} is gone after ResetSimulation SCOPE_STATE')


@clause(CLAUSES, 'RESET-10', 'SCOPE_STATE leaves the time going on', (STATE, SET, PAUSE, STEP),
        'ResetSimulation.srv', BITS)
def state_keeps_time(t: Target) -> None:
    """Paused at T, reset with STATE, one step: /clock reads T plus a step, not less."""
    t.clock.need()
    t.sim.pause()
    t.undo.on_cleanup(t.sim.stop)
    now, step_ns = t.clock.step_ns()
    t.sim.reset(_scope(t, 'STATE'))
    t.sim.pause()
    after = t.clock.after(lambda: t.sim.advance(1), 'SCOPE_STATE and one step')
    if after < now + step_ns - 1:
        raise ClauseFailed(f'SCOPE_STATE took the clock back: {now} ns before, {after} ns after '
                           'one more step')


@clause(CLAUSES, 'RESET-11', 'SCOPE_SPAWNED removes spawned entities', (SPAWNED, 'SPAWNING'),
        'ResetSimulation.srv', SPAWNED_QUOTE, services=LISTED)
def spawned_despawns(t: Target) -> None:
    """Spawn, reset with SPAWNED: gone."""
    _despawns(t, _scope(t, 'SPAWNED'))


@clause(CLAUSES, 'RESET-12', 'SCOPE_SPAWNED leaves the other entities', (SPAWNED, 'SPAWNING'),
        'ResetSimulation.srv', SPAWNED_QUOTE, services=LISTED)
def spawned_keeps_others(t: Target) -> None:
    """Spawn, reset SPAWNED: the entities there before are all still listed."""
    before = set(t.entities.names())
    t.entities.spawn(0)
    t.sim.reset(_scope(t, 'SPAWNED'))
    lost = sorted(before - set(t.entities.names()))
    if lost:
        raise ClauseFailed(f'SCOPE_SPAWNED removed entities nobody spawned: {lost[:5]}')


@clause(CLAUSES, 'RESET-13', 'TIME | STATE (3) does both', (TIME, STATE, STEP) + MOVE,
        'ResetSimulation.srv', BITS)
def time_and_state(t: Target) -> None:
    """Spawn, step 480, move; reset with 3: back at its spawn pose, one step reads one from 0."""
    t.clock.need()
    name, start, moved = _moved(t)
    _, step_ns = t.clock.step_ns()
    t.clock.after(lambda: t.sim.advance(RUN), f'{RUN} steps')
    t.entities.place(name, moved)
    t.sim.reset(_scope(t, 'TIME') | _scope(t, 'STATE'))
    position = t.entities.position(name)
    if not close(position, start):
        raise ClauseFailed(f'{name} is at {fmt(position)} after scope 3, spawned at {fmt(start)}')
    t.clock.expect_start(step_ns, 'ResetSimulation scope 3', SLACK, RUN)
