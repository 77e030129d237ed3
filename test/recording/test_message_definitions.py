"""
Definitions, type hashes and QoS YAML for recordings, checked against independent sources.

- Text: one type is compared byte for byte with the files it is made of,
  concatenated by hand in rosbag2's order. Every type is also compared with
  rosbags' own Jazzy typestore (``generate_msgdef``), which writes no
  comments, blank lines or default values and orders the sections by field
  order: so the comparison is of the set of sections and, in each, the
  fields (type, name) and constants, with bare type names qualified by the
  section's package. The section order is checked on its own, against a
  list worked out by hand.
- Hashes: equal to those rclpy's type support reports through the graph.
- QoS: parsed by rosbags' rosbag2 reader, and equal to the YAML of the
  profile that Fast DDS reports for a real publisher, except for history
  and depth, which the graph does not report.

That all this needs no rclpy is proved in a fresh interpreter by
system/test_message_definitions_system.py.
"""

import importlib
from pathlib import Path
import sys

import pytest
import rclpy
from rclpy.context import Context
from rclpy.qos import (
    DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy)
from rclpy.duration import Duration
from rosbags.rosbag2.metadata import dump_qos_v9, parse_qos
from rosbags.typesys import get_typestore, Stores
import yaml

from r2d2_sim.recording import message_definitions
from r2d2_sim.recording.message_definitions import (
    message_definition, offered_qos_profiles, type_hash, UnknownMessageType)
from r2d2_sim.testing import lease_domain

TYPES = [
    'sensor_msgs/msg/LaserScan', 'nav_msgs/msg/Odometry', 'tf2_msgs/msg/TFMessage',
    'sensor_msgs/msg/JointState', 'sensor_msgs/msg/Image', 'std_msgs/msg/String',
    'rosgraph_msgs/msg/Clock', 'sensor_msgs/msg/Imu', 'geometry_msgs/msg/TransformStamped',
]
DELIMITER = '=' * 80 + '\n'
PRIMITIVES = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16',
              'uint16', 'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring'}


def message_class(type_name):
    """Import the rclpy class of ``pkg/msg/Type``, or None when the package is not built."""
    package, _, name = type_name.split('/')
    try:
        return getattr(importlib.import_module(f'{package}.msg'), name)
    except ImportError:
        return None


def share_file(type_name, extension='.msg'):
    """Return the interface file of a type under this interpreter's share/."""
    package, namespace, name = type_name.split('/')
    return Path(sys.prefix, 'share', package, namespace, name + extension)


def sections(text):
    """Split a definition into [(section type name, body)], the top level named ''."""
    parts = text.split('\n' + DELIMITER)
    result = [('', parts[0])]
    for part in parts[1:]:
        header, _, body = part.partition('\n')
        assert header.startswith('MSG: '), header
        result.append((header[len('MSG: '):], body))
    return result


def fields(body, package):
    """Return the fields and constants of a .msg body, free of comments, spacing and defaults."""
    result = []
    for line in body.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        field_type, rest = line.split(None, 1)
        base = field_type.split('[')[0]
        if base not in PRIMITIVES and '/' not in base:
            field_type = f'{package}/{field_type}'
        if '=' in rest:  # a constant: NAME=value
            name, value = (part.strip() for part in rest.split('=', 1))
            result.append((field_type, name, value))
        else:
            result.append((field_type, rest.split()[0]))
    return result


def normalised(text, top_package):
    """Map each section of a definition to its fields (see :func:`fields`)."""
    return {name: fields(body, name.split('/')[0] if name else top_package)
            for name, body in sections(text)}


def test_laser_scan_is_the_files_in_rosbag2_order():
    """LaserScan: its .msg, then Header, then Header's Time, comments and all."""
    def read(type_name):
        return share_file(type_name).read_text()
    expected = (read('sensor_msgs/msg/LaserScan')
                + '\n' + DELIMITER + 'MSG: std_msgs/Header\n' + read('std_msgs/msg/Header')
                + '\n' + DELIMITER + 'MSG: builtin_interfaces/Time\n'
                + read('builtin_interfaces/msg/Time'))
    assert message_definition('sensor_msgs/msg/LaserScan') == expected


def test_sections_are_sorted_depth_first_each_once():
    """Odometry: sorted dependencies, each followed by its own (Header after geometry_msgs)."""
    names = [name for name, _ in sections(message_definition('nav_msgs/msg/Odometry'))]
    # Odometry uses PoseWithCovariance, TwistWithCovariance, Header (sorted:
    # geometry_msgs before std_msgs); PoseWithCovariance uses Pose, which uses
    # Point and Quaternion; Twist uses Vector3; Header uses Time.
    assert names == ['', 'geometry_msgs/PoseWithCovariance', 'geometry_msgs/Pose',
                     'geometry_msgs/Point', 'geometry_msgs/Quaternion',
                     'geometry_msgs/TwistWithCovariance', 'geometry_msgs/Twist',
                     'geometry_msgs/Vector3', 'std_msgs/Header', 'builtin_interfaces/Time']


@pytest.mark.parametrize('type_name', TYPES)
def test_definition_matches_rosbags_typestore(type_name):
    """The same sections with the same fields as rosbags' independent Jazzy typestore writes."""
    ours = message_definition(type_name)
    theirs, _ = get_typestore(Stores.ROS2_JAZZY).generate_msgdef(type_name, ros_version=2)
    package = type_name.split('/')[0]
    assert normalised(ours, package) == normalised(theirs, package)
    names = [name for name, _ in sections(ours)]
    assert len(names) == len(set(names)), 'a dependency was written twice'
    assert all(name.count('/') == 1 for name in names[1:]), 'sections named pkg/Type'


@pytest.mark.parametrize('type_name', TYPES)
def test_hash_equals_the_json_beside_the_msg(type_name):
    """The hash is the type's own entry of its .json (not a dependency's)."""
    path = share_file(type_name, '.json')
    if not path.is_file():
        pytest.skip(f'{path} is not installed here')
    import json
    entries = json.loads(path.read_text())['type_hashes']
    assert type_hash(type_name) == entries[0]['hash_string']
    assert entries[0]['type_name'] == type_name


def test_hashes_equal_what_rclpy_reports():
    """Each hash equals the one rclpy's type support puts in the graph for a publisher."""
    classes = {name: message_class(name) for name in TYPES}
    importable = {name: cls for name, cls in classes.items() if cls is not None}
    assert len(importable) >= len(TYPES) - 1, f'missing: {set(classes) - set(importable)}'
    with lease_domain() as lease:
        context = Context()
        rclpy.init(context=context, domain_id=lease.domain_id)
        try:
            node = rclpy.create_node('hash_probe', context=context)
            for index, (name, cls) in enumerate(importable.items()):
                node.create_publisher(cls, f'/hash_{index}', 1)
                info = node.get_publishers_info_by_topic(f'/hash_{index}')
                assert str(info[0].topic_type_hash) == type_hash(name), name
            node.destroy_node()
        finally:
            rclpy.try_shutdown(context=context)


def test_built_in_tf_message_equals_the_built_package(tmp_path):
    """Without share/tf2_msgs, TFMessage's built-in text and hash equal the built package's."""
    if not share_file('tf2_msgs/msg/TFMessage').is_file():
        pytest.skip('tf2_msgs is not built in this venv')
    without_tf2 = tmp_path / 'prefix'
    (without_tf2 / 'share').mkdir(parents=True)
    for package in ('geometry_msgs', 'std_msgs', 'builtin_interfaces'):
        (without_tf2 / 'share' / package).symlink_to(Path(sys.prefix, 'share', package))
    assert message_definition('tf2_msgs/msg/TFMessage', prefixes=[without_tf2]) == \
        message_definition('tf2_msgs/msg/TFMessage')
    assert type_hash('tf2_msgs/msg/TFMessage', prefixes=[without_tf2]) == \
        type_hash('tf2_msgs/msg/TFMessage')


def test_ament_prefix_path_is_searched_first(tmp_path, monkeypatch):
    """A workspace on AMENT_PREFIX_PATH supplies its own types; bare names take its package."""
    workspace = tmp_path / 'install'
    msg_dir = workspace / 'share' / 'my_msgs' / 'msg'
    msg_dir.mkdir(parents=True)
    (msg_dir / 'Thing.msg').write_text('# a thing\nstd_msgs/Header header\nPart[2] parts\n')
    (msg_dir / 'Part.msg').write_text('uint8 KIND_A=1\nfloat64 x 0.5\n')
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(workspace))
    assert message_definitions.search_prefixes()[0] == workspace
    assert [name for name, _ in sections(message_definition('my_msgs/msg/Thing'))] == [
        '', 'my_msgs/Part', 'std_msgs/Header', 'builtin_interfaces/Time']
    assert message_definition('my_msgs/Thing').startswith('# a thing\n')


@pytest.mark.parametrize('type_name, words', [
    ('foo_msgs/msg/Bar', ['foo_msgs/msg/Bar', 'share']),
    ('not a type', ['not a type', 'pkg/msg/Type']),
    ('sensor_msgs/msg/NoSuchScan', ['sensor_msgs/msg/NoSuchScan']),
])
def test_unknown_type_is_one_clear_line(type_name, words):
    """An unknown type raises UnknownMessageType with a one-line message naming it."""
    for function in (message_definition, type_hash):
        with pytest.raises(UnknownMessageType) as raised:
            function(type_name)
        text = str(raised.value)
        assert '\n' not in text
        for word in words:
            assert word in text


PROFILES = {
    'latched': QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL),
    'sensor': QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT),
    'keep_all': QoSProfile(history=HistoryPolicy.KEEP_ALL),
    'timed': QoSProfile(depth=10, deadline=Duration(seconds=1, nanoseconds=5),
                        lifespan=Duration(seconds=2),
                        liveliness=LivelinessPolicy.MANUAL_BY_TOPIC,
                        liveliness_lease_duration=Duration(seconds=3)),
}


@pytest.mark.parametrize('name', sorted(PROFILES))
def test_qos_yaml_reads_back_through_rosbags(name):
    """The YAML parses in rosbags' reader to the profile, and rosbags writes it back the same."""
    qos = PROFILES[name]
    text = offered_qos_profiles(qos)
    parsed = parse_qos(text)
    assert len(parsed) == 1
    assert parsed[0].history.name == qos.history.name
    assert parsed[0].reliability.name == qos.reliability.name
    assert parsed[0].durability.name == qos.durability.name
    assert parsed[0].depth == qos.depth
    if qos.deadline.nanoseconds:
        assert parsed[0].deadline.sec * 10**9 + parsed[0].deadline.nsec == \
            qos.deadline.nanoseconds
    assert dump_qos_v9(parsed) == yaml.safe_load(text)
    assert offered_qos_profiles(qos, qos) == text + '\n' + text


def test_qos_yaml_is_what_a_recorder_sees_in_the_graph():
    """Apart from history and depth, the YAML equals that of the profile Fast DDS offers."""
    def without_history(text):
        return [line for line in text.splitlines()
                if not line.startswith(('- history', '  depth'))]
    with lease_domain() as lease:
        context = Context()
        rclpy.init(context=context, domain_id=lease.domain_id)
        try:
            from std_msgs.msg import String
            node = rclpy.create_node('qos_probe', context=context)
            for name, qos in PROFILES.items():
                node.create_publisher(String, f'/qos_{name}', qos)
                offered = node.get_publishers_info_by_topic(f'/qos_{name}')[0].qos_profile
                assert without_history(offered_qos_profiles(qos)) == \
                    without_history(offered_qos_profiles(offered)), name
            node.destroy_node()
        finally:
            rclpy.try_shutdown(context=context)
