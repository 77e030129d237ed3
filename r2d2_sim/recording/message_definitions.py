"""
What a recording needs to say about a ROS 2 topic beside its bytes, as rosbag2 Jazzy writes it.

- :func:`message_definition`: the complete ``ros2msg`` definition text of a
  type, built the way rosbag2's ``LocalMessageDefinitionSource`` builds it:
  the type's ``.msg`` file, then every type it uses, once, depth-first over
  each file's sorted dependencies, each after a line of 80 ``=`` and
  ``MSG: <type as the field spells it>`` (``std_msgs/Header``, not
  ``std_msgs/msg/Header``: Rerun 0.41 refused the latter).
- :func:`type_hash`: the RIHS01 hash rosbag2 stores as ``topic_type_hash``,
  read from the ``.json`` type description beside the ``.msg``.
- :func:`offered_qos_profiles`: the ``offered_qos_profiles`` YAML (metadata
  version 9) for a QoS profile, which ``ros2 bag play`` uses to replay
  ``/tf_static`` and ``/robot_description`` latched.

Pure Python, no rclpy: the files come from ``share/<pkg>/msg/`` under the
prefixes of ``AMENT_PREFIX_PATH`` (a sourced ROS install, a colcon
workspace) and under ``sys.prefix`` (where the ``ros-jazzy-*`` wheels put
them, with no ament index a pip user could rely on).
"""

from enum import Enum
from functools import lru_cache
import json
import os
from pathlib import Path
import re
import sys
from typing import Iterable, List, Optional, Sequence, Tuple, TYPE_CHECKING

if TYPE_CHECKING:  # typing only: this layer loads no ROS
    from rclpy.duration import Duration
    from rclpy.qos import QoSProfile

__all__ = ['UnknownMessageType', 'known_message_type', 'message_definition',
           'offered_qos_profiles', 'search_prefixes', 'type_hash']

# rosbag2's regular expression for the field types of a .msg file ("pkg/Type"
# in "pkg/Type[] name"), applied to the whole text, comments included.
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_PRIMITIVES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string'))
_NAME = '[a-zA-Z][a-zA-Z0-9_]*'
_TYPE_NAME = re.compile(rf'^({_NAME})/(?:({_NAME})/)?({_NAME})$')
_DELIMITER = '=' * 80 + '\n'
# rosbag2's ROSBAG2_CPP_LOCAL_MESSAGE_DEFINITION_SOURCE_MAX_RECURSION_DEPTH.
_MAX_DEPTH = 50

# tf2_msgs is not on PyPI: a pip-only machine may have no share/tf2_msgs yet
# still want /tf in a recording (its bytes can come from another serializer).
# The text and hash of Jazzy's tf2_msgs TFMessage, used only when no
# share directory has the files.
_BUILT_IN = {
    'tf2_msgs/msg/TFMessage': (
        'geometry_msgs/TransformStamped[] transforms\n',
        'RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087'),
}

# rmw's RMW_DURATION_INFINITE: what Fast DDS reports, and rosbag2 records, for
# a duration the publisher left unspecified.
_INFINITE_NS = 2**63 - 1
_NS_PER_S = 1_000_000_000


class UnknownMessageType(LookupError):
    """No definition of the type was found (the message says where it was looked for)."""


def search_prefixes() -> List[Path]:
    """Return the prefixes searched for ``share/<pkg>``: AMENT_PREFIX_PATH, then sys.prefix."""
    prefixes = [Path(p) for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    prefixes.append(Path(sys.prefix))
    unique = []
    for prefix in prefixes:
        if prefix not in unique:
            unique.append(prefix)
    return unique


def _split(type_name: str) -> Tuple[str, str, str]:
    """Split ``pkg/msg/Type`` or ``pkg/Type`` into (package, namespace, type)."""
    match = _TYPE_NAME.fullmatch(type_name)
    if match is None:
        raise UnknownMessageType(
            f'{type_name[:200]!r} is not a ROS message type name (expected pkg/msg/Type)')
    package, namespace, name = match.groups()
    return package, namespace or 'msg', name


def _full_name(type_name: str) -> str:
    package, namespace, name = _split(type_name)
    return f'{package}/{namespace}/{name}'


@lru_cache(maxsize=None)
def _read(type_name: str, extension: str, prefixes: Tuple[Path, ...]) -> str:
    """Return the text of the type's interface file, or raise UnknownMessageType."""
    package, namespace, name = _split(type_name)
    relative = Path('share', package, namespace, name + extension)
    for prefix in prefixes:
        path = prefix / relative
        if path.is_file():
            return path.read_text(encoding='utf-8')
    built_in = _BUILT_IN.get(_full_name(type_name))
    if built_in is not None:
        return built_in[0] if extension == '.msg' else json.dumps(
            {'type_hashes': [{'type_name': _full_name(type_name), 'hash_string': built_in[1]}]})
    places = ', '.join(str(prefix / 'share') for prefix in prefixes) or 'no prefix'
    raise UnknownMessageType(
        f'no definition of {type_name}: {relative.relative_to("share")} is in none of '
        f'{places} (is its package installed? AMENT_PREFIX_PATH adds places)')


def _dependencies(text: str, package: str) -> List[str]:
    """Return the sorted message types a .msg text uses, qualified as rosbag2 qualifies them."""
    found = set()
    for field_type in _FIELD_TYPE.findall(text):
        if field_type in _PRIMITIVES:
            continue
        found.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(found)


def _prefixes(prefixes: Optional[Iterable[os.PathLike]]) -> Tuple[Path, ...]:
    return tuple(Path(p) for p in (search_prefixes() if prefixes is None else prefixes))


def known_message_type(type_name: str,
                       prefixes: Optional[Sequence[os.PathLike]] = None) -> str:
    """
    Return ``pkg/msg/Type`` for a message type that an installed ROS interface package defines.

    ``type_name`` is ``pkg/msg/Type`` or ``pkg/Type``; it is known when
    ``share/<pkg>/msg/<Type>.msg`` is under one of ``prefixes`` (default
    :func:`search_prefixes`: where the ament index and the ROS wheels put
    interface packages), or it is tf2_msgs' TFMessage. Raises
    :class:`UnknownMessageType`, saying where it looked, otherwise. Nothing is
    imported: a name read from a file is checked here before any code runs for it.
    """
    package, namespace, name = _split(type_name)
    if namespace != 'msg':
        raise UnknownMessageType(f'{type_name!r} is not a message type (pkg/msg/Type)')
    _read(type_name, '.msg', _prefixes(prefixes))
    return f'{package}/msg/{name}'


def message_definition(type_name: str,
                       prefixes: Optional[Sequence[os.PathLike]] = None) -> str:
    """
    Return the complete ``ros2msg`` definition of ``type_name`` as rosbag2 Jazzy writes it.

    ``type_name`` is ``pkg/msg/Type`` (or ``pkg/Type``). ``prefixes`` default
    to :func:`search_prefixes`. Raises :class:`UnknownMessageType` when a
    file is missing.
    """
    searched = _prefixes(prefixes)
    return _definition(type_name, searched)


@lru_cache(maxsize=None)
def _definition(type_name: str, prefixes: Tuple[Path, ...]) -> str:
    seen = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise UnknownMessageType(
                f'{type_name}: its definition nests deeper than {_MAX_DEPTH} types')
        text = _read(name, '.msg', prefixes)
        result = text
        for dependency in _dependencies(text, _split(name)[0]):
            if dependency not in seen:
                seen.add(dependency)
                result += '\n' + _DELIMITER + f'MSG: {dependency}\n'
                result += append(dependency, depth - 1)
        return result
    try:
        return append(type_name, _MAX_DEPTH)
    except UnknownMessageType as exc:
        if str(exc).startswith(f'no definition of {type_name}:'):
            raise
        raise UnknownMessageType(f'{type_name}: {exc}') from None


def type_hash(type_name: str, prefixes: Optional[Sequence[os.PathLike]] = None) -> str:
    """Return the RIHS01 type hash (``RIHS01_<hex>``) of ``type_name``, from its ``.json``."""
    searched = _prefixes(prefixes)
    full_name = _full_name(type_name)
    try:
        description = json.loads(_read(type_name, '.json', searched))
    except ValueError as exc:
        raise UnknownMessageType(f'{type_name}: unreadable type description: {exc}') from None
    for entry in description.get('type_hashes', ()):
        if entry.get('type_name') == full_name:
            return entry['hash_string']
    raise UnknownMessageType(f'{type_name}: its .json lists no hash for {full_name}')


def _policy(value: Enum) -> str:
    """Name a QoS policy as rmw's *_policy_to_str and rosbag2 do (keep_last, transient_local)."""
    return value.name.lower()


def _duration(duration: 'Duration') -> str:
    nanoseconds = duration.nanoseconds
    if nanoseconds == 0:  # unspecified: the rmw offers infinity
        nanoseconds = _INFINITE_NS
    return f'sec: {nanoseconds // _NS_PER_S}\n    nsec: {nanoseconds % _NS_PER_S}'


def offered_qos_profiles(*profiles: 'QoSProfile') -> str:
    """
    Return rosbag2 Jazzy's ``offered_qos_profiles`` YAML (version 9) for rclpy QoS profiles.

    The layout is yaml-cpp's, as rosbag2 dumps it. Durations the profile left
    unspecified (0) are written as infinite and ``system_default``
    liveliness as ``automatic``: what a Fast DDS publisher offers, so what
    rosbag2 records from the graph. History and depth are written as given
    (the graph reports ``unknown``/0 for them; ``ros2 bag play`` replaces
    both anyway, :mod:`r2d2_sim.apps.replay` keeps the depth).
    """
    entries = []
    for qos in profiles:
        liveliness = _policy(qos.liveliness)
        if liveliness == 'system_default':
            liveliness = 'automatic'
        entries.append(
            f'- history: {_policy(qos.history)}\n'
            f'  depth: {qos.depth}\n'
            f'  reliability: {_policy(qos.reliability)}\n'
            f'  durability: {_policy(qos.durability)}\n'
            f'  deadline:\n    {_duration(qos.deadline)}\n'
            f'  lifespan:\n    {_duration(qos.lifespan)}\n'
            f'  liveliness: {liveliness}\n'
            f'  liveliness_lease_duration:\n    {_duration(qos.liveliness_lease_duration)}\n'
            f'  avoid_ros_namespace_conventions: '
            f'{"true" if qos.avoid_ros_namespace_conventions else "false"}')
    return '\n'.join(entries)
