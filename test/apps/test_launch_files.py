"""
The launch file, the rviz config and the Foxglove layout, checked against the package.

``ros2 launch`` and rviz2 are not installable on a pip-only machine, so these
files cannot run here. What can be checked is checked: every executable of
ours they start exists, every parameter they set is declared (with a value
that validates), every file they name is installed, and every topic, frame and
message type they display is one the node publishes with these parameters.
"""

from pathlib import Path
import re
import xml.etree.ElementTree as ElementTree

import pytest
import yaml

from helpers import REPO
from r2d2_sim.sim.settings.table import PARAMETERS_BY_NAME
from r2d2_sim.sim.settings.config import parse_config
from r2d2_sim.testing import SimHarness

LAUNCH = Path(REPO) / 'launch' / 'sim.launch.xml'
RVIZ = Path(REPO) / 'config' / 'r2d2_sim.rviz'
LAYOUT = Path(REPO) / 'config' / 'foxglove_layout.json'
# Other packages' executables the launch file starts (declared in package.xml).
EXTERNAL = {('robot_state_publisher', 'robot_state_publisher'), ('rviz2', 'rviz2')}


def setup_py():
    """Return setup.py's text."""
    return (Path(REPO) / 'setup.py').read_text()


def installed_share_files():
    """Return the share/r2d2_sim paths setup.py installs: {'urdf/r2d2.urdf', 'launch/...', ...}."""
    import os
    from unittest import mock
    captured = {}
    cwd = os.getcwd()
    os.chdir(REPO)  # setup.py globs relative paths
    try:
        with mock.patch('setuptools.setup', lambda **kwargs: captured.update(kwargs)):
            exec(compile(setup_py(), 'setup.py', 'exec'),
                 {'__name__': 'setup', '__file__': os.path.join(REPO, 'setup.py')})
    finally:
        os.chdir(cwd)
    files = set()
    for target, sources in captured['data_files']:
        if target.startswith('share/r2d2_sim'):
            prefix = target[len('share/r2d2_sim'):].strip('/')
            files |= {f'{prefix}/{Path(source).name}'.strip('/') for source in sources}
    return files


def launch_tree():
    """Return the parsed launch file."""
    return ElementTree.parse(LAUNCH).getroot()


def substitute(value, args):
    """Resolve $(var name) with the arguments' defaults and $(find-pkg-share r2d2_sim)."""
    value = re.sub(r'\$\(var (\w+)\)', lambda m: args[m.group(1)], value)
    return value.replace('$(find-pkg-share r2d2_sim)', 'SHARE')


def test_the_launch_file_starts_our_executable_and_known_ones():
    """Every <node> is sim_node of this package or another package's declared executable."""
    package_xml = (Path(REPO) / 'package.xml').read_text()
    nodes = [(n.get('pkg'), n.get('exec')) for n in launch_tree().iter('node')]
    assert ('r2d2_sim', 'sim_node') in nodes
    for pkg, executable in nodes:
        if pkg == 'r2d2_sim':
            assert f"'{executable} = r2d2_sim." in setup_py(), executable
        else:
            assert (pkg, executable) in EXTERNAL
            assert f'<exec_depend>{pkg}</exec_depend>' in package_xml, pkg


def test_the_launch_files_parameters_exist_and_validate():
    """sim_node's <param>s are declared parameters; with the defaults they pass validation."""
    root = launch_tree()
    args = {a.get('name'): a.get('default') for a in root.iter('arg')}
    sim = next(n for n in root.iter('node') if n.get('exec') == 'sim_node')
    values = {}
    for param in sim.iter('param'):
        name = param.get('name')
        assert name in PARAMETERS_BY_NAME, name
        values[name] = yaml.safe_load(substitute(param.get('value'), args))
    values['urdf'] = str(Path(REPO) / 'urdf' / 'r2d2.urdf')  # $(find-pkg-share) stands for it
    config = parse_config(values)
    assert config.publish_ground_truth_tf and not config.publish_link_tf
    for node in root.iter('node'):  # use_sim_time everywhere else
        if node.get('exec') != 'sim_node':
            params = {p.get('name'): p.get('value') for p in node.iter('param')}
            assert params.get('use_sim_time') == 'true', node.get('exec')


def test_every_file_the_launch_file_names_is_installed():
    """$(find-pkg-share r2d2_sim)/... paths are among setup.py's data files."""
    text = LAUNCH.read_text()
    named = set(re.findall(r'\$\(find-pkg-share r2d2_sim\)/([\w./]+)', text))
    assert named >= {'urdf/r2d2.urdf', 'rviz/r2d2_sim.rviz'}
    assert named <= installed_share_files(), named - installed_share_files()
    assert {'launch/sim.launch.xml', 'foxglove/foxglove_layout.json'} <= installed_share_files()


@pytest.fixture(scope='module')
def published():
    """Return {topic: type} and the TF frames the node publishes with the launch's settings."""
    root = launch_tree()
    args = {a.get('name'): a.get('default') for a in root.iter('arg')}
    sim = next(n for n in root.iter('node') if n.get('exec') == 'sim_node')
    values = {p.get('name'): yaml.safe_load(substitute(p.get('value'), args))
              for p in sim.iter('param')}
    values.pop('urdf')
    values.pop('foxglove_port')
    with SimHarness(**values) as harness:
        harness.listen_tf()
        harness.advance(2)
        # Waits for /tf and /tf_static (the links are robot_state_publisher's in the launch).
        harness.lookup_transform('world', 'base_scan')
        topics = {name: types[0] for name, types in harness.sim.get_topic_names_and_types()}
        frames = harness.listen_tf().buffer.frames
    return topics, frames


def test_the_rviz_config_shows_what_the_node_publishes(published):
    """Each display's topic exists with the display's type; the frames it names exist."""
    topics, frames = published
    config = yaml.safe_load(RVIZ.read_text())['Visualization Manager']
    expected_type = {'rviz_default_plugins/LaserScan': 'sensor_msgs/msg/LaserScan',
                     'rviz_default_plugins/Odometry': 'nav_msgs/msg/Odometry',
                     'rviz_default_plugins/Image': 'sensor_msgs/msg/Image',
                     'rviz_default_plugins/RobotModel': 'std_msgs/msg/String'}
    shown = set()
    for display in config['Displays']:
        topic = (display.get('Topic') or display.get('Description Topic') or {}).get('Value')
        if topic is None:
            continue
        assert topics.get(topic) == expected_type[display['Class']], (topic, display['Class'])
        shown.add(topic)
    assert shown == {'/scan', '/odom', '/ground_truth', '/camera/image_raw',
                     '/robot_description'}
    assert config['Global Options']['Fixed Frame'] in frames
    assert config['Views']['Current']['Target Frame'] in frames


def test_the_foxglove_layout_names_what_the_node_publishes(published):
    """The layout's topics and followed frame are the node's (the live view test draws it)."""
    import json
    topics, frames = published
    text = LAYOUT.read_text()
    json.loads(text)
    # The 3D panel's own publish tools (clicked point, pose estimate, goal) are not ours.
    named = set(re.findall(r'"(/[\w/]+)"', text)) - {
        '/', '/clicked_point', '/initialpose', '/move_base_simple/goal'}
    assert named and all(t.split('.')[0] in topics for t in named), named - set(topics)
    assert 'base_footprint' in text and 'base_footprint' in frames
