"""ENTITY: listing, reading and placing entities, frames, info; BOUNDS: GetEntityBounds."""

import math
from typing import Any, List, Sequence, Tuple

from r2d2_sim.conformance.clause import Clause, clause, ClauseFailed, ClauseSkipped
from r2d2_sim.conformance.entity_verbs import BOX_SIZE_M, Point
from r2d2_sim.conformance.target import Target
from r2d2_sim.conformance.values import (
    close, fmt, quaternion, same_rotation, vector, yaw_quaternion)

CLAUSES: List[Clause] = []

SET, PAUSE = 'SIMULATION_STATE_SETTING', 'SIMULATION_STATE_PAUSE'
GETTING, SETTING = 'ENTITY_STATE_GETTING', 'ENTITY_STATE_SETTING'
MOVE = ('SPAWNING', SETTING, GETTING, SET, PAUSE)
LISTED = ('GetEntities',)
# At most this many entities are read one by one (a big world has thousands).
SAMPLE = 20
FRAME_QUOTE = ('std_msgs/Header header # Reference frame and timestamp for pose and twist. Empty '
               'frame defaults to world.')
TWIST_QUOTE = ('geometry_msgs/Twist twist # Ground truth linear and angular velocities '
               'observed in the frame specified by header.frame_id')
INVALID_POSE_QUOTE = ('INVALID_POSE = 101 # initial_pose is invalid, such as when the quaternion '
                      'is invalid or position exceeds simulator world bounds.')
CATEGORIES = (0, 1, 2, 4, 5)


def _world_frames(t: Target) -> Tuple[str, str, str]:
    return ('', 'world', t.options.world_frame)


@clause(CLAUSES, 'ENTITY-01', 'GetEntities lists unique names', (), 'GetEntities.srv',
        'string[] entities # Unique names of all entities matching the filters.', services=LISTED)
def unique_names(t: Target) -> None:
    """No name twice, none empty."""
    names = t.entities.names()
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice or '' in names:
        raise ClauseFailed(f'GetEntities lists {twice[:5] or "an empty name"} more than once'
                           if twice else 'GetEntities lists an empty name')


@clause(CLAUSES, 'ENTITY-02', 'GetEntitiesStates gives one state per entity GetEntities lists',
        (GETTING,), 'GetEntitiesStates.srv', 'EntityState[] states # States for these entities.',
        services=LISTED)
def states_aligned(t: Target) -> None:
    """Compare the arrays: as long as each other, naming what GetEntities names."""
    names = t.entities.names()
    reply = t.ok('GetEntitiesStates', t.srv.GetEntitiesStates.Request(), 'GetEntitiesStates')
    if len(reply.entities) != len(reply.states):
        raise ClauseFailed(f'{len(reply.entities)} entities but {len(reply.states)} states')
    if sorted(reply.entities) != sorted(names):
        raise ClauseFailed(f'GetEntitiesStates names {sorted(reply.entities)[:5]}, GetEntities '
                           f'{sorted(names)[:5]}')


@clause(CLAUSES, 'ENTITY-03', 'GetEntityState answers in the world frame', (GETTING,),
        'EntityState.msg', FRAME_QUOTE, services=LISTED)
def state_in_world(t: Target) -> None:
    """Every entity's state (up to 20) has frame_id '' or the world's."""
    for name in t.entities.names()[:SAMPLE]:
        frame = t.entities.state(name).header.frame_id
        if frame not in _world_frames(t):
            raise ClauseFailed(f'the state of {name} is in frame {frame!r}, not the world '
                               '(give --world-frame if the world frame has another name)')


@clause(CLAUSES, 'ENTITY-04', 'GetEntityState and GetEntitiesStates agree', (GETTING, SET, PAUSE),
        'GetEntitiesStates.srv', 'EntityState[] states # States for these entities.')
def states_agree(t: Target) -> None:
    """
    Paused, each entity's pose is the same from both services: the kit's own first.

    Where it may spawn, the kit puts three boxes at distinct places, so that
    a state given to the wrong entity shows (start-up entities often share
    one place); then up to 20 of the others.
    """
    t.sim.pause()
    t.undo.on_cleanup(t.sim.stop)
    own = [t.entities.spawn(i, yaw=0.3 * i) for i in range(3)] if t.declared('SPAWNING') else []
    reply = t.ok('GetEntitiesStates', t.srv.GetEntitiesStates.Request(), 'GetEntitiesStates')
    pairs = list(zip(reply.entities, reply.states))
    mine = [(name, state) for name, state in pairs if name in own]
    if len(mine) != len(own):
        raise ClauseFailed(f'GetEntitiesStates lists {len(mine)} of the {len(own)} entities the '
                           f'kit spawned ({", ".join(own)})')
    for name, state in mine + [(n, s) for n, s in pairs if n not in own][:SAMPLE]:
        one = t.entities.state(name)
        a = vector(one.pose.position) + quaternion(one.pose.orientation)
        b = vector(state.pose.position) + quaternion(state.pose.orientation)
        if not close(a, b, 1e-6):
            raise ClauseFailed(f'{name}: GetEntityState {fmt(a)}, GetEntitiesStates {fmt(b)}')


def _expect_pose(t: Target, name: str, position: Point, orientation: Sequence[float],
                 doing: str) -> None:
    state = t.entities.state(name)
    got_p, got_q = vector(state.pose.position), quaternion(state.pose.orientation)
    if state.header.frame_id not in _world_frames(t):
        raise ClauseFailed(f'after {doing}, {name} is read in frame {state.header.frame_id!r}')
    if not close(got_p, position) or not same_rotation(got_q, orientation):
        raise ClauseFailed(f'after {doing}, {name} is at {fmt(got_p)} {fmt(got_q)}, expected '
                           f'{fmt(position)} {fmt(orientation)}')


def _expect_twist(t: Target, name: str, linear: Point, angular: Point, doing: str) -> None:
    twist = t.entities.state(name).twist
    got = vector(twist.linear) + vector(twist.angular)
    if not close(got, tuple(linear) + tuple(angular)):
        raise ClauseFailed(f'after {doing}, {name} moves at {fmt(got)} (linear, angular), '
                           f'expected {fmt(tuple(linear) + tuple(angular))}')


def _paused_box(t: Target, index: int = 0, yaw: float = 0.0) -> str:
    t.sim.pause()
    t.undo.on_cleanup(t.sim.stop)
    return t.entities.spawn(index, yaw=yaw)


@clause(CLAUSES, 'ENTITY-05', 'SetEntityState places an entity; GetEntityState reads it there',
        MOVE, 'SetEntityState.srv', 'Set a state of an object, which will result in an instant '
        'change in its pose and/or twist.')
def place_and_read(t: Target) -> None:
    """Paused: move the kit's box and turn it; its state reads that pose."""
    name = _paused_box(t)
    x, y, z = t.entities.slot(0)
    position, orientation = (x + 0.5, y - 0.7, z + 0.3), yaw_quaternion(0.6)
    t.entities.place(name, position, orientation)
    _expect_pose(t, name, position, orientation, 'SetEntityState')


@clause(CLAUSES, 'ENTITY-06', 'a twist set in the world frame reads back in the world frame',
        MOVE, 'EntityState.msg', TWIST_QUOTE)
def twist_in_world(t: Target) -> None:
    """Give a box turned 90 degrees 1 m/s along world x: its twist reads x, not its own -y."""
    name = _paused_box(t, yaw=math.pi / 2)
    t.entities.place(name, t.entities.slot(0), yaw_quaternion(math.pi / 2),
                     linear=(1.0, 0.0, 0.0), angular=(0.0, 0.0, 0.5))
    _expect_twist(t, name, (1.0, 0.0, 0.0), (0.0, 0.0, 0.5), 'a world-frame SetEntityState')


@clause(CLAUSES, 'ENTITY-07', 'a pose in another entity\'s frame is relative to that entity',
        MOVE, 'EntityState.msg', FRAME_QUOTE)
def pose_in_entity_frame(t: Target) -> None:
    """B placed 1 m along x of A, which is turned 90 degrees: B is 1 m along world y of A."""
    a = _paused_box(t, 0, yaw=math.pi / 2)
    b = t.entities.spawn(1)
    t.entities.place(b, (1.0, 0.0, 0.0), frame=a)
    x, y, z = t.entities.slot(0)
    _expect_pose(t, b, (x, y + 1.0, z), yaw_quaternion(math.pi / 2),
                 f'SetEntityState in the frame of {a}')


@clause(CLAUSES, 'ENTITY-08', 'a twist in another entity\'s frame is observed along its axes',
        MOVE, 'EntityState.msg', TWIST_QUOTE)
def twist_in_entity_frame(t: Target) -> None:
    """1 m/s along x of A (turned 90 degrees) reads as 1 m/s along world y."""
    a = _paused_box(t, 0, yaw=math.pi / 2)
    b = t.entities.spawn(1)
    t.entities.place(b, (1.0, 0.0, 0.0), linear=(1.0, 0.0, 0.0), frame=a)
    _expect_twist(t, b, (0.0, 1.0, 0.0), (0.0, 0.0, 0.0), f'SetEntityState in the frame of {a}')


@clause(CLAUSES, 'ENTITY-09', 'the whole state is set: a zero twist stops the entity', MOVE,
        'SetEntityState.srv', 'EntityState state # New state to set immediately.')
def zero_twist_stops(t: Target) -> None:
    """Given 1 m/s, then a pose with a zero twist: it no longer moves."""
    name = _paused_box(t)
    t.entities.place(name, t.entities.slot(0), linear=(1.0, 0.0, 0.0))
    t.entities.place(name, t.entities.slot(0))
    _expect_twist(t, name, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 'a SetEntityState of zero twist')


def _invalid_pose(t: Target, position: Point, orientation: Sequence[float], what: str) -> None:
    name = _paused_box(t)
    before = t.entities.position(name)
    t.expect('SetEntityState', t.entities.set_request(name, position, orientation),
             (t.srv.SetEntityState.Response.INVALID_POSE,), f'SetEntityState with {what}')
    after = t.entities.position(name)
    if not close(before, after):
        raise ClauseFailed(f'the refused SetEntityState moved {name} to {fmt(after)}')


@clause(CLAUSES, 'ENTITY-10', 'a zero quaternion is INVALID_POSE and moves nothing', MOVE,
        'SetEntityState.srv', INVALID_POSE_QUOTE)
def zero_quaternion(t: Target) -> None:
    """Orientation (0, 0, 0, 0): 101, and the entity is where it was."""
    _invalid_pose(t, t.entities.slot(0), (0.0, 0.0, 0.0, 0.0), 'a zero quaternion')


@clause(CLAUSES, 'ENTITY-11', 'a NaN position is INVALID_POSE and moves nothing', MOVE,
        'SetEntityState.srv', INVALID_POSE_QUOTE)
def nan_position(t: Target) -> None:
    """Position (NaN, y, z): 101, and the entity is where it was."""
    x, y, z = t.entities.slot(0)
    _invalid_pose(t, (math.nan, y, z), (0.0, 0.0, 0.0, 1.0), 'a NaN position')


@clause(CLAUSES, 'ENTITY-12', 'a twist or an acceleration for a static entity is '
        'OPERATION_FAILED', (SETTING, GETTING, 'ENTITY_INFO_GETTING'), 'SetEntityState.srv',
        'If non-zero twist or acceleration is requested for static object, the service call '
        'fails and RESULT_OPERATION_FAILED is returned.', services=LISTED)
def static_twist(t: Target) -> None:
    """Give the first STATIC_OBJECT its own pose and 1 m/s, then 1 m/s^2 alone: refused."""
    static = t.msg.EntityCategory.CATEGORY_STATIC_OBJECT
    name = next((n for n in t.entities.names()[:SAMPLE]
                 if t.entities.info(n).category.category == static), None)
    if name is None:
        raise ClauseSkipped('no entity of category STATIC_OBJECT among the first '
                            f'{SAMPLE} listed')
    pose = t.entities.state(name).pose
    request = t.entities.set_request(name, vector(pose.position),
                                     quaternion(pose.orientation), linear=(1.0, 0.0, 0.0))
    t.expect('SetEntityState', request, (t.msg.Result.RESULT_OPERATION_FAILED,),
             f'SetEntityState of the static {name} with a twist')
    request = t.entities.set_request(name, vector(pose.position), quaternion(pose.orientation))
    request.state.acceleration.linear.x = 1.0
    t.expect('SetEntityState', request, (t.msg.Result.RESULT_OPERATION_FAILED,),
             f'SetEntityState of the static {name} with an acceleration and no twist')


@clause(CLAUSES, 'ENTITY-13', 'GetEntityInfo gives each entity a defined category',
        ('ENTITY_INFO_GETTING',), 'EntityInfo.msg',
        'EntityCategory category # Major category for the entity.', services=LISTED)
def defined_categories(t: Target) -> None:
    """Each category (up to 20 entities) is one of EntityCategory's five."""
    for name in t.entities.names()[:SAMPLE]:
        category = t.entities.info(name).category.category
        if category not in CATEGORIES:
            raise ClauseFailed(f'{name} has category {category}, no EntityCategory constant')


@clause(CLAUSES, 'ENTITY-14', 'the stamp in SetEntityState\'s header is ignored', MOVE,
        'SetEntityState.srv', 'EntityState state # New state to set immediately. The timestamp '
        'in header is ignored.')
def stamp_ignored(t: Target) -> None:
    """Place with a stamp a day ahead: OK, and the entity is placed."""
    name = _paused_box(t)
    x, y, z = t.entities.slot(0)
    target = (x, y + 0.5, z)
    t.ok('SetEntityState', t.entities.set_request(name, target, stamp=(86_400, 5)),
         'SetEntityState stamped a day ahead')
    _expect_pose(t, name, target, (0.0, 0.0, 0.0, 1.0), 'a SetEntityState stamped a day ahead')


@clause(CLAUSES, 'ENTITY-15', 'SetEntityInfo\'s category, description and tags read back',
        ('ENTITY_INFO_SETTING', 'ENTITY_INFO_GETTING', 'SPAWNING'), 'SetEntityInfo.srv',
        'EntityInfo info # EntityInfo to set to the entity, which will override its current '
        'values.')
def info_round_trip(t: Target) -> None:
    """Set DYNAMIC_OBJECT, a description and two tags on the kit's box; read the same."""
    name = t.entities.spawn(0)
    info = t.msg.EntityInfo(description='set by the conformance kit',
                            tags=['conformance_a', 'conformance_b'])
    info.category.category = t.msg.EntityCategory.CATEGORY_DYNAMIC_OBJECT
    t.ok('SetEntityInfo', t.srv.SetEntityInfo.Request(entity=name, info=info),
         f'SetEntityInfo of {name}')
    got = t.entities.info(name)
    wanted = (info.category.category, info.description, sorted(info.tags))
    seen = (got.category.category, got.description, sorted(got.tags))
    if seen != wanted:
        raise ClauseFailed(f'GetEntityInfo of {name} reads {seen}, set {wanted}')


# -- BOUNDS -------------------------------------------------------------------------------

def _bounds(t: Target, name: str) -> Any:
    return t.ok('GetEntityBounds', t.srv.GetEntityBounds.Request(entity=name),
                f'GetEntityBounds of {name}').bounds


def check_region(t: Target, bounds: Any, what: str) -> None:
    """Raise ClauseFailed unless the Bounds are of a defined type with its number of points."""
    B = t.msg.Bounds
    count = len(bounds.points)
    wanted = {B.TYPE_EMPTY: count == 0, B.TYPE_BOX: count == 2, B.TYPE_SPHERE: count == 2,
              B.TYPE_CONVEX_HULL: count >= 3}
    if bounds.type not in wanted:
        raise ClauseFailed(f'{what}: bounds of undefined type {bounds.type}')
    if not wanted[bounds.type]:
        raise ClauseFailed(f'{what}: bounds of type {bounds.type} with {count} points')
    if bounds.type == B.TYPE_SPHERE and not bounds.points[1].x > 0.0:
        raise ClauseFailed(f'{what}: a sphere of radius {bounds.points[1].x}')
    if not all(math.isfinite(v) for p in bounds.points for v in vector(p)):
        raise ClauseFailed(f'{what}: bounds with a value that is not finite')


@clause(CLAUSES, 'BOUNDS-01', 'GetEntityBounds gives a region the standard defines',
        ('ENTITY_BOUNDS', 'SPAWNING'), 'Bounds.msg', 'Valid sizes are zero (no bounds), 2 '
        '(sphere or box, depending on type field), and 3 or more (convex hull).')
def valid_bounds(t: Target) -> None:
    """Ask the kit's box's bounds: a defined type with as many points as that type has."""
    name = t.entities.spawn(0)
    check_region(t, _bounds(t, name), f'GetEntityBounds of {name}')


@clause(CLAUSES, 'BOUNDS-02', 'an entity\'s bounds move with it (they are relative to it)',
        ('ENTITY_BOUNDS',) + MOVE, 'Bounds.msg', 'For entities, these limits are relative to '
        'entity\'s canonical link transform, following ROS rep-103 convention.')
def bounds_relative(t: Target) -> None:
    """Move the box 3 m and turn it: the same bounds (a world-aligned box would change)."""
    name = _paused_box(t)
    before = _bounds(t, name)
    t.entities.place(name, t.entities.slot(1), yaw_quaternion(0.7))
    after = _bounds(t, name)
    a = sorted(vector(p) for p in before.points)
    b = sorted(vector(p) for p in after.points)
    if before.type != after.type or len(a) != len(b) or not all(
            close(p, q, 1e-4) for p, q in zip(a, b)):
        raise ClauseFailed(f'the bounds of {name} changed when it moved: {before.type} '
                           f'{[fmt(p) for p in a][:4]} -> {after.type} {[fmt(p) for p in b][:4]}')


def _holds(t: Target, bounds: Any, size: float) -> bool:
    """Return True when Bounds (not empty) hold a cube ``size`` wide centred on the link."""
    B, half, slack = t.msg.Bounds, size / 2.0, 1e-3
    points = [vector(p) for p in bounds.points]
    if bounds.type == B.TYPE_SPHERE:
        reach = math.dist(points[0], (0.0, 0.0, 0.0)) + half * math.sqrt(3.0)
        return reach <= points[1][0] + slack
    # A box, or a hull judged by the box around it.
    low = [min(p[i] for p in points) for i in range(3)]
    high = [max(p[i] for p in points) for i in range(3)]
    return all(lo <= -half + slack and hi >= half - slack for lo, hi in zip(low, high))


def _enclosing_bounds(t: Target, name: str, size: float) -> Any:
    """Return the Bounds of ``name``, a cube ``size`` wide; ClauseFailed unless they hold it."""
    bounds = _bounds(t, name)
    check_region(t, bounds, f'GetEntityBounds of {name}')
    if bounds.type == t.msg.Bounds.TYPE_EMPTY:
        raise ClauseFailed(f'{name}, a {size:g} m box, has empty bounds')
    if not _holds(t, bounds, size):
        raise ClauseFailed(f'the bounds of {name} (type {bounds.type}, '
                           f'{[fmt(vector(p)) for p in bounds.points][:4]}) do not hold a '
                           f'{size:g} m cube centred on its link')
    return bounds


@clause(CLAUSES, 'BOUNDS-03', 'the bounds of each of the kit\'s boxes hold it, and fit it',
        ('ENTITY_BOUNDS', 'SPAWNING'), 'GetEntityBounds.srv', 'Get geometrical bounds for entity.')
def bounds_enclose(t: Target) -> None:
    """
    Spawn a 0.2 m cube and a 0.6 m one: the bounds of each hold it; the small one's, not the big.

    So a region that is the same for every entity (or no bound at all, a
    huge box) fails: an entity's geometrical bounds are its own.
    """
    t.entities.need_resource_string()
    small = t.entities.spawn(0)
    big = t.entities.new_name('big_box')
    big_size = 3 * BOX_SIZE_M
    t.entities.spawn_call(t.entities.spawn_request(
        big, t.entities.slot(1), resource=t.entities.box_text(big, size=big_size)))
    bounds = _enclosing_bounds(t, small, BOX_SIZE_M)
    _enclosing_bounds(t, big, big_size)
    if _holds(t, bounds, big_size):
        raise ClauseFailed(f'the bounds of {small}, a {BOX_SIZE_M:g} m cube, would hold a '
                           f'{big_size:g} m one (type {bounds.type}, '
                           f'{[fmt(vector(p)) for p in bounds.points][:4]}): they are not its own')
