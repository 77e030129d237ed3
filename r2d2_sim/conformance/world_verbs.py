"""
The world of the simulation under test: the one found at the start, loaded, unloaded, put back.

:class:`TargetWorld` is a part of :class:`~r2d2_sim.conformance.target.Target`
(``t.world``). Loading and unloading go through it because the kit must
remember that it did: it owns the world found when the kit connected and
whether a clause changed it, and puts that world back after the clause.
"""

from typing import Any

from r2d2_sim.conformance.calls import TargetCalls


class TargetWorld:
    """The world of ``target``: what was loaded at the start, and whether the kit changed it."""

    def __init__(self, target: TargetCalls) -> None:
        self.target = target
        self.initial: Any = None  # the WorldResource current at connect, when told
        self.known = False  # GetCurrentWorld answered at connect (a world, or none)
        self.changed = False  # the kit loaded or unloaded a world since

    def remember(self) -> None:
        """Read the world loaded now (where GetCurrentWorld is declared and served)."""
        t = self.target
        if not (t.declared('WORLD_INFO_GETTING') and 'GetCurrentWorld' in t.interfaces):
            return
        reply = t.call('GetCurrentWorld', t.srv.GetCurrentWorld.Request(), check=False)
        no_world = t.srv.GetCurrentWorld.Response.NO_WORLD_LOADED
        if reply is not None and reply.result.result in (t.msg.Result.RESULT_OK, no_world):
            self.known = True
            if reply.result.result == t.msg.Result.RESULT_OK:
                self.initial = reply.world

    def load(self, resource: Any, doing: str) -> Any:
        """Load the world of a Resource (uri or resource_string), OK expected; return the reply."""
        t = self.target
        request = t.srv.LoadWorld.Request(uri=resource.uri,
                                          resource_string=resource.resource_string)
        self.changed = True
        return t.ok('LoadWorld', request, doing)

    def unload(self) -> None:
        """UnloadWorld, OK expected."""
        t = self.target
        self.changed = True
        t.ok('UnloadWorld', t.srv.UnloadWorld.Request(), 'UnloadWorld')

    def put_back(self) -> None:
        """
        Load the world found at the start again (or unload, if there was none).

        Without WORLD_INFO_GETTING the kit cannot know it: the last world it
        loaded stays.
        """
        if not self.changed or not self.known:
            return
        t = self.target
        world = self.initial
        resource = world.world_resource if world is not None else None
        if resource is not None and (resource.uri or resource.resource_string):
            self.load(resource, 'LoadWorld of the world found at the start')
        elif world is None and t.declared('WORLD_UNLOADING'):
            no_world = t.srv.UnloadWorld.Response.NO_WORLD_LOADED
            t.expect('UnloadWorld', t.srv.UnloadWorld.Request(),
                     (t.msg.Result.RESULT_OK, no_world), 'UnloadWorld, as at the start')
        self.changed = False
