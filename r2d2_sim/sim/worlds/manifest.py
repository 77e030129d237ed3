"""
r2d2_sim's world manifest: a small YAML file naming a world's models and its named poses.

No ROS here. The format (``*.world.yaml``, documented in
``docs/changing-the-world.md``)::

    r2d2_sim_world: 1            # the format and its version: required
    name: room
    description: Four walls and three boxes.
    tags: [indoor, small]
    start_pose: start            # a named pose: the start-up robots stand there
    models:
      - uri: room.urdf           # relative to this file, package://, file://, pybullet_data
        name: room               # default: the URDF's robot name, made unique
        position: [0, 0, 0]      # metres; and yaw (rad) or orientation [x, y, z, w]
        tags: [walls]
    named_poses:
      - name: spawn_area
        description: Free floor.
        tags: [spawn]
        position: [-1.5, 1.0, 0.0]
        yaw: 0.0
        bounds: {box: [[1.0, 0.8, 1.0], [-1.0, -0.8, 0.0]]}   # relative to the pose

Files come from any peer on the ROS domain (LoadWorld's ``resource_string``)
or from directories the operator listed, so reading one is bounded: its
size, how deeply it nests, how many nodes it has, and no YAML aliases (the
"billion laughs" of YAML), no tags beyond YAML's own (the safe loader). Every
refusal is a :class:`~r2d2_sim.errors.RefusedError` whose message says where
in the file the problem is (``named_poses[2].position``), never what the
file says there.
"""

import math
from typing import Any, List, NamedTuple, Optional, Sequence, Tuple

import yaml

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.transforms import Quaternion, Vector3
from r2d2_sim.sim.bounds import check_region, EMPTY, Region
from r2d2_sim.sim.names import is_name, MAX_NAME_LENGTH
from r2d2_sim.sim.tags import check_description_text, check_tags
from r2d2_sim.sim.worlds.world import NamedPose

__all__ = ['MANIFEST_KEY', 'MANIFEST_VERSION', 'MAX_WORLD_BYTES', 'MAX_YAML_DEPTH',
           'MAX_YAML_NODES', 'MAX_MODELS', 'MAX_NAMED_POSES', 'MAX_NAME_LENGTH',
           'ModelEntry', 'Manifest', 'load_yaml', 'looks_like_manifest', 'read_manifest',
           'check_world_pose']

MANIFEST_KEY = 'r2d2_sim_world'
MANIFEST_VERSION = 1
# What one world file may cost to read (the room's manifest is 2 kB).
MAX_WORLD_BYTES = 1_000_000
MAX_YAML_DEPTH = 32
MAX_YAML_NODES = 200_000
MAX_MODELS = 1000
MAX_NAMED_POSES = 1000
# As far out as a pose may be: the robots' blow-up bound.
MAX_DISTANCE_M = 10_000.0
QUATERNION_NORM_TOLERANCE = 1e-3
PARSE = 'RESOURCE_PARSE_ERROR'

_TOP = ('r2d2_sim_world', 'name', 'description', 'tags', 'start_pose', 'models', 'named_poses')
_MODEL = ('uri', 'name', 'description', 'tags', 'position', 'yaw', 'orientation')
_POSE = ('name', 'description', 'tags', 'position', 'yaw', 'orientation', 'bounds')
_BOUNDS = ('box', 'sphere', 'convex_hull')
_SPHERE = ('centre', 'center', 'radius')


def load_yaml(text: str) -> Any:
    """
    Return the data of a YAML text, read safely and within bounds; RESOURCE_PARSE_ERROR if not.

    The events are looked at first (libyaml's parser when there is one):
    an alias, nesting deeper than MAX_YAML_DEPTH or more than MAX_YAML_NODES
    nodes refuse the text before anything is built from it.
    """
    if len(text.encode('utf-8', errors='replace')) > MAX_WORLD_BYTES:
        raise RefusedError(PARSE, f'the world file is larger than {MAX_WORLD_BYTES} bytes')
    loader = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)
    depth = nodes = 0
    try:
        for event in yaml.parse(text, Loader=loader):
            if isinstance(event, yaml.AliasEvent):
                raise RefusedError(PARSE, 'the world file uses a YAML alias (*name), which a '
                                          'world file may not')
            if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                depth += 1
                if depth > MAX_YAML_DEPTH:
                    raise RefusedError(PARSE, f'the world file nests deeper than '
                                              f'{MAX_YAML_DEPTH} levels')
            elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                depth -= 1
            nodes += 1
            if nodes > MAX_YAML_NODES:
                raise RefusedError(PARSE, f'the world file has more than {MAX_YAML_NODES} '
                                          'YAML nodes')
        return yaml.load(text, Loader=loader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, 'problem_mark', None) or getattr(exc, 'context_mark', None)
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        raise RefusedError(PARSE, f'the world file is not valid YAML{where} '
                                  f'({type(exc).__name__})') from None


def looks_like_manifest(data: Any) -> bool:
    """Return True for YAML data that says it is an r2d2_sim world manifest."""
    return isinstance(data, dict) and MANIFEST_KEY in data


class ModelEntry(NamedTuple):
    """One model a manifest lists: its URI as written, name, pose, description and tags."""

    uri: str
    name: Optional[str]          # None: the URDF's robot name, made unique
    position: Tuple[float, float, float]
    orientation: Tuple[float, float, float, float]
    description: str
    tags: Tuple[str, ...]


class Manifest(NamedTuple):
    """What a manifest says, checked; ``ignored`` says where it has keys that mean nothing here."""

    name: str
    description: str
    tags: Tuple[str, ...]
    start_pose: Optional[str]
    models: Tuple[ModelEntry, ...]
    named_poses: Tuple[NamedPose, ...]
    ignored: Tuple[str, ...]


def _fail(where: str, problem: str) -> RefusedError:
    return RefusedError(PARSE, f'{where}: {problem}')


def _mapping(value: Any, where: str, keys: Sequence[str], ignored: List[str]) -> dict:
    if not isinstance(value, dict):
        raise _fail(where, 'expected a mapping (key: value)')
    for key in value:
        if not isinstance(key, str):
            raise _fail(where, 'every key is a string')
        if key not in keys:
            ignored.append(where or 'the top level')  # where, never the key's text
    return value


def _list(value: Any, where: str, most: int) -> list:
    if value is None:
        return []
    if not isinstance(value, list):
        raise _fail(where, 'expected a list')
    if len(value) > most:
        raise _fail(where, f'{len(value)} entries, more than {most}')
    return value


def _text(value: Any, where: str, default: Optional[str] = None) -> str:
    if value is None and default is not None:
        return default
    if not isinstance(value, str):
        raise _fail(where, 'expected a string')
    return value


def _name(value: Any, where: str) -> str:
    name = _text(value, where)
    if not is_name(name):
        raise _fail(where, f'a name is letters, digits, _ and - (at most {MAX_NAME_LENGTH}), '
                           'starting with a letter or _')
    return name


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise _fail(where, 'expected a finite number')
    return float(value)


def _numbers(value: Any, where: str, count: int) -> Tuple[float, ...]:
    if not isinstance(value, list) or len(value) != count:
        raise _fail(where, f'expected a list of {count} numbers')
    return tuple(_number(v, f'{where}[{i}]') for i, v in enumerate(value))


def _point(value: Any, where: str) -> Vector3:
    x, y, z = _numbers(value, where, 3)
    return x, y, z


def check_world_pose(position: Sequence[float], orientation: Sequence[float],
                     where: str) -> Quaternion:
    """Return the unit orientation; RESOURCE_PARSE_ERROR for a pose beyond 10 km or not unit."""
    if max(map(abs, position)) > MAX_DISTANCE_M:
        raise _fail(where, f'the position is more than {MAX_DISTANCE_M:g} m from the origin')
    norm = math.sqrt(sum(q * q for q in orientation))
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise _fail(where, f'the orientation is not a unit quaternion (norm {norm:.6g})')
    x, y, z, w = orientation
    return x / norm, y / norm, z / norm, w / norm


def _pose(entry: dict, where: str) -> Tuple[Vector3, Quaternion]:
    position = (_point(entry['position'], f'{where}.position')
                if 'position' in entry else (0.0, 0.0, 0.0))
    if 'yaw' in entry and 'orientation' in entry:
        raise _fail(where, 'give yaw or orientation, not both')
    if 'orientation' in entry:
        orientation = _numbers(entry['orientation'], f'{where}.orientation', 4)
    else:
        yaw = _number(entry['yaw'], f'{where}.yaw') if 'yaw' in entry else 0.0
        orientation = (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))
    return position, check_world_pose(position, orientation, where)


def _bounds(value: Any, where: str, ignored: List[str]) -> Region:
    if value is None:
        return EMPTY
    bounds = _mapping(value, where, _BOUNDS, ignored)
    given = [key for key in _BOUNDS if key in bounds]
    if len(given) != 1:
        raise _fail(where, 'give one of box, sphere or convex_hull')
    kind = given[0]
    if kind == 'sphere':
        sphere = _mapping(bounds['sphere'], f'{where}.sphere', _SPHERE, ignored)
        centre = sphere.get('centre', sphere.get('center', [0.0, 0.0, 0.0]))
        region = Region('sphere', (_point(centre, f'{where}.sphere.centre'),
                                   (_number(sphere.get('radius'), f'{where}.sphere.radius'),
                                    0.0, 0.0)))
    else:
        points = _list(bounds[kind], f'{where}.{kind}', 1000)
        region = Region(kind, tuple(_point(p, f'{where}.{kind}[{i}]')
                                    for i, p in enumerate(points)))
    return check_region(region, where, PARSE)


def read_manifest(data: Any, default_name: str) -> Manifest:
    """
    Return a manifest's content, checked; RefusedError if it is not one this package reads.

    ``data`` is the YAML's data (:func:`load_yaml`); ``default_name`` names a
    world that gives no ``name`` (its file's). UNSUPPORTED_FORMAT for data that
    is not a manifest or one of another version, RESOURCE_PARSE_ERROR for a
    malformed one; keys that mean nothing here are listed in ``ignored``.
    """
    if not looks_like_manifest(data):
        raise RefusedError('UNSUPPORTED_FORMAT', f'not an r2d2_sim world manifest (it has no '
                                                 f'"{MANIFEST_KEY}: {MANIFEST_VERSION}")')
    if data[MANIFEST_KEY] != MANIFEST_VERSION or isinstance(data[MANIFEST_KEY], bool):
        raise RefusedError('UNSUPPORTED_FORMAT', f'{MANIFEST_KEY}: this r2d2_sim reads version '
                                                 f'{MANIFEST_VERSION} only')
    ignored: List[str] = []
    _mapping(data, '', _TOP, ignored)
    name = _text(data['name'], 'name') if 'name' in data else default_name
    if not name or len(name) > MAX_NAME_LENGTH:
        raise _fail('name', f'a world\'s name has 1 to {MAX_NAME_LENGTH} characters')
    description = check_description_text(_text(data.get('description'), 'description', ''),
                                         'description', PARSE)
    tags = check_tags(_list(data.get('tags'), 'tags', 1000), 'tags', PARSE)
    models = []
    for i, raw in enumerate(_list(data.get('models'), 'models', MAX_MODELS)):
        where = f'models[{i}]'
        entry = _mapping(raw, where, _MODEL, ignored)
        if 'uri' not in entry:
            raise _fail(where, 'a model needs a uri')
        position, orientation = _pose(entry, where)
        uri = _text(entry['uri'], f'{where}.uri')
        models.append(ModelEntry(
            uri, _name(entry['name'], f'{where}.name') if 'name' in entry else None,
            position, orientation,
            check_description_text(_text(entry.get('description'), f'{where}.description',
                                         ''), f'{where}.description', PARSE),
            check_tags(_list(entry.get('tags'), f'{where}.tags', 1000), f'{where}.tags',
                       PARSE)))
    named = [m.name for m in models if m.name is not None]
    if len(set(named)) != len(named):
        raise _fail('models', 'two models have the same name')
    poses = []
    for i, raw in enumerate(_list(data.get('named_poses'), 'named_poses', MAX_NAMED_POSES)):
        where = f'named_poses[{i}]'
        entry = _mapping(raw, where, _POSE, ignored)
        if 'name' not in entry:
            raise _fail(where, 'a named pose needs a name')
        position, orientation = _pose(entry, where)
        poses.append(NamedPose(
            _name(entry['name'], f'{where}.name'),
            check_description_text(_text(entry.get('description'), f'{where}.description',
                                         ''), f'{where}.description', PARSE),
            check_tags(_list(entry.get('tags'), f'{where}.tags', 1000), f'{where}.tags', PARSE),
            position, orientation, _bounds(entry.get('bounds'), f'{where}.bounds', ignored)))
    names = [pose.name for pose in poses]
    if len(set(names)) != len(names):
        raise _fail('named_poses', 'two named poses have the same name')
    start = data.get('start_pose')
    if start is not None:
        start = _text(start, 'start_pose')
        if start not in names:
            raise _fail('start_pose', 'it names no named pose of this world')
    return Manifest(name, description, tags, start, tuple(models), tuple(poses),
                    tuple(ignored))
