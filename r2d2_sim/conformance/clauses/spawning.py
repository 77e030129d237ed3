"""SPAWN: SpawnEntity's names, resources, poses; BATCH: SpawnEntities; DELETE; SPAWNABLES."""

import math
from typing import Any, List, Sequence

from r2d2_sim.conformance.clause import Clause, clause, ClauseFailed, ClauseSkipped
from r2d2_sim.conformance.entity_verbs import Point
from r2d2_sim.conformance.target import Target
from r2d2_sim.conformance.values import (
    close, fmt, quaternion, same_rotation, vector, yaw_quaternion)

CLAUSES: List[Clause] = []

SPAWNING, RESOURCE = 'SPAWNING', 'SPAWNING_RESOURCE_STRING'
SET, PAUSE, GETTING = ('SIMULATION_STATE_SETTING', 'SIMULATION_STATE_PAUSE',
                       'ENTITY_STATE_GETTING')
LISTED = ('GetEntities',)
NAME_QUOTE = ('string entity_name # Spawned entity full name, guaranteed to be unique in the '
              'simulation.')
POSE_QUOTE = ('geometry_msgs/PoseStamped initial_pose # Initial entity pose. The header contains '
              'a reference frame, which defaults to global "world" frame. This frame must be '
              'known to the simulator, e.g. of an object spawned earlier.')
INVALID_POSE_QUOTE = ('INVALID_POSE = 109 # initial_pose is invalid, such as when the quaternion '
                      'is invalid or position exceeds simulator world bounds.')


def _listed(t: Target, name: str, doing: str) -> None:
    if name not in t.entities.names():
        raise ClauseFailed(f'{doing} returned {name!r}, which GetEntities does not list')


def _refused(t: Target, request: Any, codes: Sequence[int], doing: str) -> None:
    """Send a spawn that must be refused with one of ``codes``; nothing may appear."""
    before = set(t.entities.names())
    t.entities.spawn_call(request, codes, doing)
    new = sorted(set(t.entities.names()) - before)
    t.entities.spawned.extend(n for n in new if n not in t.entities.spawned)
    if new:
        raise ClauseFailed(f'the refused spawn ({doing}) left new entities: {new[:5]}')


@clause(CLAUSES, 'SPAWN-01', 'a spawn by uri gets the name asked for and is listed', (SPAWNING,),
        'SpawnEntity.srv', NAME_QUOTE, services=LISTED)
def spawn_uri(t: Target) -> None:
    """Spawn the --asset URI by a fresh name, no renaming: that name back, and listed."""
    if not t.options.asset:
        raise ClauseSkipped('no --asset URI given')
    name = t.entities.new_name('asset')
    request = t.entities.spawn_request(name, t.entities.slot(0), uri=t.options.asset)
    got = t.entities.spawn_call(request).entity_name
    if got != name:
        raise ClauseFailed(f'spawned {name!r} and got back {got!r}')
    _listed(t, got, 'SpawnEntity')


@clause(CLAUSES, 'SPAWN-02',
        'a spawn from a resource_string gets the name asked for and is listed',
        (SPAWNING, RESOURCE), 'SpawnEntity.srv', 'string resource_string # An entity definition '
        'file passed as a string.', services=LISTED)
def spawn_resource(t: Target) -> None:
    """Spawn the kit's box as URDF or SDF text: that name back, and listed."""
    t.entities.need_resource_string()
    name = t.entities.spawn(0)
    _listed(t, name, 'SpawnEntity')


@clause(CLAUSES, 'SPAWN-03', 'an empty name takes the name in the file', (SPAWNING, RESOURCE),
        'SpawnEntity.srv', 'string name # A name to give to the spawned entity. If empty, the '
        'name field in the URI file or resource_string will be used, if supported and not empty')
def name_from_file(t: Target) -> None:
    """
    Spawn with name '' a box named in its text: that name, or NAME_INVALID.

    "if supported": a simulator that reads no names from files refuses the
    empty name (NAME_INVALID) rather than making one up.
    """
    t.entities.need_resource_string()
    inner = t.entities.new_name('named_in_file')
    request = t.entities.spawn_request('', t.entities.slot(0), resource=t.entities.box_text(inner))
    reply = t.entities.spawn_call(request, (t.msg.Result.RESULT_OK,
                                            t.srv.SpawnEntity.Response.NAME_INVALID),
                                  'SpawnEntity with an empty name')
    if reply.result.result == t.msg.Result.RESULT_OK and reply.entity_name != inner:
        raise ClauseFailed(f'an empty name with {inner!r} in the file gave {reply.entity_name!r}')


@clause(CLAUSES, 'SPAWN-04', 'a taken name without allow_renaming is NAME_NOT_UNIQUE', (SPAWNING,),
        'SpawnEntity.srv', 'NAME_NOT_UNIQUE = 101 # Given name is already taken by entity and '
        'allow_renaming is false.', services=LISTED)
def name_taken(t: Target) -> None:
    """Spawn A; spawn A again without renaming: 101, nothing new."""
    name = t.entities.spawn(0)
    _refused(t, t.entities.spawn_request(name, t.entities.slot(1)),
             (t.srv.SpawnEntity.Response.NAME_NOT_UNIQUE,),
             f'a second {name} without allow_renaming')


@clause(CLAUSES, 'SPAWN-05', 'a taken name with allow_renaming gets a new unique name',
        (SPAWNING,), 'SpawnEntity.srv', 'the service returns a generated name in the entity_name '
        'response field if the allow_renaming field is set to true.', services=LISTED)
def renamed(t: Target) -> None:
    """Spawn A; spawn A again with renaming: OK, another name, listed beside A."""
    name = t.entities.spawn(0)
    request = t.entities.spawn_request(name, t.entities.slot(1), allow_renaming=True)
    got = t.entities.spawn_call(request, doing=f'a second {name} with allow_renaming').entity_name
    if got == name or not got:
        raise ClauseFailed(f'a second {name} with allow_renaming came back as {got!r}')
    names = t.entities.names()
    if name not in names or got not in names:
        raise ClauseFailed(f'after renaming, GetEntities lists {sorted(names)[:6]}: not both '
                           f'{name} and {got}')


@clause(CLAUSES, 'SPAWN-06', 'an empty name, none in the file, no renaming: NAME_INVALID',
        (SPAWNING, RESOURCE), 'SpawnEntity.srv', 'NAME_INVALID = 102 # ... This is also returned '
        'if name is empty and allow_renaming is false.', services=LISTED)
def no_name_at_all(t: Target) -> None:
    """Spawn as '' a box of empty name: 102 (or 106: that file is no URDF)."""
    t.entities.need_resource_string()
    request = t.entities.spawn_request('', t.entities.slot(0), resource=t.entities.box_text(''))
    response = t.srv.SpawnEntity.Response
    _refused(t, request, (response.NAME_INVALID, response.RESOURCE_PARSE_ERROR),
             'SpawnEntity with no name anywhere')


@clause(CLAUSES, 'SPAWN-07', 'the uri wins over resource_string', (SPAWNING,), 'SpawnEntity.srv',
        'If uri field is not empty, resource_string field will be ignored.')
def uri_wins(t: Target) -> None:
    """Spawn --asset with a resource string that is no model: OK (the string is ignored)."""
    if not t.options.asset:
        raise ClauseSkipped('no --asset URI given')
    request = t.entities.spawn_request(t.entities.new_name('asset'), t.entities.slot(0),
                                       uri=t.options.asset, resource='this is not a model')
    t.entities.spawn_call(request, doing='SpawnEntity with a uri and a broken resource_string')


@clause(CLAUSES, 'SPAWN-08', 'neither uri nor resource_string is NO_RESOURCE', (SPAWNING,),
        'SpawnEntity.srv', 'NO_RESOURCE = 104 # Both uri and resource string are empty.',
        services=LISTED)
def no_resource(t: Target) -> None:
    """Both empty: 104, nothing new."""
    request = t.entities.spawn_request(t.entities.new_name(), t.entities.slot(0), uri='',
                                       resource='')
    _refused(t, request, (t.srv.SpawnEntity.Response.NO_RESOURCE,), 'SpawnEntity of nothing')


@clause(CLAUSES, 'SPAWN-09', 'a zero quaternion is INVALID_POSE', (SPAWNING,), 'SpawnEntity.srv',
        INVALID_POSE_QUOTE, services=LISTED)
def spawn_zero_quaternion(t: Target) -> None:
    """Orientation (0, 0, 0, 0): 109, nothing new."""
    name = t.entities.new_name()
    request = t.entities.spawn_request(name, t.entities.slot(0), (0.0, 0.0, 0.0, 0.0))
    _refused(t, request, (t.srv.SpawnEntity.Response.INVALID_POSE,),
             'SpawnEntity with a zero quaternion')


@clause(CLAUSES, 'SPAWN-10', 'a NaN position is INVALID_POSE', (SPAWNING,), 'SpawnEntity.srv',
        INVALID_POSE_QUOTE, services=LISTED)
def spawn_nan(t: Target) -> None:
    """Position (NaN, y, z): 109, nothing new."""
    x, y, z = t.entities.slot(0)
    request = t.entities.spawn_request(t.entities.new_name(), (math.nan, y, z))
    _refused(t, request, (t.srv.SpawnEntity.Response.INVALID_POSE,),
             'SpawnEntity at a NaN position')


def _expect_at(t: Target, name: str, position: Point, orientation: Sequence[float],
               doing: str) -> None:
    pose = t.entities.state(name).pose
    got_p, got_q = vector(pose.position), quaternion(pose.orientation)
    if not close(got_p, position) or not same_rotation(got_q, orientation):
        raise ClauseFailed(f'{doing}: {name} is at {fmt(got_p)} {fmt(got_q)}, asked for '
                           f'{fmt(position)} {fmt(orientation)}')


@clause(CLAUSES, 'SPAWN-11', 'an entity is spawned at its initial_pose',
        (SPAWNING, GETTING, SET, PAUSE), 'SpawnEntity.srv', POSE_QUOTE)
def spawn_at_pose(t: Target) -> None:
    """Paused: a box spawned turned by 0.8 rad, in the air, reads exactly there."""
    t.sim.pause()
    t.undo.on_cleanup(t.sim.stop)
    name = t.entities.spawn(0, yaw=0.8)
    _expect_at(t, name, t.entities.slot(0), yaw_quaternion(0.8), 'SpawnEntity')


@clause(CLAUSES, 'SPAWN-12', 'an initial_pose in another entity\'s frame is relative to it',
        (SPAWNING, GETTING, SET, PAUSE), 'SpawnEntity.srv', POSE_QUOTE)
def spawn_in_entity_frame(t: Target) -> None:
    """Turn A 90 degrees, spawn B 1 m along A's x: B is 1 m along world y of A."""
    t.sim.pause()
    t.undo.on_cleanup(t.sim.stop)
    a = t.entities.spawn(0, yaw=math.pi / 2)
    b = t.entities.spawn(name=t.entities.new_name(), position=(1.0, 0.0, 0.0), frame=a)
    x, y, z = t.entities.slot(0)
    _expect_at(t, b, (x, y + 1.0, z), yaw_quaternion(math.pi / 2),
               f'SpawnEntity in the frame of {a}')


@clause(CLAUSES, 'SPAWN-13', 'an initial_pose in an unknown frame is refused', (SPAWNING,),
        'SpawnEntity.srv', 'This frame must be known to the simulator, e.g. of an object spawned '
        'earlier.', services=LISTED)
def spawn_unknown_frame(t: Target) -> None:
    """Frame 'conformance_no_such_frame': any refusal but 0, nothing new."""
    request = t.entities.spawn_request(t.entities.new_name(), t.entities.slot(0),
                                       frame='conformance_no_such_frame')
    before = set(t.entities.names())
    reply = t.call('SpawnEntity', request)
    if reply.result.result == t.msg.Result.RESULT_OK:
        t.entities.spawned.append(reply.entity_name)
    if reply.result.result in (t.msg.Result.RESULT_OK, t.msg.Result.RESULT_FEATURE_UNSUPPORTED):
        raise ClauseFailed(f'SpawnEntity in an unknown frame answered '
                           f'{t.describe("SpawnEntity", reply)}')
    new = sorted(set(t.entities.names()) - before)
    if new:
        t.entities.spawned.extend(new)
        raise ClauseFailed(f'the refused spawn left new entities: {new[:5]}')


@clause(CLAUSES, 'SPAWN-14', 'an invalid namespace is NAMESPACE_INVALID', (SPAWNING,),
        'SpawnEntity.srv', 'NAMESPACE_INVALID = 105 # Namespace does not meet namespace naming '
        'standards.', services=LISTED)
def bad_namespace(t: Target) -> None:
    """Namespace '/bad namespace!' (a space and a '!': no ROS namespace): 105, nothing new."""
    request = t.entities.spawn_request(t.entities.new_name(), t.entities.slot(0),
                                       namespace='/bad namespace!')
    _refused(t, request, (t.srv.SpawnEntity.Response.NAMESPACE_INVALID,),
             'SpawnEntity with namespace /bad namespace!')


@clause(CLAUSES, 'SPAWN-15', 'a resource that does not parse is RESOURCE_PARSE_ERROR',
        (SPAWNING, RESOURCE), 'SpawnEntity.srv', 'RESOURCE_PARSE_ERROR = 106 # Resource file or '
        'string failed to parse.', services=LISTED)
def parse_error(t: Target) -> None:
    """Spawn the kit's box text cut in half: 106, nothing new."""
    t.entities.need_resource_string()
    name = t.entities.new_name()
    text = t.entities.box_text(name)
    request = t.entities.spawn_request(name, t.entities.slot(0), resource=text[:len(text) // 2])
    _refused(t, request, (t.srv.SpawnEntity.Response.RESOURCE_PARSE_ERROR,),
             'SpawnEntity of a truncated description')


@clause(CLAUSES, 'SPAWN-16', 'a resource in no format gets a spawn code, not OPERATION_FAILED',
        (SPAWNING, RESOURCE), 'Result.msg', 'Implementation rule: check extended codes for called '
        'service (e.g. SpawnEntity) to provide a return code which is more specific.',
        services=LISTED)
def specific_code(t: Target) -> None:
    """Plain text: UNSUPPORTED_FORMAT (103) or RESOURCE_PARSE_ERROR (106), nothing new."""
    t.entities.need_resource_string()
    response = t.srv.SpawnEntity.Response
    request = t.entities.spawn_request(t.entities.new_name(), t.entities.slot(0),
                                       resource='hello, this is no model')
    _refused(t, request, (response.UNSUPPORTED_FORMAT, response.RESOURCE_PARSE_ERROR),
             'SpawnEntity of plain text')


@clause(CLAUSES, 'SPAWN-17', 'the stamp of initial_pose is ignored', (SPAWNING,),
        'SpawnEntity.srv', 'The timestamp field in the header is ignored.', services=LISTED)
def spawn_stamp_ignored(t: Target) -> None:
    """Stamped a day ahead: OK and listed."""
    name = t.entities.new_name()
    request = t.entities.spawn_request(name, t.entities.slot(0), stamp=(86_400, 5))
    got = t.entities.spawn_call(request, doing='SpawnEntity stamped a day ahead').entity_name
    _listed(t, got, 'SpawnEntity stamped a day ahead')


# -- BATCH: SpawnEntities ---------------------------------------------------------------

def _member(t: Target, name: str, index: int, empty: bool = False) -> Any:
    msg = t.msg.SpawnEntity(name=name, allow_renaming=False)
    if not empty:
        uri, resource = t.entities.source(name)
        msg.entity_resource = t.msg.Resource(uri=uri, resource_string=resource)
    x, y, z = t.entities.slot(index)
    position = msg.initial_pose.pose.position
    position.x, position.y, position.z = x, y, z
    msg.initial_pose.pose.orientation.w = 1.0
    return msg


def _batch(t: Target, members: Sequence[Any], doing: str) -> Any:
    reply = t.call('SpawnEntities', t.srv.SpawnEntities.Request(spawn_requests=members))
    for result in reply.results:
        if result.result.result == t.msg.Result.RESULT_OK and result.entity_name:
            t.entities.spawned.append(result.entity_name)
    if len(reply.results) != len(members):
        raise ClauseFailed(f'{doing}: {len(reply.results)} results for {len(members)} requests')
    return reply


def _codes(t: Target, reply: Any) -> List[str]:
    return [t.code_name('SpawnEntity', r.result.result) for r in reply.results]


BATCH_QUOTE = ('ENTITIES_SPAWN_FAILED = 150 # There was at least one failed spawn request. Check '
               'individual results in the `results`.')


@clause(CLAUSES, 'BATCH-01', 'two good requests: OK, one result each, in order, both listed',
        ('SPAWNING_ENTITIES',), 'SpawnEntities.srv',
        'SpawnResult[] results # List of results for each spawn request.', services=LISTED)
def batch_ok(t: Target) -> None:
    """Two boxes: OK, two OK results naming them in order, both in GetEntities."""
    a, b = t.entities.new_name(), t.entities.new_name()
    reply = _batch(t, [_member(t, a, 0), _member(t, b, 1)], 'SpawnEntities of two')
    if reply.result.result != t.msg.Result.RESULT_OK:
        raise ClauseFailed(f'SpawnEntities of two good requests: '
                           f'{t.describe("SpawnEntities", reply)}')
    names = [r.entity_name for r in reply.results]
    if names != [a, b] or any(r.result.result != t.msg.Result.RESULT_OK for r in reply.results):
        raise ClauseFailed(f'results {list(zip(names, _codes(t, reply)))} for {[a, b]}')
    listed = t.entities.names()
    if a not in listed or b not in listed:
        raise ClauseFailed(f'{a} and {b} are not both listed after SpawnEntities')


@clause(CLAUSES, 'BATCH-02', 'a failed request: ENTITIES_SPAWN_FAILED with each request\'s result',
        ('SPAWNING_ENTITIES',), 'SpawnEntities.srv', BATCH_QUOTE)
def batch_failed(t: Target) -> None:
    """Spawn a good box and one of no resource: 150, results OK and NO_RESOURCE."""
    good, bad = t.entities.new_name(), t.entities.new_name()
    reply = _batch(t, [_member(t, good, 0), _member(t, bad, 1, empty=True)],
                   'SpawnEntities with a bad request')
    if reply.result.result != t.srv.SpawnEntities.Response.ENTITIES_SPAWN_FAILED:
        raise ClauseFailed(f'a batch with a bad request answered '
                           f'{t.describe("SpawnEntities", reply)}, not ENTITIES_SPAWN_FAILED')
    codes = [r.result.result for r in reply.results]
    wanted = [t.msg.Result.RESULT_OK, t.msg.SpawnResult.NO_RESOURCE]
    if codes != wanted:
        raise ClauseFailed(f'results {_codes(t, reply)}, expected OK and NO_RESOURCE')


@clause(CLAUSES, 'BATCH-03', 'the good requests of a failed batch are spawned',
        ('SPAWNING_ENTITIES',), 'SpawnEntities.srv', BATCH_QUOTE, services=LISTED)
def batch_keeps_good(t: Target) -> None:
    """Spawn a bad request, then a good box: the good one is listed afterwards."""
    bad, good = t.entities.new_name(), t.entities.new_name()
    _batch(t, [_member(t, bad, 0, empty=True), _member(t, good, 1)], 'SpawnEntities')
    if good not in t.entities.names():
        raise ClauseFailed(f'{good}, a good request beside a bad one, was not spawned')


@clause(CLAUSES, 'BATCH-04', 'one name twice in a batch: the second is NAME_NOT_UNIQUE',
        ('SPAWNING_ENTITIES',), 'SpawnResult.msg', 'NAME_NOT_UNIQUE = 101 # Given name is already '
        'taken by entity and allow_renaming is false.')
def batch_same_name(t: Target) -> None:
    """Two requests for one name without renaming: OK, then NAME_NOT_UNIQUE."""
    name = t.entities.new_name()
    reply = _batch(t, [_member(t, name, 0), _member(t, name, 1)],
                   'SpawnEntities of one name twice')
    codes = [r.result.result for r in reply.results]
    if codes != [t.msg.Result.RESULT_OK, t.msg.SpawnResult.NAME_NOT_UNIQUE]:
        raise ClauseFailed(f'results {_codes(t, reply)}, expected OK and NAME_NOT_UNIQUE')


# -- DELETE ------------------------------------------------------------------------------

@clause(CLAUSES, 'DELETE-01', 'a deleted entity is no longer listed', ('DELETING', SPAWNING),
        'DeleteEntity.srv', 'Remove an entity (a robot, other object) from the simulation.',
        services=LISTED)
def deleted_gone(t: Target) -> None:
    """Spawn, delete: OK, and GetEntities no longer lists it."""
    name = t.entities.spawn(0)
    t.entities.delete(name)
    if name in t.entities.names():
        raise ClauseFailed(f'{name} is still listed after DeleteEntity')


@clause(CLAUSES, 'DELETE-02', 'deleting one entity leaves the others', ('DELETING', SPAWNING),
        'DeleteEntity.srv', 'string entity # Entity identified by its unique name with a '
        'namespace, as returned by SpawnEntity or GetEntities.', services=LISTED)
def delete_one(t: Target) -> None:
    """Spawn A and B, delete A: B and everything else still listed."""
    before = set(t.entities.names())
    a, b = t.entities.spawn(0), t.entities.spawn(1)
    t.entities.delete(a)
    lost = sorted((before | {b}) - set(t.entities.names()))
    if lost:
        raise ClauseFailed(f'deleting {a} also removed {lost[:5]}')


# -- SPAWNABLES ----------------------------------------------------------------------------

SPAWNABLES_QUOTE = ('Return a list of resources which are valid as SpawnEntity uri fields (e.g. '
                    'visible to or registered in simulator).')


def _spawnables(t: Target, sources: Sequence[str] = ()) -> Any:
    return t.ok('GetSpawnables', t.srv.GetSpawnables.Request(sources=list(sources)),
                'GetSpawnables')


@clause(CLAUSES, 'SPAWNABLES-01', 'GetSpawnables lists URIs', ('SPAWNABLES',), 'GetSpawnables.srv',
        SPAWNABLES_QUOTE)
def spawnable_uris(t: Target) -> None:
    """Every spawnable has a uri."""
    empty = [i for i, s in enumerate(_spawnables(t).spawnables) if not s.uri.strip()]
    if empty:
        raise ClauseFailed(f'spawnables {empty[:5]} have no uri')


@clause(CLAUSES, 'SPAWNABLES-02', 'an unknown source is named in error_message, not a failure',
        ('SPAWNABLES',), 'GetSpawnables.srv', 'Unrecognized values are listed as such in the '
        'result.error_message, but do not hinder success of the response.')
def unknown_source(t: Target) -> None:
    """Source 'conformance://no/such/source': OK, and the message names it."""
    source = 'conformance://no/such/source'
    reply = _spawnables(t, [source])
    if source not in reply.result.error_message:
        raise ClauseFailed(f'the unknown source is not in error_message '
                           f'({reply.result.error_message[:120]!r})')


@clause(CLAUSES, 'SPAWNABLES-03', 'a listed spawnable can be spawned', ('SPAWNABLES', SPAWNING),
        'GetSpawnables.srv', SPAWNABLES_QUOTE, services=LISTED)
def spawnable_spawns(t: Target) -> None:
    """Spawn --asset if listed, else the first box or cube, else the first: OK, listed."""
    uris = [s.uri for s in _spawnables(t).spawnables if s.uri.strip()]
    if not uris:
        raise ClauseSkipped('GetSpawnables lists nothing')
    boxes = [u for u in uris if 'box' in u.lower() or 'cube' in u.lower()]
    uri = t.options.asset if t.options.asset in uris else (boxes or uris)[0]
    name = t.entities.new_name('spawnable')
    got = t.entities.spawn_call(t.entities.spawn_request(name, t.entities.slot(0), uri=uri),
                                doing=f'SpawnEntity of the listed {uri}').entity_name
    _listed(t, got, f'SpawnEntity of {uri}')
