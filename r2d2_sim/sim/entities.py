"""
The world's entities as the simulation standard sees them: list, spawn, move, delete, reset.

No ROS here: :mod:`r2d2_sim.ros.standard.server` translates these operations into
``simulation_interfaces`` services, and the testing API calls them directly.
Entities are the world's bodies by their unique names: the robot, the ground
plane, ``extra_models``, the ``world`` model and whatever was spawned. Every
refusal is an :class:`EntityError` whose ``code`` says which of the
standard's results it is, with a one-line message that never quotes a file.

Spawn requests come from anyone on the ROS domain, so what one may cost is
bounded: the description's size, its links, the bodies spawned, no XML
entities or DOCTYPE (the billion-laughs bomb), and meshes only from the
description's own directory, a ROS package or pybullet_data.
"""

import math
import os
import re
from typing import Callable, Dict, List, NamedTuple, Optional, Sequence, Tuple, TYPE_CHECKING
import xml.etree.ElementTree as ElementTree

import pybullet_data

from r2d2_sim.physics.description import (
    DescriptionError, DescriptionFile, PACKAGE_SCHEME, package_share_directory,
    resolve_description_path)
from r2d2_sim.errors import WorldError
from r2d2_sim.model.health import MAX_DISTANCE_M
from r2d2_sim.model.transforms import compose, quaternion_multiply, Quaternion as Quat, Transform
from r2d2_sim.model.transforms import Vector3 as Vec3

if TYPE_CHECKING:  # typing only: the testing API imports this module without PyBullet
    from r2d2_sim.physics.body import Body

__all__ = ['EntityError', 'Category', 'EntityState', 'Entities', 'MAX_DESCRIPTION_BYTES',
           'MAX_LINKS', 'MAX_SPAWNED']

# What one spawn request may cost (a URDF of R2D2 is 14 kB and 16 links).
MAX_DESCRIPTION_BYTES = 1_000_000
MAX_LINKS = 200
MAX_SPAWNED = 100
# A unit quaternion, give or take rounding in a client's arithmetic.
QUATERNION_NORM_TOLERANCE = 1e-3
NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_\-]*\Z')


class EntityError(Exception):
    """A request refused: ``code`` names the standard's result (e.g. 'NAME_NOT_UNIQUE')."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


class Category:
    """The standard's entity categories (simulation_interfaces/EntityCategory)."""

    OBJECT = 0
    ROBOT = 1
    DYNAMIC_OBJECT = 4
    STATIC_OBJECT = 5


class EntityState(NamedTuple):
    """Pose of an entity's URDF base link in the world, the twist of its origin in the world."""

    position: Vec3
    orientation: Quat
    linear_velocity: Vec3
    angular_velocity: Vec3


def _finite(*vectors: Sequence[float]) -> bool:
    return all(math.isfinite(v) for vector in vectors for v in vector)


def check_pose(position: Sequence[float], orientation: Sequence[float]) -> Quat:
    """
    Return the orientation normalised; INVALID_POSE for a NaN or a non-unit quaternion.

    Also for a position beyond the blow-up check's bound (10 km): a robot put
    there would be reset as blown up at its next measurement.
    """
    if not _finite(position, orientation):
        raise EntityError('INVALID_POSE', 'the pose has a value that is not finite')
    if max(map(abs, position)) > MAX_DISTANCE_M:
        raise EntityError('INVALID_POSE', f'the position is more than {MAX_DISTANCE_M:g} m '
                                          'from the origin')
    norm = math.sqrt(sum(q * q for q in orientation))
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise EntityError('INVALID_POSE', f'the orientation is not a unit quaternion '
                                          f'(norm {norm:.6g})')
    return tuple(q / norm for q in orientation)


def check_description(text: str, base_dir: Optional[str]) -> str:
    """
    Return the URDF's robot name if ``text`` is one a domain peer may have us load.

    ``base_dir`` is the description file's directory (None for text sent in
    a request). EntityError otherwise: RESOURCE_PARSE_ERROR, UNSUPPORTED_FORMAT,
    MISSING_ASSETS or UNSUPPORTED_ASSETS, naming neither a file's content nor
    more than the offending path.
    """
    if len(text.encode('utf-8', errors='replace')) > MAX_DESCRIPTION_BYTES:
        raise EntityError('RESOURCE_PARSE_ERROR', f'the description is larger than '
                                                  f'{MAX_DESCRIPTION_BYTES} bytes')
    if '<!DOCTYPE' in text or '<!ENTITY' in text:
        raise EntityError('RESOURCE_PARSE_ERROR', 'the description declares a DOCTYPE or '
                                                  'entities, which a URDF does not need')
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as exc:
        raise EntityError('RESOURCE_PARSE_ERROR', f'not well-formed XML ({exc})') from None
    if root.tag != 'robot':
        raise EntityError('UNSUPPORTED_FORMAT', f'the root element is <{root.tag[:40]}>, '
                                                'not a URDF <robot>')
    links = root.findall('link')
    if not links:
        raise EntityError('RESOURCE_PARSE_ERROR', 'the URDF has no <link>')
    if len(links) > MAX_LINKS:
        raise EntityError('RESOURCE_PARSE_ERROR', f'the URDF has {len(links)} links, more '
                                                  f'than {MAX_LINKS}')
    for mesh in root.iter('mesh'):
        _check_mesh(mesh.get('filename', ''), base_dir)
    return root.get('name', '')


def _check_mesh(filename: str, base_dir: Optional[str]) -> None:
    """Allow a mesh from the description's directory, a ROS package or pybullet_data."""
    shown = filename[:200]
    if filename.startswith(PACKAGE_SCHEME):
        package, _, relative = filename[len(PACKAGE_SCHEME):].partition('/')
        try:
            root = package_share_directory(package)
        except DescriptionError:
            raise EntityError('MISSING_ASSETS', f'mesh {shown}: no package {package!r}') from None
        path = os.path.join(root, relative)
    elif filename.startswith('file://') or os.path.isabs(filename) or base_dir is None:
        raise EntityError('UNSUPPORTED_ASSETS', f'mesh {shown}: meshes must be relative to the '
                                                'URDF file or package:// URIs')
    else:
        root = base_dir
        path = os.path.join(base_dir, filename)
    real = os.path.realpath(path)
    roots = (os.path.realpath(root), os.path.realpath(pybullet_data.getDataPath()))
    if not any(real == r or real.startswith(r + os.sep) for r in roots):
        raise EntityError('UNSUPPORTED_ASSETS', f'mesh {shown} lies outside the URDF\'s '
                                                'directory and package')
    if not os.path.isfile(real):
        raise EntityError('MISSING_ASSETS', f'mesh {shown} does not exist')


def read_spawnable(uri: str, resource_string: str
                   ) -> Tuple[str, Optional[DescriptionFile], str, str]:
    """
    Return (URDF path to load, a temporary file to close or None, robot name, text).

    ``uri`` wins over ``resource_string`` (the standard's rule): a file path,
    ``file://``, ``package://`` or a pybullet_data name, resolved as the
    ``urdf`` parameter is. EntityError NO_RESOURCE, UNSUPPORTED_FORMAT...
    """
    if uri:
        path = uri[len('file://'):] if uri.startswith('file://') else uri
        try:
            path = resolve_description_path(path)
        except DescriptionError as exc:
            raise EntityError('NO_RESOURCE', str(exc)) from None
        if not path.lower().endswith('.urdf'):
            raise EntityError('UNSUPPORTED_FORMAT', f'{uri[:200]}: only .urdf files can be '
                                                    'spawned')
        if os.path.getsize(path) > MAX_DESCRIPTION_BYTES:
            raise EntityError('RESOURCE_PARSE_ERROR', f'{uri[:200]} is larger than '
                                                      f'{MAX_DESCRIPTION_BYTES} bytes')
        try:
            with open(path, encoding='utf-8') as handle:
                text = handle.read()
        except (OSError, UnicodeDecodeError):
            raise EntityError('RESOURCE_PARSE_ERROR', f'{uri[:200]} cannot be read as '
                                                      'text') from None
        return path, None, check_description(text, os.path.dirname(path)), text
    if not resource_string:
        raise EntityError('NO_RESOURCE', 'neither a uri nor a resource_string was given')
    name = check_description(resource_string, None)
    description = DescriptionFile(resource_string)
    return description.path, description, name, resource_string


def spawnable_uris() -> List[str]:
    """Return the URDFs GetSpawnables offers: this package's and pybullet_data's own."""
    uris = []
    try:
        share = package_share_directory('r2d2_sim')
        uris += [f'{PACKAGE_SCHEME}r2d2_sim/urdf/{name}'
                 for name in sorted(os.listdir(os.path.join(share, 'urdf')))
                 if name.endswith('.urdf')]
    except (DescriptionError, OSError):
        pass
    data = pybullet_data.getDataPath()
    uris += sorted(name for name in os.listdir(data) if name.endswith('.urdf'))
    return uris


class Entities:
    """
    The entities of a :class:`~r2d2_sim.sim.simulation.Simulation`'s world, by name.

    ``time_ns`` gives the simulated time for states; ``on_teleport(body)``
    is told when a body is placed (the robot's IMU must not take a teleport
    for an acceleration).
    """

    def __init__(self, world, robots: Callable[[], List], world_frame_id: str,
                 on_teleport: Callable[['Body'], None]) -> None:
        self._world = world
        self._robots = robots
        self.world_frame_id = world_frame_id
        self._on_teleport = on_teleport
        self._files: Dict[str, DescriptionFile] = {}  # spawned from text, by entity name

    def names(self) -> List[str]:
        """Return every entity's name, in the order the world loaded them."""
        return list(self._world.bodies)

    def body(self, name: str) -> 'Body':
        """Return the entity named ``name``; EntityError NOT_FOUND listing the others."""
        body = self._world.bodies.get(name)
        if body is None:
            raise EntityError('NOT_FOUND', f'no entity named {name!r}; the world has: '
                                           f'{", ".join(self._world.bodies)}')
        return body

    def category(self, body: 'Body') -> int:
        """Return the standard's category: ROBOT, STATIC_OBJECT or DYNAMIC_OBJECT."""
        if any(robot.body is body for robot in self._robots()):
            return Category.ROBOT
        return Category.STATIC_OBJECT if body.static else Category.DYNAMIC_OBJECT

    def state(self, name: str) -> EntityState:
        """Return the pose of the entity's URDF base link and its origin's twist, in the world."""
        body = self.body(name)
        position, orientation = body.link_pose(-1)
        moving = body.world_state()  # the same origin: the body frame only turns by a yaw
        return EntityState(tuple(position), tuple(orientation), moving.linear_velocity,
                           moving.angular_velocity)

    def frame_pose(self, frame_id: str) -> Transform:
        """Return the world pose of a frame a request names: '' or the world, or an entity."""
        if frame_id in ('', 'world', self.world_frame_id):
            return Transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
        if frame_id not in self._world.bodies:
            raise EntityError('INVALID_POSE', f'unknown frame {frame_id[:100]!r}: give world or '
                                              'an entity\'s name')
        state = self.state(frame_id)
        return Transform(state.position, state.orientation)

    def set_state(self, name: str, frame_id: str, position: Sequence[float],
                  orientation: Sequence[float], linear: Sequence[float],
                  angular: Sequence[float]) -> None:
        """
        Place the entity's base link at a pose in ``frame_id`` with a world-frame twist.

        The twist is always applied (the Jazzy request has no flags): a
        pose-only request stops the body. A static body may not move.
        """
        body = self.body(name)
        orientation = check_pose(position, orientation)
        if not _finite(linear, angular):
            raise EntityError('INVALID_POSE', 'the twist has a value that is not finite')
        if body.static and any(v != 0.0 for v in (*linear, *angular)):
            raise EntityError('OPERATION_FAILED', f'{name} is static: it takes a pose, '
                                                  'not a twist')
        pose = compose(self.frame_pose(frame_id), Transform(tuple(position), orientation))
        yaw = body.body_yaw_offset_rad
        turn = (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))
        body.set_world_state(pose.translation, quaternion_multiply(pose.rotation, turn),
                             tuple(linear), tuple(angular))
        self._on_teleport(body)

    def spawn(self, name: str, allow_renaming: bool, uri: str, resource_string: str,
              frame_id: str, position: Sequence[float], orientation: Sequence[float]) -> str:
        """
        Load a URDF at a pose (of its base link, exactly: no ground clearance); return its name.

        Named ``name``, or the URDF's robot name when empty; a taken or
        invalid name is refused unless ``allow_renaming`` (then ``_1``, ``_2``...).
        """
        body, _ = self.spawn_body(name, allow_renaming, uri, resource_string, frame_id,
                                  position, orientation)
        return body.name

    def spawn_body(self, name: str, allow_renaming: bool, uri: str, resource_string: str,
                   frame_id: str, position: Sequence[float], orientation: Sequence[float], *,
                   flags: int = 0, body_yaw_offset_rad: float = 0.0) -> Tuple['Body', str]:
        """
        Spawn as :meth:`spawn` does; return the body and its description's text.

        ``flags`` go to loadURDF (a driven robot's: true cylinders, inertias
        from the file); ``body_yaw_offset_rad`` turns its body frame from the
        URDF base (a robot that drives along its base y).
        """
        if sum(body.spawned for body in self._world.bodies.values()) >= MAX_SPAWNED:
            raise EntityError('OPERATION_FAILED', f'{MAX_SPAWNED} entities are spawned already: '
                                                  'delete some first')
        orientation = check_pose(position, orientation)
        pose = compose(self.frame_pose(frame_id), Transform(tuple(position), orientation))
        path, text_file, urdf_name, text = read_spawnable(uri, resource_string)
        try:
            name = self._name(name or urdf_name, allow_renaming)
            body = self._world.load(path, pose.translation, pose.rotation, name=name,
                                    spawned=True, source=uri or 'resource_string', flags=flags,
                                    body_yaw_offset_rad=body_yaw_offset_rad)
        except (EntityError, WorldError) as exc:
            if text_file is not None:
                text_file.close()
            if isinstance(exc, WorldError):
                raise EntityError('RESOURCE_PARSE_ERROR', str(exc)) from None
            raise
        if text_file is not None:
            self._files[name] = text_file
        return body, text

    def _name(self, wanted: str, allow_renaming: bool) -> str:
        if not NAME.match(wanted or ''):
            if not allow_renaming:
                raise EntityError('NAME_INVALID', f'{wanted[:100]!r} is not a valid entity '
                                                  'name (letters, digits, _ and -)')
            wanted = re.sub(r'[^A-Za-z0-9_\-]', '_', wanted or 'entity') or 'entity'
            if not wanted[0].isalpha() and wanted[0] != '_':
                wanted = 'entity_' + wanted
        if wanted in self._world.bodies and not allow_renaming:
            raise EntityError('NAME_NOT_UNIQUE', f'an entity named {wanted!r} exists')
        return self._world.unique_name(wanted)

    def delete(self, name: str) -> None:
        """Remove a spawned entity; start-up ones stay (a full reset could not bring them back)."""
        body = self.body(name)
        if not body.spawned:
            raise EntityError('OPERATION_FAILED', f'{name} was there at start-up: only spawned '
                                                  'entities can be deleted')
        self._world.remove(body)
        text_file = self._files.pop(name, None)
        if text_file is not None:
            text_file.close()

    def delete_spawned(self) -> None:
        """Remove every spawned entity (ResetSimulation's SPAWNED scope)."""
        for name, body in list(self._world.bodies.items()):
            if body.spawned:
                self.delete(name)

    def overlapping(self, centre: Sequence[float], radius_m: float) -> List[str]:
        """Return the entities whose bounding boxes meet a sphere (the standard's bounds)."""
        result = []
        for name, body in self._world.bodies.items():
            for link in body.links():
                low, high = body.aabb(link)
                nearest = [min(max(c, lo), hi) for c, lo, hi in zip(centre, low, high)]
                if math.dist(nearest, centre) <= radius_m:
                    result.append(name)
                    break
        return result

    def close(self) -> None:
        """Delete the temporary files of entities spawned from text."""
        for text_file in self._files.values():
            text_file.close()
        self._files.clear()
