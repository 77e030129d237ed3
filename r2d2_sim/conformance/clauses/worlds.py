"""NAMED: named poses and their bounds; WORLD: available, load, current, unload."""

from typing import Any, List, Sequence, Tuple

from r2d2_sim.conformance.clause import Clause, clause, ClauseFailed, ClauseSkipped
from r2d2_sim.conformance.clauses.entities import check_region
from r2d2_sim.conformance.target import Target
from r2d2_sim.conformance.values import close, fmt, quaternion, same_rotation, vector

CLAUSES: List[Clause] = []

NAMED = 'NAMED_POSES'
SET, PAUSE, GET = ('SIMULATION_STATE_SETTING', 'SIMULATION_STATE_PAUSE',
                   'SIMULATION_STATE_GETTING')
TAGS_QUOTE = ('TagsFilter tags # Tags filter to apply. Only named poses with matching tags field '
              'will be returned.')
# At most this many worlds are loaded to find one whose named poses show.
MOST_WORLDS = 3


def _poses(t: Target, tags: Sequence[str] = (), mode: int = 0) -> List[Any]:
    request = t.srv.GetNamedPoses.Request(tags=t.msg.TagsFilter(tags=list(tags), filter_mode=mode))
    return list(t.ok('GetNamedPoses', request, 'GetNamedPoses').poses)


def _shown_poses(t: Target) -> list:
    """
    Return the named poses of a world that has some: the one loaded, else one the kit loads.

    NAMED_POSES is declared: a world that has named poses must show them.
    When the world loaded shows none, the kit loads up to three others
    (``--world``, then the available ones) and looks again (the world is put
    back after the clause); none showing any fails (a GetNamedPoses that
    always answers an empty list). Skipped only where the kit can load no world.
    """
    poses = _poses(t)
    if poses:
        return poses
    candidates = _other_worlds(t) if t.declared('WORLD_LOADING') else []
    if not candidates:
        raise ClauseSkipped('GetNamedPoses lists no pose in the world loaded, and the kit has no '
                            'other world to load (give --world a world with named poses)')
    t.world.need_put_back()
    t.undo.on_cleanup(t.world.put_back)
    tried = []
    for resource in candidates:
        tried.append(resource.uri or 'a resource string')
        t.world.load(resource, f'LoadWorld of {tried[-1]}, to find named poses')
        poses = _poses(t)
        if poses:
            return poses
    raise ClauseFailed(f'NAMED_POSES is declared, yet GetNamedPoses lists no pose in the world '
                       f'loaded nor in the {len(tried)} the kit loaded ({", ".join(tried)})')


def _other_worlds(t: Target) -> list:
    """Return up to MOST_WORLDS Resources to load: --world, then available ones not loaded now."""
    now = _current(t).world if t.declared('WORLD_INFO_GETTING') else t.world.current
    loaded = _resource_of(now) if now is not None else None
    found = [t.msg.Resource(uri=t.options.world)] if t.options.world else []
    if t.declared('AVAILABLE_WORLDS'):
        found += [w.world_resource for w in _available(t) if _resource_of(w)]
    chosen: list = []
    for resource in found:
        key = resource.uri or resource.resource_string[:60]
        if key != loaded and key not in [r.uri or r.resource_string[:60] for r in chosen]:
            chosen.append(resource)
    return chosen[:MOST_WORLDS]


@clause(CLAUSES, 'NAMED-01', 'GetNamedPoses lists poses by unique names', (NAMED,),
        'NamedPose.msg', 'string name # Unique name.')
def unique_pose_names(t: Target) -> None:
    """Read a world's poses (see _shown_poses): no name twice, none empty, unit quaternions."""
    poses = _shown_poses(t)
    names = [p.name for p in poses]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice or '' in names:
        raise ClauseFailed(f'named poses listed twice or unnamed: {twice[:5] or [""]}')
    for pose in poses:
        norm = sum(v * v for v in quaternion(pose.pose.orientation)) ** 0.5
        if abs(norm - 1.0) > 1e-3:
            raise ClauseFailed(f'named pose {pose.name} has a quaternion of norm {norm:.4g}')


def _tag_check(t: Target, mode: int, label: str) -> None:
    poses = _shown_poses(t)
    tags = sorted({tag for p in poses for tag in p.tags})
    if not tags:
        raise ClauseSkipped('no named pose has tags')
    chosen = tags[:2]
    for asked in ([chosen[0]], chosen):
        if mode == t.msg.TagsFilter.FILTER_MODE_ALL:
            wanted = {p.name for p in poses if set(asked) <= set(p.tags)}
        else:
            wanted = {p.name for p in poses if set(asked) & set(p.tags)}
        got = {p.name for p in _poses(t, asked, mode)}
        if got != wanted:
            raise ClauseFailed(f'{label} {asked} gave {sorted(got)[:6]}, expected '
                               f'{sorted(wanted)[:6]}')


@clause(CLAUSES, 'NAMED-02', 'a tags filter in ANY mode picks the poses with any of the tags',
        (NAMED,), 'GetNamedPoses.srv', TAGS_QUOTE)
def poses_any(t: Target) -> None:
    """For the first tag, and the first two: exactly the poses having any of them."""
    _tag_check(t, t.msg.TagsFilter.FILTER_MODE_ANY, 'ANY')


@clause(CLAUSES, 'NAMED-03', 'a tags filter in ALL mode picks the poses with all the tags',
        (NAMED,), 'GetNamedPoses.srv', TAGS_QUOTE)
def poses_all(t: Target) -> None:
    """For the first tag, and the first two: exactly the poses having all of them."""
    _tag_check(t, t.msg.TagsFilter.FILTER_MODE_ALL, 'ALL')


@clause(CLAUSES, 'NAMED-04', 'every named pose has bounds the standard defines',
        (NAMED, 'POSE_BOUNDS'), 'GetNamedPoseBounds.srv', 'Get bounds for the named pose.')
def pose_bounds(t: Target) -> None:
    """Ask the bounds of each pose of a world's (see _shown_poses): OK, a defined type."""
    poses = _shown_poses(t)
    for pose in poses[:20]:
        bounds = t.ok('GetNamedPoseBounds', t.srv.GetNamedPoseBounds.Request(name=pose.name),
                      f'GetNamedPoseBounds of {pose.name}').bounds
        check_region(t, bounds, f'GetNamedPoseBounds of {pose.name}')


@clause(CLAUSES, 'NAMED-05', 'an entity spawned at a named pose is there',
        (NAMED, 'SPAWNING', 'ENTITY_STATE_GETTING', SET, PAUSE), 'NamedPose.msg',
        'geometry_msgs/Pose pose # Pose relative to world, which can be used with '
        'SpawnEntity.srv.')
def spawn_at_named_pose(t: Target) -> None:
    """Paused: the kit's box spawned at a world's first named pose reads exactly there."""
    pose = _shown_poses(t)[0]
    t.sim.pause()
    t.undo.on_cleanup(t.sim.stop)
    position, orientation = vector(pose.pose.position), quaternion(pose.pose.orientation)
    name = t.entities.new_name()
    t.entities.spawn_call(t.entities.spawn_request(name, position, orientation),
                          doing=f'SpawnEntity at the named pose {pose.name}')
    state = t.entities.state(name).pose
    got_p, got_q = vector(state.position), quaternion(state.orientation)
    if not close(got_p, position) or not same_rotation(got_q, orientation):
        raise ClauseFailed(f'{name} spawned at the named pose {pose.name} reads {fmt(got_p)} '
                           f'{fmt(got_q)}, the pose is {fmt(position)} {fmt(orientation)}')


# -- WORLD -------------------------------------------------------------------------------

NO_WORLD = 'NO_WORLD_LOADED = 101 # No world is loaded at the moment.'
# The unloading clauses load a world first (so that there is one) and load the world found
# at the start back afterwards: they need both.
UNLOAD = ('WORLD_LOADING', 'WORLD_UNLOADING')


def _current(t: Target) -> Any:
    """Return GetCurrentWorld's reply (OK or NO_WORLD_LOADED expected)."""
    codes = (t.msg.Result.RESULT_OK, t.srv.GetCurrentWorld.Response.NO_WORLD_LOADED)
    return t.expect('GetCurrentWorld', t.srv.GetCurrentWorld.Request(), codes, 'GetCurrentWorld')


def _available(t: Target) -> List[Any]:
    request = t.srv.GetAvailableWorlds.Request(offline_only=True)
    return list(t.ok('GetAvailableWorlds', request, 'GetAvailableWorlds (offline only)').worlds)


def _resource_of(world: Any) -> str:
    return world.world_resource.uri or world.world_resource.resource_string[:60]


def _world_to_load(t: Target) -> Any:
    """Return a Resource to load: --world, else an available world other than the current."""
    if t.options.world:
        return t.msg.Resource(uri=t.options.world)
    current = t.world.current
    if t.declared('AVAILABLE_WORLDS'):
        worlds = [w for w in _available(t) if _resource_of(w)]
        others = [w for w in worlds if current is None or _resource_of(w) != _resource_of(current)]
        if others or worlds:
            return (others or worlds)[0].world_resource
    if current is not None and _resource_of(current):
        return current.world_resource
    raise ClauseSkipped('no world to load: give --world URI (or declare AVAILABLE_WORLDS)')


def _load(t: Target, doing: str = 'LoadWorld') -> Tuple[Any, Any]:
    """Load a world (see _world_to_load), to be put back after the clause."""
    t.world.need_put_back()
    resource = _world_to_load(t)
    t.undo.on_cleanup(t.world.put_back)
    reply = t.world.load(resource, f'{doing} of {resource.uri or "a resource string"}')
    return resource, reply


def _unload(t: Target) -> None:
    """Load a world (so that there is one), then unload it; put back after the clause."""
    _load(t)
    t.world.unload()


@clause(CLAUSES, 'WORLD-01', 'GetAvailableWorlds lists worlds LoadWorld can take',
        ('AVAILABLE_WORLDS',), 'GetAvailableWorlds.srv', 'Return a list of available world '
        'resources which can be used with LoadWorld.')
def available_worlds(t: Target) -> None:
    """Offline only: OK, and every world has a uri or a resource string."""
    bad = [w.name or '(no name)' for w in _available(t) if not _resource_of(w)]
    if bad:
        raise ClauseFailed(f'worlds without a uri or resource string: {bad[:5]}')


@clause(CLAUSES, 'WORLD-02', 'a tags filter picks the worlds with the tags',
        ('AVAILABLE_WORLDS', 'WORLD_TAGS'), 'GetAvailableWorlds.srv', 'TagsFilter filter # Only '
        'get worlds with tags matching the filter.')
def world_tags(t: Target) -> None:
    """For the first tag: ANY gives exactly the worlds having it."""
    worlds = _available(t)
    tags = sorted({tag for w in worlds for tag in w.tags})
    if not tags:
        raise ClauseSkipped('no available world has tags')
    request = t.srv.GetAvailableWorlds.Request(offline_only=True)
    request.filter = t.msg.TagsFilter(tags=[tags[0]], filter_mode=0)
    got = {w.name for w in t.ok('GetAvailableWorlds', request, 'GetAvailableWorlds').worlds}
    wanted = {w.name for w in worlds if tags[0] in w.tags}
    if got != wanted:
        raise ClauseFailed(f'worlds tagged {tags[0]!r}: got {sorted(got)[:5]}, expected '
                           f'{sorted(wanted)[:5]}')


@clause(CLAUSES, 'WORLD-03', 'GetCurrentWorld answers OK or NO_WORLD_LOADED, as the state says',
        ('WORLD_INFO_GETTING',), 'GetCurrentWorld.srv', 'WorldResource world # Information about '
        'the currently loaded world. Only valid if result is RESULT_OK.')
def current_world(t: Target) -> None:
    """OK with a world, or 101; 101 exactly when the state reads NO_WORLD (if readable)."""
    reply = _current(t)
    if t.declared(GET):
        no_world = t.sim.state() == t.sim.S.STATE_NO_WORLD
        if no_world != (reply.result.result != t.msg.Result.RESULT_OK):
            raise ClauseFailed(f'GetCurrentWorld {t.describe("GetCurrentWorld", reply)} while '
                               f'the state reads {t.sim.state_name(t.sim.state())}')
    elif reply.result.result == t.msg.Result.RESULT_OK and not _resource_of(reply.world):
        raise ClauseFailed('GetCurrentWorld answered OK with a world of no resource')


@clause(CLAUSES, 'WORLD-04', 'LoadWorld answers OK with the world it loaded', ('WORLD_LOADING',),
        'LoadWorld.srv', 'WorldResource world # Information about the loaded world. Only valid if '
        'result is RESULT_OK.')
def load_world(t: Target) -> None:
    """Load a world: OK, and its reply names a world (a name or a resource)."""
    _, reply = _load(t)
    if not (reply.world.name or _resource_of(reply.world)):
        raise ClauseFailed('LoadWorld answered OK with an empty world')


@clause(CLAUSES, 'WORLD-05', 'after LoadWorld the simulation is STOPPED',
        ('WORLD_LOADING', SET, GET), 'LoadWorld.srv', 'Once a world is loaded, simulation will be '
        'left in a Stopped state.')
def loaded_stopped(t: Target) -> None:
    """Play, load a world: the state reads STOPPED."""
    t.sim.play()
    _load(t)
    t.sim.expect_state(t.sim.S.STATE_STOPPED, 'LoadWorld')


@clause(CLAUSES, 'WORLD-06', 'LoadWorld removes spawned entities', ('WORLD_LOADING', 'SPAWNING'),
        'LoadWorld.srv', 'Any previously spawned entities will be removed.',
        services=('GetEntities',))
def load_despawns(t: Target) -> None:
    """Spawn, load a world: the spawned entity is gone."""
    name = t.entities.spawn(0)
    _load(t)
    if name in t.entities.names():
        raise ClauseFailed(f'{name} is still listed after LoadWorld')


@clause(CLAUSES, 'WORLD-07', 'GetCurrentWorld names the world LoadWorld loaded',
        ('WORLD_LOADING', 'WORLD_INFO_GETTING'), 'GetCurrentWorld.srv',
        'Get information about the currently loaded world in the simulation.')
def current_is_loaded(t: Target) -> None:
    """Load a world: GetCurrentWorld gives the world LoadWorld's reply gave."""
    _, reply = _load(t)
    current = _current(t)
    if current.result.result != t.msg.Result.RESULT_OK:
        raise ClauseFailed(f'after LoadWorld, GetCurrentWorld answered '
                           f'{t.describe("GetCurrentWorld", current)}')
    loaded = (reply.world.name, _resource_of(reply.world))
    if (current.world.name, _resource_of(current.world)) != loaded:
        raise ClauseFailed(f'GetCurrentWorld gives {current.world.name!r} '
                           f'({_resource_of(current.world)}), LoadWorld loaded '
                           f'{reply.world.name!r} ({_resource_of(reply.world)})')


@clause(CLAUSES, 'WORLD-08', 'LoadWorld of nothing is NO_RESOURCE', ('WORLD_LOADING',),
        'LoadWorld.srv', 'NO_RESOURCE = 102 # Both uri and resource string are empty.')
def load_nothing(t: Target) -> None:
    """Both empty: 102."""
    t.expect('LoadWorld', t.srv.LoadWorld.Request(), (t.srv.LoadWorld.Response.NO_RESOURCE,),
             'LoadWorld of nothing')


@clause(CLAUSES, 'WORLD-09', 'a world string that does not parse is refused, the world kept',
        ('WORLD_LOADING', 'WORLD_RESOURCE_STRING'), 'LoadWorld.srv',
        'RESOURCE_PARSE_ERROR = 103 # Resource file or string failed to parse.')
def load_garbage(t: Target) -> None:
    """Load a cut-off XML world: 103 (or 101, no format), and GetCurrentWorld unchanged."""
    t.world.need_put_back()  # should the simulator take it, the world must go back
    before = _current(t) if t.declared('WORLD_INFO_GETTING') else None
    response = t.srv.LoadWorld.Response
    t.expect('LoadWorld', t.srv.LoadWorld.Request(resource_string='<sdf version="1.6"><world'),
             (response.RESOURCE_PARSE_ERROR, response.UNSUPPORTED_FORMAT),
             'LoadWorld of a cut-off world')
    if before is not None:
        after = _current(t)
        if (after.result.result, after.world.name) != (before.result.result, before.world.name):
            t.world.changed = True
            t.undo.on_cleanup(t.world.put_back)
            raise ClauseFailed(f'the refused LoadWorld changed the current world from '
                               f'{before.world.name!r} to {after.world.name!r}')


@clause(CLAUSES, 'WORLD-10', 'after UnloadWorld, GetCurrentWorld is NO_WORLD_LOADED',
        UNLOAD + ('WORLD_INFO_GETTING',), 'GetCurrentWorld.srv', NO_WORLD)
def unloaded_no_world(t: Target) -> None:
    """Unload: GetCurrentWorld answers 101."""
    _unload(t)
    t.expect('GetCurrentWorld', t.srv.GetCurrentWorld.Request(),
             (t.srv.GetCurrentWorld.Response.NO_WORLD_LOADED,),
             'GetCurrentWorld after UnloadWorld')


@clause(CLAUSES, 'WORLD-11', 'UnloadWorld with no world is NO_WORLD_LOADED', UNLOAD,
        'UnloadWorld.srv', NO_WORLD)
def unload_twice(t: Target) -> None:
    """Unload twice: the second answers 101."""
    _unload(t)
    t.expect('UnloadWorld', t.srv.UnloadWorld.Request(),
             (t.srv.UnloadWorld.Response.NO_WORLD_LOADED,), 'a second UnloadWorld')


@clause(CLAUSES, 'WORLD-12', 'with no world the state reads NO_WORLD', UNLOAD + (GET,),
        'SimulationState.msg', 'STATE_NO_WORLD = 4 # Simulation world is currently unloaded.')
def no_world_state(t: Target) -> None:
    """Unload: the state reads NO_WORLD."""
    _unload(t)
    t.sim.expect_state(t.sim.S.STATE_NO_WORLD, 'UnloadWorld')


@clause(CLAUSES, 'WORLD-13', 'with no world the simulation cannot be played, stopped or paused',
        UNLOAD + (SET,), 'SimulationState.msg', 'The simulation is inactive and cannot '
        'be started, stopped, or paused.')
def no_world_no_play(t: Target) -> None:
    """
    Unload, ask for PLAYING, STOPPED and PAUSED: each refused (not OK, not 0).

    PAUSED only where SIMULATION_STATE_PAUSE is declared (elsewhere 0 is its
    right answer).
    """
    _unload(t)
    S = t.sim.S
    states = [S.STATE_PLAYING, S.STATE_STOPPED] + (
        [S.STATE_PAUSED] if t.declared(PAUSE) else [])
    for state in states:
        reply = t.sim.request_state(state)
        if reply.result.result in (t.msg.Result.RESULT_OK,
                                   t.msg.Result.RESULT_FEATURE_UNSUPPORTED):
            raise ClauseFailed(f'{t.sim.state_name(state)} with no world answered '
                               f'{t.describe("SetSimulationState", reply)}')


@clause(CLAUSES, 'WORLD-14', 'UnloadWorld removes spawned entities',
        UNLOAD + ('SPAWNING',), 'UnloadWorld.srv',
        'Any previously spawned entities will be removed.', services=('GetEntities',))
def unload_despawns(t: Target) -> None:
    """Load a world, spawn, unload: GetEntities no longer lists it (or answers with no world)."""
    _load(t)
    name = t.entities.spawn(0)
    t.world.unload()
    reply = t.call('GetEntities', t.srv.GetEntities.Request())
    if reply.result.result == t.msg.Result.RESULT_OK and name in reply.entities:
        raise ClauseFailed(f'{name} is still listed after UnloadWorld')
    if name in t.entities.spawned:
        t.entities.spawned.remove(name)
