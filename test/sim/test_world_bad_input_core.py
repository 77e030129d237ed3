"""
Bad worlds and bad info in the core: the standard's code, one line, no file contents, no change.

A world file outside the allowed places, one that does not parse, a hostile
one (DOCTYPE, entity bomb, YAML aliases, deep nesting, huge), an unknown
named pose, a tag flood: each is refused with LoadWorld's (or the entity
services') code and a message that names where, never what the file says.
A refused load leaves the world exactly as it was: the same run afterwards,
bit for bit, as a twin simulation's that was never asked.
"""

import subprocess
import sys

from common import drive_and_read
import pytest

from r2d2_sim.errors import RefusedError
from r2d2_sim.sim.entities import Category
from r2d2_sim.sim.tags import check_filter, MAX_TAG_LENGTH, MAX_TAGS
from r2d2_sim.sim.worlds.manifest import MAX_WORLD_BYTES, MAX_YAML_DEPTH

ROOM = 'package://r2d2_sim/urdf/room.world.yaml'
SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'scan_rate': 0.0, 'imu_rate': 0.0,
                       'world': ROOM}
MARK = 'SECRET_CONTENT_42'  # in every bad file: no message may show it

ALIAS_BOMB = (f'r2d2_sim_world: 1\nname: {MARK}\n'
              'a: &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]\n'
              'b: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n'
              'c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b]\n'
              'd: [*c, *c, *c, *c, *c, *c, *c, *c, *c]\n')
ENTITY_BOMB = ('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "' + MARK + '">'
               '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;">]><robot name="b"><link name="&b;"/>'
               '</robot>')

BAD_TEXTS = {
    'YAML that does not parse': (f'r2d2_sim_world: 1\nname: [{MARK}\n', 'RESOURCE_PARSE_ERROR'),
    'URDF that does not parse': (f'<robot name="{MARK}"><link name="a"></robot',
                                 'RESOURCE_PARSE_ERROR'),
    'not a manifest': (f'{MARK}: 1\nother: 2\n', 'UNSUPPORTED_FORMAT'),
    'another version': (f'r2d2_sim_world: 2\nname: {MARK}\n', 'UNSUPPORTED_FORMAT'),
    'MJCF': (f'<mujoco model="{MARK}"><worldbody/></mujoco>', 'UNSUPPORTED_FORMAT'),
    'SDF of another version': (f'<sdf version="1.2"><world name="{MARK}"/></sdf>',
                               'UNSUPPORTED_FORMAT'),
    'YAML alias bomb': (ALIAS_BOMB, 'RESOURCE_PARSE_ERROR'),
    'deep nesting': ('r2d2_sim_world: 1\nx: ' + '[' * (MAX_YAML_DEPTH + 5) + MARK
                     + ']' * (MAX_YAML_DEPTH + 5) + '\n', 'RESOURCE_PARSE_ERROR'),
    'python object tag': (f'r2d2_sim_world: 1\nname: !!python/object/apply:os.system ["{MARK}"]\n',
                          'RESOURCE_PARSE_ERROR'),
    'entity bomb': (ENTITY_BOMB, 'RESOURCE_PARSE_ERROR'),
    'huge': ('r2d2_sim_world: 1\nname: x\n#' + MARK * (MAX_WORLD_BYTES // len(MARK) + 1),
             'RESOURCE_PARSE_ERROR'),
    'a pose not unit': ('r2d2_sim_world: 1\nname: x\nnamed_poses:\n  - {name: p, orientation: '
                        '[0, 0, 0, 2]}\n', 'RESOURCE_PARSE_ERROR'),
    'bounds with a point': ('r2d2_sim_world: 1\nnamed_poses:\n  - name: p\n    bounds: {box: '
                            '[[1, 1, 1]]}\n', 'RESOURCE_PARSE_ERROR'),
    'a tag flood': ('r2d2_sim_world: 1\ntags: [' + ', '.join(
        f't{i}' for i in range(MAX_TAGS + 1)) + ']\n', 'RESOURCE_PARSE_ERROR'),
    'a model outside': ('r2d2_sim_world: 1\nmodels:\n  - {uri: /etc/hostname.urdf}\n',
                        'UNSUPPORTED_ASSETS'),
    'a model of another format': ('r2d2_sim_world: 1\nmodels:\n  - {uri: mjcf/ant.xml}\n',
                                  'UNSUPPORTED_ASSETS'),
    'a mesh outside': ('<robot name="m"><link name="a"><visual><geometry><mesh '
                       'filename="/etc/passwd"/></geometry></visual></link></robot>',
                       'UNSUPPORTED_ASSETS'),
    'two poses of one name': ('r2d2_sim_world: 1\nnamed_poses:\n  - {name: p}\n  - {name: p}\n',
                              'RESOURCE_PARSE_ERROR'),
    'a start pose that is not there': ('r2d2_sim_world: 1\nstart_pose: nowhere\n',
                                       'RESOURCE_PARSE_ERROR'),
    'nothing': ('', 'NO_RESOURCE'),
}


@pytest.mark.parametrize('text, code', BAD_TEXTS.values(), ids=BAD_TEXTS.keys())
def test_a_bad_world_text_is_refused_and_the_world_runs_on_as_it_was(make, text, code):
    twin, simulation = make(), make()
    drive_and_read(twin, 60)
    drive_and_read(simulation, 60)
    with pytest.raises(RefusedError) as refused:
        simulation.load_world('', text)
    assert refused.value.code == code, refused.value
    assert MARK not in str(refused.value) and '\n' not in str(refused.value)
    assert simulation.worlds.current.name == 'room' and simulation.step_count == 60
    # Exactly as it was: the same run, bit for bit.
    assert drive_and_read(simulation) == drive_and_read(twin)


def test_bad_world_files_are_refused_by_name_without_their_contents(make, tmp_path):
    for name, (text, _) in BAD_TEXTS.items():
        suffix = '.urdf' if text.startswith('<') else '.world.yaml'
        (tmp_path / (name.replace(' ', '_') + suffix)).write_text(text)
    (tmp_path / 'stadium.sdf').write_text(f'<sdf>{MARK}</sdf>')
    (tmp_path / 'lists_stadium.world.yaml').write_text(  # beside it: not pybullet_data's
        'r2d2_sim_world: 1\nmodels:\n  - {uri: stadium.sdf}\n')
    (tmp_path / 'folder.world.yaml').mkdir()
    simulation = make(world_paths=[str(tmp_path)])
    expected = dict(BAD_TEXTS)
    expected['nothing'] = ('', 'UNSUPPORTED_FORMAT')  # an empty YAML file is no manifest
    for name, (text, code) in expected.items():
        suffix = '.urdf' if text.startswith('<') else '.world.yaml'
        path = str(tmp_path / (name.replace(' ', '_') + suffix))
        with pytest.raises(RefusedError) as refused:
            simulation.load_world(path)
        assert refused.value.code == code, (name, refused.value)
        assert MARK not in str(refused.value) and path in str(refused.value)
    for path, code in ((tmp_path / 'stadium.sdf', 'UNSUPPORTED_FORMAT'),
                       (tmp_path / 'lists_stadium.world.yaml', 'UNSUPPORTED_ASSETS'),
                       (tmp_path / 'folder.world.yaml', 'NOT_FOUND'),
                       (tmp_path / 'no_such.world.yaml', 'NOT_FOUND')):
        with pytest.raises(RefusedError, match=f'^{code}:'):
            simulation.load_world(str(path))
    assert simulation.worlds.current.name == 'room'


def test_outside_the_allowed_places_only_the_operator_may_load(make, tmp_path):
    (tmp_path / 'mine.world.yaml').write_text('r2d2_sim_world: 1\nname: mine\n')
    simulation = make()
    with pytest.raises(RefusedError, match='^NOT_FOUND: .*outside the places worlds are loaded'):
        simulation.load_world(str(tmp_path / 'mine.world.yaml'))
    with pytest.raises(RefusedError, match='^NOT_FOUND: .*outside the places'):
        simulation.load_world('file:///etc/passwd')
    with pytest.raises(RefusedError, match='^NOT_FOUND: .*only local files'):
        simulation.load_world('https://example.com/world.world.yaml')
    assert make(world=str(tmp_path / 'mine.world.yaml')).worlds.current.name == 'mine'


@pytest.mark.parametrize('uri', [ROOM + '\0', 'room\0.world.yaml', 'file:///tmp/\0.world.yaml'])
def test_a_nul_byte_in_a_world_uri_is_refused_in_one_line(make, uri):
    """Python's path functions raised ValueError 'embedded null byte' (the Python API only)."""
    simulation = make()
    with pytest.raises(RefusedError) as refused:
        simulation.load_world(uri)
    assert (refused.value.code, refused.value.message) == (
        'NOT_FOUND', f'{uri!r}: no such file (a path cannot hold a NUL byte)')
    assert simulation.worlds.current.name == 'room'


def test_a_nul_byte_in_a_model_uri_is_a_missing_asset(make):
    """A YAML escape puts one in a model's URI, over ROS too (LoadWorld's resource_string)."""
    simulation = make()
    world = ('r2d2_sim_world: 1\nname: n\nmodels:\n'
             '  - {uri: "cube\\0.urdf", position: [5.0, 5.0, 0.1]}\n')
    with pytest.raises(RefusedError) as refused:
        simulation.load_world('', world)
    assert (refused.value.code, refused.value.message) == (
        'MISSING_ASSETS', "'cube\\x00.urdf': no such file (a path cannot hold a NUL byte)")
    assert simulation.worlds.current.name == 'room'


def test_an_unknown_named_pose_is_not_found(make):
    simulation = make()
    with pytest.raises(RefusedError, match=r"^NOT_FOUND: no named pose 'kitchen_door'"):
        simulation.worlds.named_pose('kitchen_door')


@pytest.mark.parametrize('tags', [
    [f't{i}' for i in range(MAX_TAGS + 1)], ['x' * (MAX_TAG_LENGTH + 1)], [''], ['a\nb']],
    ids=['too many', 'too long', 'empty', 'control character'])
def test_a_tag_flood_is_refused_and_the_info_stays(make, tags):
    simulation = make()
    simulation.set_entity_info('room', Category.STATIC_OBJECT, 'the room', ['walls'])
    with pytest.raises(RefusedError, match='^OPERATION_FAILED: .*tag'):
        simulation.set_entity_info('room', Category.STATIC_OBJECT, 'flooded', tags)
    assert simulation.entities.info('room').tags == ('walls',)
    assert simulation.entities.info('room').description == 'the room'
    with pytest.raises(RefusedError, match='^OPERATION_FAILED: .*tag'):
        check_filter(tags, 0)


def test_set_entity_info_refuses_an_unknown_category_or_entity(make):
    simulation = make()
    with pytest.raises(RefusedError, match='^OPERATION_FAILED: unknown entity category 3'):
        simulation.set_entity_info('room', 3, '', [])
    with pytest.raises(RefusedError, match='^NOT_FOUND'):
        simulation.set_entity_info('kitchen', Category.OBJECT, '', [])
    with pytest.raises(RefusedError, match='^OPERATION_FAILED: unknown tags filter_mode'):
        check_filter(['a'], 7)


def test_comments_before_the_root_element_are_read_past_in_one_pass():
    """
    Read '<!---->' * n before the root in one pass, never 2^n tries.

    A regular expression with ``.*?`` across comments tries about 2^n ways
    (27 held LoadWorld and every service 47 s); a scan reads each once. The
    sniffers of LoadWorld and SpawnEntity run in a process of their own, under
    a deadline that only a stuck sniffer (hours at n = 40) meets, not a
    measure of speed; 9,000 comments (99 kB) show the scan is linear.
    """
    code = '\n'.join([
        'from r2d2_sim.errors import RefusedError',
        'from r2d2_sim.sim.sdf.elements import root_tag',
        'from r2d2_sim.sim.sdf.spawning import is_sdf_spawn',
        'from r2d2_sim.sim.worlds import Places, read_world',
        "comments = '<!---->' * 40",
        "world = '<sdf version=\"1.9\"><world name=\"w\"/></sdf>'",
        "print(repr(root_tag(comments)), root_tag(comments + ' <sdf/>'),",
        "      root_tag('<?xml version=\"1.0\"?>' + '<!-- a -->\\n' * 9000 + '<robot/>'),",
        "      is_sdf_spawn('', comments), is_sdf_spawn('', comments + world))",
        'try:',
        "    read_world('', comments, Places())",
        'except RefusedError as exc:',
        '    print(exc.code)',
        "print(read_world('', comments + world, Places()).name)",
    ])
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split() == ["''", 'sdf', 'robot', 'False', 'True', 'UNSUPPORTED_FORMAT',
                                     'w']
