"""
Before and after each clause: the start state, the undo list, the simulator left as found.

:class:`TargetUndo` is a part of :class:`~r2d2_sim.conformance.target.Target`
(``t.undo``): ``prepare`` puts the simulator in STOPPED before a clause,
``cleanup`` runs what the clause registered and deletes what it spawned,
and ``restore`` leaves the simulator as the kit found it (its world, its
state). It owns the undo list and the state found at the start, and is
given the parts whose changes it undoes.
"""

from typing import Callable, List, Optional, TYPE_CHECKING

from r2d2_sim.conformance.calls import TargetCalls
from r2d2_sim.conformance.clause import ClauseFailed, ClauseSkipped

if TYPE_CHECKING:
    from r2d2_sim.conformance.entity_verbs import TargetEntities
    from r2d2_sim.conformance.simulation_verbs import TargetSimulation
    from r2d2_sim.conformance.world_verbs import TargetWorld


class TargetUndo:
    """What a clause changed on ``target``, and its undoing; the simulator's state at the start."""

    def __init__(self, target: TargetCalls, sim: 'TargetSimulation', entities: 'TargetEntities',
                 world: 'TargetWorld') -> None:
        self.target = target
        self.sim, self.entities, self.world = sim, entities, world
        self.initial_state: Optional[int] = None  # the state when the kit connected
        self._cleanups: List[Callable[[], None]] = []

    def remember(self) -> None:
        """Read the simulation state now (where GetSimulationState is declared and served)."""
        t = self.target
        if not (t.declared('SIMULATION_STATE_GETTING') and 'GetSimulationState' in t.interfaces):
            return
        reply = t.call('GetSimulationState', t.srv.GetSimulationState.Request(), check=False)
        if reply is not None and reply.result.result == t.msg.Result.RESULT_OK:
            self.initial_state = reply.state.state

    def on_cleanup(self, undo: Callable[[], None]) -> None:
        """Run ``undo`` after the clause, pass or fail (last registered first)."""
        self._cleanups.append(undo)

    def prepare(self, stop: bool = True) -> None:
        """
        Forget the last clause; with ``stop``, put the simulator in the start state: STOPPED.

        Through SetSimulationState where declared (STOPPED is "pausing and
        resetting with ALL"), else a full ResetSimulation where that is.
        """
        self._cleanups.clear()
        self.entities.spawned.clear()
        self.sim.forget_feedback()
        if not stop:
            return
        if self.target.declared('SIMULATION_STATE_SETTING'):
            self.sim.stop()
        elif self.target.declared('SIMULATION_RESET'):
            self.sim.reset(0)

    def cleanup(self) -> List[str]:
        """Undo what the clause did; return what could not be undone (one line each)."""
        problems = []
        while self._cleanups:
            try:
                self._cleanups.pop()()
            except (ClauseFailed, ClauseSkipped) as exc:
                problems.append(str(exc))
        spawned = self.entities.spawned
        if spawned and self.target.declared('DELETING'):
            # By name: one the clause (or a reset) removed already answers NOT_FOUND.
            for name in list(spawned):
                try:
                    self.entities.delete(name, missing_ok=True)
                except ClauseFailed as exc:
                    problems.append(str(exc))
        spawned.clear()
        return problems

    def restore(self) -> List[str]:
        """
        Leave the simulator as found: the world loaded again, the state it was in.

        Returns what could not be restored. The time, the entities and the
        poses are those of a fresh start (the clauses reset them). A simulator
        found with no world is left with none.
        """
        problems = self.cleanup()
        try:
            self.world.restore()
            S = self.sim.S
            # NO_WORLD (the world loaded for the run now unloaded) is no state one can ask for.
            if (self.initial_state not in (None, S.STATE_NO_WORLD)
                    and self.target.declared('SIMULATION_STATE_SETTING')):
                self.sim.stop()
                if self.initial_state == S.STATE_PLAYING:
                    self.sim.play()
                elif (self.initial_state == S.STATE_PAUSED
                      and self.target.declared('SIMULATION_STATE_PAUSE')):
                    self.sim.pause()
        except (ClauseFailed, ClauseSkipped) as exc:
            problems.append(str(exc))
        return problems
