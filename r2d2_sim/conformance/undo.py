"""
Before and after each clause: the start state, the undo list, the world put back.

:class:`UndoVerbs` is mixed into :class:`~r2d2_sim.conformance.target.Target`:
``prepare`` puts the simulator in STOPPED before a clause, ``cleanup`` runs
what the clause registered and deletes what it spawned, and ``restore``
leaves the simulator as the kit found it (its world, its state). Loading and
unloading a world live here because the kit must remember that it did.
"""

from typing import Callable, List

from r2d2_sim.conformance.clause import ClauseFailed, ClauseSkipped


class UndoVerbs:
    """The Target's bookkeeping of what a clause changed, and its undoing."""

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
        self.spawned.clear()
        self._feedback.clear()
        if not stop:
            return
        if self.declared('SIMULATION_STATE_SETTING'):
            self.stop()
        elif self.declared('SIMULATION_RESET'):
            self.reset(0)

    def cleanup(self) -> List[str]:
        """Undo what the clause did; return what could not be undone (one line each)."""
        problems = []
        while self._cleanups:
            try:
                self._cleanups.pop()()
            except (ClauseFailed, ClauseSkipped) as exc:
                problems.append(str(exc))
        if self.spawned and self.declared('DELETING'):
            try:
                present = set(self.names())
            except ClauseFailed as exc:
                return problems + [str(exc)]
            for name in list(self.spawned):
                if name in present:
                    try:
                        self.delete(name)
                    except ClauseFailed as exc:
                        problems.append(str(exc))
        self.spawned.clear()
        return problems

    def load_world(self, resource, doing: str):
        """Load the world of a Resource (uri or resource_string), OK expected; return the reply."""
        request = self.srv.LoadWorld.Request(uri=resource.uri,
                                             resource_string=resource.resource_string)
        self.world_changed = True
        return self.ok('LoadWorld', request, doing)

    def unload_world(self) -> None:
        """UnloadWorld, OK expected."""
        self.world_changed = True
        self.ok('UnloadWorld', self.srv.UnloadWorld.Request(), 'UnloadWorld')

    def put_world_back(self) -> None:
        """
        Load the world found at the start again (or unload, if there was none).

        Without WORLD_INFO_GETTING the kit cannot know it: the last world it
        loaded stays.
        """
        if not self.world_changed or not self.initial_world_known:
            return
        world = self.initial_world
        resource = world.world_resource if world is not None else None
        if resource is not None and (resource.uri or resource.resource_string):
            self.load_world(resource, 'LoadWorld of the world found at the start')
        elif world is None and self.declared('WORLD_UNLOADING'):
            no_world = self.srv.UnloadWorld.Response.NO_WORLD_LOADED
            self.expect('UnloadWorld', self.srv.UnloadWorld.Request(),
                        (self.msg.Result.RESULT_OK, no_world), 'UnloadWorld, as at the start')
        self.world_changed = False

    def restore(self) -> List[str]:
        """
        Leave the simulator as found: the world loaded again, the state it was in.

        Returns what could not be restored. The time, the entities and the
        poses are those of a fresh start (the clauses reset them).
        """
        problems = self.cleanup()
        try:
            self.put_world_back()
            if self.initial_state is not None and self.declared('SIMULATION_STATE_SETTING'):
                S = self.S
                self.stop()
                if self.initial_state == S.STATE_PLAYING:
                    self.play()
                elif (self.initial_state == S.STATE_PAUSED
                      and self.declared('SIMULATION_STATE_PAUSE')):
                    self.pause()
        except (ClauseFailed, ClauseSkipped) as exc:
            problems.append(str(exc))
        return problems
