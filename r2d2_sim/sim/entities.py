"""
The world's entities as the simulation standard sees them: list, read, place, spawn, delete.

No ROS here: :mod:`r2d2_sim.ros.standard.entities` translates these
operations into ``simulation_interfaces`` services, through the core's
:class:`~r2d2_sim.sim.simulation.Simulation`, which decides whether a spawn
is a driven robot. Entities are the world's bodies by their unique names: the
robots, the ground plane, ``extra_models``, the ``world`` model and whatever
was spawned. Every refusal is a :class:`~r2d2_sim.errors.RefusedError` whose
``code`` says which of the standard's results it is, with a one-line message
that never quotes a file; what a spawn may load is checked in
:mod:`r2d2_sim.sim.spawnables`.
"""

import math
from typing import Callable, Dict, List, Mapping, NamedTuple, Optional, Sequence, Tuple, \
    TYPE_CHECKING

from r2d2_sim.errors import RefusedError, WorldError
from r2d2_sim.model.health import MAX_ANGULAR_SPEED_RAD_S, MAX_DISTANCE_M, MAX_LINEAR_SPEED_M_S
from r2d2_sim.model.transforms import BaseState, compose, quaternion_multiply, rotate, Transform
from r2d2_sim.sim.names import entity_name, MAX_NAME_LENGTH, NAME
from r2d2_sim.sim.bounds import body_box, body_meets, check_region, Region
from r2d2_sim.sim.sdf.loading import SdfSettings
from r2d2_sim.sim.spawnables import Closable, directory_spawnables, read_spawnable, Spawnable
from r2d2_sim.sim.tags import check_description_text, check_tags

if TYPE_CHECKING:  # typing only: the testing API imports this module without PyBullet
    from r2d2_sim.physics.body import Body
    from r2d2_sim.physics.world import SimWorld

__all__ = ['Category', 'EntityInfo', 'SpawnRequest', 'Spawned', 'Entities', 'check_pose',
           'name_filter', 'MAX_SPAWNED', 'MAX_NAME_LENGTH', 'MAX_FILTER_LENGTH', 'NAME']

MAX_SPAWNED = 100
# A name filter as long as a request may make it: every name is matched against
# every filter a peer sends (names are at most names.MAX_NAME_LENGTH).
MAX_FILTER_LENGTH = 1000
# What RE2 may take to compile one filter (bytes); a bigger program is refused.
FILTER_MEMORY_BYTES = 8 << 20
# A unit quaternion, give or take rounding in a client's arithmetic.
QUATERNION_NORM_TOLERANCE = 1e-3


class Category:
    """The standard's entity categories (simulation_interfaces/EntityCategory)."""

    OBJECT = 0
    ROBOT = 1
    HUMAN = 2
    DYNAMIC_OBJECT = 4
    STATIC_OBJECT = 5
    ALL = (OBJECT, ROBOT, HUMAN, DYNAMIC_OBJECT, STATIC_OBJECT)


class EntityInfo(NamedTuple):
    """
    What the standard's EntityInfo says of an entity, as set (None: what the entity is).

    ``category`` None is the category the entity has by what it is (a driven
    robot, a static or a moving body); ``description`` None is where it came
    from. SetEntityInfo sets all three; a full reset gives a start-up entity
    back the info it started with.
    """

    category: Optional[int] = None
    description: Optional[str] = None
    tags: Tuple[str, ...] = ()


class SpawnRequest(NamedTuple):
    """
    One spawn as the standard asks it: what, where, named how, and driven or not.

    ``uri`` wins over ``resource_string`` (a URDF's text). The pose is of the
    URDF's base link in ``frame_id`` ('' or the world frame, or an entity's
    name), exactly. With a ``namespace`` the entity is a driven robot with
    every interface a robot has, there.
    """

    name: str = ''
    allow_renaming: bool = False
    uri: str = ''
    resource_string: str = ''
    namespace: str = ''
    frame_id: str = ''
    # Any sequences, as a caller in Python gives them: check_pose takes 3 and 4 numbers or refuses.
    position: Sequence[float] = (0.0, 0.0, 0.0)
    orientation: Sequence[float] = (0.0, 0.0, 0.0, 1.0)


class Spawned(NamedTuple):
    """A spawn's outcome: the body, the URDF text it was loaded from, what was not simulated."""

    body: 'Body'
    text: str
    notes: str


def _finite(*vectors: Sequence[float]) -> bool:
    return all(math.isfinite(v) for vector in vectors for v in vector)


def name_filter(pattern: str) -> Callable[[str], bool]:
    """
    Return whether a name matches ``pattern`` (a part of it: a search), as a function.

    The standard's filters are POSIX extended regular expressions from any
    peer, so they run on RE2, whose time is linear in the name's length:
    Python's backtracking engine takes exponential time on ``(a+)+c`` and
    holds the interpreter meanwhile. RefusedError OPERATION_FAILED for a
    pattern longer than MAX_FILTER_LENGTH, one RE2 refuses, or without RE2.
    """
    if not pattern:
        return lambda name: True
    if len(pattern) > MAX_FILTER_LENGTH:
        raise RefusedError('OPERATION_FAILED', f'the filter is longer than {MAX_FILTER_LENGTH} '
                                               'characters')
    try:
        import re2
    except ImportError:
        raise RefusedError('OPERATION_FAILED', 'name filters need RE2: pip install '
                                               'google-re2') from None
    options = re2.Options()
    options.log_errors = False  # one stderr line per bad pattern a peer sends, otherwise
    options.never_capture = True
    options.max_mem = FILTER_MEMORY_BYTES
    try:
        compiled = re2.compile(pattern, options)
    except re2.error as exc:
        reason = exc.args[0].decode('utf-8', 'replace') if exc.args and isinstance(
            exc.args[0], bytes) else str(exc)
        raise RefusedError('OPERATION_FAILED', f'bad filter regex: {reason[:200]}') from None
    return lambda name: compiled.search(name) is not None


def check_pose(position: Sequence[float], orientation: Sequence[float]) -> Transform:
    """
    Return the pose, its orientation normalised; INVALID_POSE for a NaN or a non-unit quaternion.

    Also for a position beyond the blow-up check's bound (10 km): a robot put
    there would be reset as blown up at its next measurement; and for other
    than 3 numbers and 4 (a caller in Python may give any sequence).
    """
    if len(position) != 3 or len(orientation) != 4:
        raise RefusedError('INVALID_POSE', f'a pose is 3 numbers of position and 4 of '
                           f'orientation, not {len(position)} and {len(orientation)}')
    if not _finite(position, orientation):
        raise RefusedError('INVALID_POSE', 'the pose has a value that is not finite')
    if max(map(abs, position)) > MAX_DISTANCE_M:
        raise RefusedError('INVALID_POSE', f'the position is more than {MAX_DISTANCE_M:g} m '
                           'from the origin')
    norm = math.sqrt(sum(q * q for q in orientation))
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise RefusedError('INVALID_POSE', f'the orientation is not a unit quaternion '
                           f'(norm {norm:.6g})')
    x, y, z = position
    qx, qy, qz, qw = orientation
    return Transform((x, y, z), (qx / norm, qy / norm, qz / norm, qw / norm))


class Entities:
    """
    The bodies of a :class:`~r2d2_sim.physics.world.SimWorld` as the standard's entities.

    Found by name, read and placed in ``world_frame_id`` (or another
    entity's frame), spawned from a :class:`SpawnRequest` and deleted. The
    :class:`~r2d2_sim.sim.simulation.Simulation` wraps them: it knows which
    entities are robots.
    """

    def __init__(self, world: 'SimWorld', world_frame_id: str,
                 sdf: SdfSettings = SdfSettings()) -> None:
        self._world = world
        self.world_frame_id = world_frame_id
        self.sdf = sdf  # where SDF models are found, what they are compared with
        self._files: Dict[str, Closable] = {}  # spawned from text, by entity name
        self._info: Dict[str, EntityInfo] = {}        # as set, by entity name
        # Frames a request may name beside the entities: the world's named poses.
        self.named_frames: Dict[str, Transform] = {}

    def names(self) -> List[str]:
        """Return every entity's name, in the order the world loaded them."""
        return list(self._world.bodies)

    def body(self, name: str) -> 'Body':
        """Return the entity named ``name``; RefusedError NOT_FOUND listing the others."""
        body = self._world.bodies.get(name)
        if body is None:
            raise RefusedError('NOT_FOUND', f'no entity named {name!r}; the world has: '
                                            f'{", ".join(self._world.bodies)}')
        return body

    def state(self, name: str) -> BaseState:
        """Return the pose of the entity's URDF base link and its origin's twist, in the world."""
        body = self.body(name)
        position, orientation = body.link_pose(-1)
        moving = body.world_state()  # the same origin: the body frame only turns by a yaw
        return BaseState(position, orientation, moving.linear_velocity,
                         moving.angular_velocity)

    def frame_pose(self, frame_id: str) -> Transform:
        """
        Return the world pose of a frame a request names: '' or the world, an entity, a named pose.

        An entity's name wins over a named pose's (an entity may be named
        after a named pose at any time; the world's poses are fixed).
        """
        if frame_id in ('', 'world', self.world_frame_id):
            return Transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        if frame_id in self._world.bodies:
            state = self.state(frame_id)
            return Transform(state.position, state.orientation)
        if frame_id in self.named_frames:
            return self.named_frames[frame_id]
        raise RefusedError('INVALID_POSE', f'unknown frame {frame_id[:100]!r}: give world, an '
                                           'entity\'s name or a named pose\'s')

    def set_state(self, name: str, frame_id: str, position: Sequence[float],
                  orientation: Sequence[float], linear: Sequence[float],
                  angular: Sequence[float], acceleration: Sequence[float] = ()) -> 'Body':
        """
        Place the entity's base link at a pose and with a twist, both in ``frame_id``.

        ``frame_id`` is '' or the world frame, or an entity's name: the pose is
        then relative to that entity's base link, and the twist's axes are its
        axes (``EntityState.msg``: "observed in the frame specified by
        header.frame_id"), turned into the world's here. The twist is always
        applied (the Jazzy request has no flags): a pose-only request stops
        the body. A static body may not move. Returns the body placed.
        ``acceleration`` (linear then angular, empty for none) is checked, not
        applied ("the acceleration field may be ignored by simulators"): the
        physics gives a body its acceleration. Not finite is INVALID_POSE, as
        a twist; not zero for a static body OPERATION_FAILED, as the standard asks.
        """
        body = self.body(name)
        placed = check_pose(position, orientation)
        if not _finite(linear, angular):
            raise RefusedError('INVALID_POSE', 'the twist has a value that is not finite')
        if not _finite(acceleration):
            raise RefusedError('INVALID_POSE', 'the acceleration has a value that is not finite')
        speed, spin = math.hypot(*linear), math.hypot(*angular)
        if speed >= MAX_LINEAR_SPEED_M_S or spin >= MAX_ANGULAR_SPEED_RAD_S:
            # What a robot's health check takes for a blow-up: any other body would step
            # to NaN and stay there (only robots are put back).
            raise RefusedError('INVALID_POSE', f'the twist ({speed:g} m/s, {spin:g} rad/s) is '
                               f'not below {MAX_LINEAR_SPEED_M_S:g} m/s and '
                               f'{MAX_ANGULAR_SPEED_RAD_S:g} rad/s')
        if body.static and any(v != 0.0 for v in (*linear, *angular)):
            raise RefusedError('OPERATION_FAILED', f'{name} is static: it takes a pose, '
                                                   'not a twist')
        if body.static and any(v != 0.0 for v in acceleration):
            raise RefusedError('OPERATION_FAILED', f'{name} is static: it takes a pose, '
                                                   'not an acceleration')
        frame = self.frame_pose(frame_id)
        pose = compose(frame, placed)
        yaw = body.body_yaw_offset_rad
        turn = (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))
        from r2d2_sim.physics.crowding import check_crowding  # PyBullet: imported when used
        before = body.moment()
        body.set_world_state(pose.translation, quaternion_multiply(pose.rotation, turn),
                             rotate(frame.rotation, linear), rotate(frame.rotation, angular))
        try:  # into a crowd of moving bodies: put back where it was, and refused
            check_crowding(self._world.client, list(self._world.bodies.values()), [body],
                           'INVALID_POSE', f'{name} at that pose')
        except RefusedError:
            body.resume(before)
            raise
        return body

    def read(self, request: SpawnRequest) -> Spawnable:
        """
        Read what a spawn request loads, checked, without touching the physics: a Spawnable.

        The slow part of a spawn (files, an SDF model's includes and meshes
        converted, a URDF written): a caller may do it outside the simulator's
        lock and hand the result to :meth:`spawn`, which closes it. RefusedError
        with the standard's codes (see :func:`~r2d2_sim.sim.spawnables.read_spawnable`).
        """
        return read_spawnable(request.uri, request.resource_string, self.sdf)

    def listed(self, source: str) -> Optional[List[str]]:
        """Return the model files of a directory a spawn takes by path (directory_spawnables)."""
        return directory_spawnables(source, self.sdf)

    def spawn(self, request: SpawnRequest, *, flags: int = 0,
              body_yaw_offset_rad: float = 0.0,
              spawnable: Optional[Spawnable] = None,
              usable: Callable[[str], bool] = lambda name: True) -> Spawned:
        """
        Load a URDF or an SDF model at a pose (of its base link, or SDF model frame, exactly).

        Returns the body, its description's text and what an SDF model does
        not simulate (no ground clearance added). Named ``request.name``,
        or the URDF's robot name when empty; a taken or invalid name is
        refused unless ``allow_renaming`` (then ``_1``, ``_2``..., the first
        free one that is also ``usable``: a robot's frames free). A body
        that can fall, at a pose off the ground plane, is INVALID_POSE (it would
        fall for ever: ``SimWorld.off_ground``). ``flags`` go to loadURDF (a
        driven robot's: true cylinders, inertias from the file);
        ``body_yaw_offset_rad`` turns its body frame from the
        URDF base (a robot that drives along its base y). ``spawnable`` is
        the request read beforehand (:meth:`read`), else it is read here; it
        is closed when the spawn is refused.
        """
        try:
            if sum(body.spawned for body in self._world.bodies.values()) >= MAX_SPAWNED:
                raise RefusedError('OPERATION_FAILED', f'{MAX_SPAWNED} entities are spawned '
                                                       'already: delete some first')
            pose = compose(self.frame_pose(request.frame_id),
                           check_pose(request.position, request.orientation))
        except RefusedError:
            if spawnable is not None and spawnable.file is not None:
                spawnable.file.close()
            raise
        if spawnable is None:
            spawnable = self.read(request)
        text_file = spawnable.file
        if spawnable.sdf:
            pose = compose(pose, spawnable.base)
        try:
            name = self._name(request.name or spawnable.name, request.allow_renaming, usable)
            body = self._world.load(
                spawnable.path, pose.translation, pose.rotation, name=name, spawned=True,
                source=request.uri or 'resource_string',
                flags=flags | (self._world.model_flags if spawnable.sdf else 0),
                body_yaw_offset_rad=body_yaw_offset_rad,
                made_from=f'SDF model {spawnable.name} of '
                f'{request.uri[:200] or "the resource_string"}' if spawnable.sdf else None,
                given_as=None if request.uri else 'the resource_string')
            if spawnable.sdf and not flags:
                body.free_joints()  # a model's joints move as Gazebo's do; a robot drives its own
            from r2d2_sim.physics.crowding import check_crowding  # PyBullet, when used
            x, y, _ = pose.translation
            off = None if body.static else self._world.off_ground(x, y)
            try:  # too many moving links, or into a crowd of moving bodies: taken out again
                if off is not None:  # it would fall for ever, unnoticed
                    raise RefusedError('INVALID_POSE', f'{name} at x {x:g}, y {y:g} would be '
                                                       f'{off} and fall for ever')
                check_crowding(self._world.client, list(self._world.bodies.values()), [body],
                               'INVALID_POSE', f'{name} at that pose')
            except RefusedError:
                self._world.remove(body)
                raise
        except (RefusedError, WorldError) as exc:
            if text_file is not None:
                text_file.close()
            if isinstance(exc, WorldError):
                raise RefusedError('RESOURCE_PARSE_ERROR', str(exc)) from None
            raise
        if text_file is not None:
            self._files[name] = text_file
        return Spawned(body, spawnable.text, spawnable.notes)

    def _name(self, wanted: str, allow_renaming: bool, usable: Callable[[str], bool]) -> str:
        if not allow_renaming and len(wanted) > MAX_NAME_LENGTH:
            raise RefusedError('NAME_INVALID', f'an entity name is at most {MAX_NAME_LENGTH} '
                                               f'characters, not {len(wanted)}')
        if not allow_renaming and not NAME.match(wanted):
            raise RefusedError('NAME_INVALID', f'{wanted[:100]!r} is not a valid entity '
                               'name (letters, digits, _ and -)')
        wanted = entity_name(wanted)  # valid already, or renaming allowed
        if not allow_renaming:
            if wanted in self._world.bodies:
                raise RefusedError('NAME_NOT_UNIQUE', f'an entity named {wanted!r} exists')
            return wanted
        return self._world.unique_name(wanted, usable)

    def delete(self, name: str) -> None:
        """Remove an entity, spawned or there at start-up (a full reset brings those back)."""
        self._world.remove(self.body(name))
        self.dropped(name)

    def dropped(self, name: str) -> None:
        """Forget what an entity that left the world held (its info, the file of its text)."""
        self._info.pop(name, None)
        text_file = self._files.pop(name, None)
        if text_file is not None:
            text_file.close()

    def source(self, name: str) -> str:
        """Return where an entity's description came from (a path, a URI, 'resource_string')."""
        return self.body(name).source

    def category(self, name: str) -> int:
        """Return an entity's category: as set (a robot: ROBOT), else STATIC_ or DYNAMIC_OBJECT."""
        info = self._info.get(name)
        body = self.body(name)
        if info is not None and info.category is not None:
            return info.category
        return Category.STATIC_OBJECT if body.static else Category.DYNAMIC_OBJECT

    def info(self, name: str) -> EntityInfo:
        """Return GetEntityInfo's answer: category, description (as set, else the source), tags."""
        info = self._info.get(name, EntityInfo())
        description = info.description if info.description is not None else self.source(name)
        return EntityInfo(self.category(name), description, info.tags)

    def tags(self, name: str) -> Tuple[str, ...]:
        """Return an entity's tags."""
        self.body(name)
        return self._info.get(name, EntityInfo()).tags

    def mark(self, name: str, info: EntityInfo) -> None:
        """Give an entity the info it starts with (a robot's category, its tags)."""
        self.body(name)
        self._info[name] = info

    def set_info(self, name: str, category: int, description: str,
                 tags: Sequence[str]) -> None:
        """
        Set an entity's info, all of it (SetEntityInfo overrides the current values).

        The category is a label: it changes what GetEntityInfo and the
        category filter say, not how the entity moves. OPERATION_FAILED for
        an unknown category, a description or tags beyond their bounds; the
        info stays as it was then.
        """
        self.body(name)
        if category not in Category.ALL:
            raise RefusedError('OPERATION_FAILED', f'unknown entity category {category}: one of '
                                                   f'{", ".join(map(str, Category.ALL))}')
        description = check_description_text(description, 'the description')
        self._info[name] = EntityInfo(category, description,
                                      check_tags(tags, 'the entity\'s tags'))

    def restore_info(self, infos: Mapping[str, EntityInfo]) -> None:
        """Forget every info set; give the entities named in ``infos`` theirs (a full reset)."""
        self._info = {name: info for name, info in infos.items() if name in self._world.bodies}

    def overlapping(self, region: Region) -> List[str]:
        """Return the entities whose collision shape meets a region (the standard's bounds)."""
        region = check_region(region)
        return [name for name, body in self._world.bodies.items() if body_meets(body, region)]

    def bounds(self, name: str) -> Region:
        """Return the box around an entity's collision shape, in its base link's frame."""
        return Region.box(*body_box(self.body(name)))

    def delete_spawned(self) -> None:
        """Remove every spawned entity (ResetSimulation's SPAWNED scope)."""
        for name, body in list(self._world.bodies.items()):
            if body.spawned:
                self.delete(name)

    def close(self) -> None:
        """Delete the temporary files of entities spawned from text."""
        for text_file in self._files.values():
            text_file.close()
        self._files.clear()
