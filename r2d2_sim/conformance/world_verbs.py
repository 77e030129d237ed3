"""
The world of the simulation under test: the one found at the start, loaded, unloaded, put back.

:class:`TargetWorld` is a part of :class:`~r2d2_sim.conformance.target.Target`
(``t.world``). Loading and unloading go through it because the kit must
remember that it did: it owns the world found when the kit connected, the
world each clause starts with (that one; or, where the simulator had none,
one the kit loaded for the run and unloads at the end) and whether a clause
changed it, and puts that world back after the clause. The world given by
the user (``--world``) is tried once: refused, it is a setup problem (one
line), not the simulator's failure, and the clauses that need it are skipped.
"""

from typing import Any, Optional

from r2d2_sim.conformance.calls import TargetCalls
from r2d2_sim.conformance.clause import ClauseFailed, ClauseSkipped, one_line


def has_resource(world: Any) -> bool:
    """Return True when a WorldResource says how to load it again (a uri or a string)."""
    resource = world.world_resource
    return bool(resource.uri or resource.resource_string)


class TargetWorld:
    """The world of ``target``: what was loaded at the start, and whether the kit changed it."""

    def __init__(self, target: TargetCalls) -> None:
        self.target = target
        self.initial: Any = None  # the WorldResource current at connect, when told
        self.known = False  # the world at connect is known (GetCurrentWorld, or NO_WORLD read)
        self.current: Any = None  # the world each clause starts with (see load_for_run)
        self.loaded_for_run = False  # there was none: the kit loaded ``current``, unloads it
        self.changed = False  # the kit loaded or unloaded a world since
        self.missing = ''  # why no clause can start from STOPPED: no world, none loadable
        self.problem = ''  # the world given could not be loaded: the setup line
        self._given_loads = False  # the world given was loaded once (it is not tried again)

    def remember(self, no_world: bool = False) -> None:
        """
        Read the world loaded now (where GetCurrentWorld is declared and served).

        ``no_world``: the state read NO_WORLD, so there is none, told or not.
        """
        t = self.target
        if t.declared('WORLD_INFO_GETTING') and 'GetCurrentWorld' in t.interfaces:
            reply = t.call('GetCurrentWorld', t.srv.GetCurrentWorld.Request(), check=False)
            no_world_code = t.srv.GetCurrentWorld.Response.NO_WORLD_LOADED
            if reply is not None and reply.result.result in (t.msg.Result.RESULT_OK,
                                                             no_world_code):
                self.known = True
                if reply.result.result == t.msg.Result.RESULT_OK:
                    self.initial = reply.world
        if no_world:
            self.known, self.initial = True, None
        self.current = self.initial

    def no_world(self) -> bool:
        """Return True when the simulator had no world loaded at the start."""
        return self.known and self.initial is None

    def load_for_run(self) -> None:
        """
        Where the simulator has no world, load one for the run (unloaded by :meth:`restore`).

        A simulation with no world "cannot be started, stopped, or paused", so
        no clause could start from STOPPED: the kit loads the world given, else
        the first GetAvailableWorlds lists. Where it cannot (nothing to load,
        no WORLD_LOADING or WORLD_UNLOADING to undo it, the load refused),
        ``missing`` says why, and those clauses are skipped.
        """
        if not self.no_world():
            return
        t = self.target
        lacking = [f for f in ('WORLD_LOADING', 'WORLD_UNLOADING') if not t.declared(f)]
        if lacking:
            self.missing = (f'no world is loaded, and the kit cannot load one and unload it '
                            f'afterwards: {" and ".join(lacking)} not declared')
            return
        resource = self._first_world()
        if resource is None:
            self.missing = ('no world is loaded, and the kit has none to load: give it one '
                            '(--world URI)')
            return
        what = resource.uri or 'a resource string'
        try:
            reply = self.load(resource, f'LoadWorld of {what}, as no world was loaded')
        except (ClauseFailed, ClauseSkipped) as exc:
            self.missing = one_line(f'no world is loaded, and the kit could not load one: {exc}')
            return
        world = reply.world
        if not has_resource(world):  # the reply need not say it again: the kit knows it
            world = self.target.msg.WorldResource(name=world.name, world_resource=resource)
        self.current, self.loaded_for_run, self.changed = world, True, False

    def _first_world(self) -> Any:
        """Return the Resource to load where there is no world: the one given, else one listed."""
        t = self.target
        if t.options.world:
            return t.msg.Resource(uri=t.options.world)
        if not t.declared('AVAILABLE_WORLDS'):
            return None
        request = t.srv.GetAvailableWorlds.Request(offline_only=True)
        reply = t.call('GetAvailableWorlds', request, check=False)
        if reply is None or reply.result.result != t.msg.Result.RESULT_OK:
            return None
        return next((w.world_resource for w in reply.worlds if has_resource(w)), None)

    def given(self, resource: Any) -> bool:
        """Return True for the world the user gave (``--world``)."""
        uri = self.target.options.world
        return bool(uri) and resource.uri == uri and not resource.resource_string

    def load(self, resource: Any, doing: str) -> Any:
        """
        Load the world of a Resource (uri or resource_string), OK expected; return the reply.

        The world given is tried once: refused, ClauseSkipped with the setup line
        (``problem``), now and whenever it is asked for again.
        """
        t = self.target
        given = self.given(resource)
        if given and self.problem:
            raise ClauseSkipped(self.problem)
        request = t.srv.LoadWorld.Request(uri=resource.uri,
                                          resource_string=resource.resource_string)
        self.changed = True
        if not given or self._given_loads:
            return t.ok('LoadWorld', request, doing)
        reply = t.call('LoadWorld', request)
        if reply.result.result != t.msg.Result.RESULT_OK:
            self.problem = one_line(f'the world given, {resource.uri!r}, could not be loaded: '
                                    f'LoadWorld answered {t.describe("LoadWorld", reply)}')
            raise ClauseSkipped(self.problem)
        self._given_loads = True
        return reply

    def unload(self) -> None:
        """UnloadWorld, OK expected."""
        t = self.target
        self.changed = True
        t.ok('UnloadWorld', t.srv.UnloadWorld.Request(), 'UnloadWorld')

    def need_put_back(self) -> None:
        """
        Raise ClauseSkipped when the kit could not load the world of the start back.

        GetCurrentWorld named it without a uri or a resource string: a clause
        that loads another world would leave it gone.
        """
        world = self.current
        if self.known and world is not None and not has_resource(world):
            raise ClauseSkipped(f'the world loaded now ({world.name!r}) has no uri or resource '
                                'string in GetCurrentWorld: the kit could not load it back, so '
                                'it loads no other')

    def put_back(self) -> None:
        """
        Load the world each clause starts with again (or unload, if there was none).

        Without WORLD_INFO_GETTING the kit cannot know it: the last world it
        loaded stays (and :meth:`restore` says so).
        """
        if not self.changed or not self.known:
            return
        t = self.target
        world = self.current
        if world is None:
            if not t.declared('WORLD_UNLOADING'):
                raise ClauseFailed('no world was loaded at the start, and the kit cannot '
                                   'unload the one there now: WORLD_UNLOADING not declared')
            no_world = t.srv.UnloadWorld.Response.NO_WORLD_LOADED
            t.expect('UnloadWorld', t.srv.UnloadWorld.Request(),
                     (t.msg.Result.RESULT_OK, no_world), 'UnloadWorld, as at the start')
        elif has_resource(world):
            self.load(world.world_resource, f'LoadWorld of the world of the start, {world.name!r}')
        else:
            raise ClauseFailed(f'the world of the start ({world.name!r}) could not be loaded '
                               'back: GetCurrentWorld gave no uri or resource string')
        self.changed = False

    def restore(self) -> None:
        """
        Leave the world as found: put back, and unload the world loaded for the run.

        ClauseFailed for what could not be left as found, one line.
        """
        self.put_back()
        t = self.target
        if self.loaded_for_run:
            no_world = t.srv.UnloadWorld.Response.NO_WORLD_LOADED
            t.expect('UnloadWorld', t.srv.UnloadWorld.Request(),
                     (t.msg.Result.RESULT_OK, no_world),
                     'UnloadWorld of the world the kit loaded, as there was none')
            self.loaded_for_run = False
        if self.changed and not self.known:
            self.changed = False
            raise ClauseFailed('the world loaded at the start is unknown (WORLD_INFO_GETTING '
                               'not declared): the last world the kit loaded stays')

    def described(self) -> Optional[str]:
        """Return a header line on the world the run starts with (None when nothing to say)."""
        if self.missing:
            return self.missing
        if self.loaded_for_run:
            resource = self.current.world_resource
            return (f'no world was loaded: the kit loaded {resource.uri or "a resource string"} '
                    'for the run, and unloads it at the end')
        return None
