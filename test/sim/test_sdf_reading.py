"""
Reading SDF: includes through model paths and Fuel's cache, nested models, frames, joints, notes.

No ROS, no physics: the tests write their own models (directories with
model.config, as Gazebo keeps them) and read them with the reader r2d2_sim
loads worlds with, then check every pose against geometry worked out by
hand, and every refusal for its standard code and a one-line message that
names the file and the element, never the file's text.
"""

import math
import os

import pytest

from common import approx
from r2d2_sim.errors import RefusedError
from r2d2_sim.model.transforms import apply, compose
from r2d2_sim.sim.sdf import elements, reader as reader_module
from r2d2_sim.sim.sdf.reader import Reader, ReadOptions
from r2d2_sim.sim.sdf.resources import Resources
from r2d2_sim.sim.worlds import LoadOptions, Places, read_world, SdfSettings
from sdf_files import box_model, model_dir, sdf

SECRET = 'do-not-echo-7f3a'  # text of a file that no message may show


def read(text, directory, model_paths=(), environ=None, options=ReadOptions(), name='w.sdf'):
    """Read an SDF text as a file ``name`` in ``directory``; return the scene."""
    path = os.path.join(str(directory), name)
    with open(path, 'w') as handle:
        handle.write(text)
    resources = Resources(model_paths, environ={} if environ is None else environ)
    return Reader(resources, options).read(text, path, name)


def links(scene):
    return {f'{m.name}/{link.name}': link for m in scene.models for link in m.links}


def world_position(model, link, point=(0.0, 0.0, 0.0)):
    return apply(compose(model.pose, link.pose), point)


def test_includes_find_models_on_the_model_path_with_their_name_and_pose(tmp_path):
    models = tmp_path / 'models'
    model_dir(models, 'crate', box_model('crate', static=True))
    scene = read(sdf('<world name="w">'
                     '<include><uri>model://crate</uri><name>a</name>'
                     '<pose>1 2 0 0 0 1.5707963267948966</pose></include>'
                     '<include><uri>model://crate</uri><name>b</name></include></world>'),
                 tmp_path, [str(models)])
    assert [m.name for m in scene.models] == ['a', 'b']
    a = scene.models[0]
    assert (a.static, a.source) == (True, 'model://crate/model.sdf')
    assert a.pose.translation == approx((1.0, 2.0, 0.0))
    assert world_position(a, a.links[0], (1.0, 0.0, 0.0)) == approx((1.0, 3.0, 0.0))


@pytest.mark.parametrize('name, problem', [
    ('x' * 256, 'a <include> needs a name of 1 to 255 characters'),
    ('x' * 1100, 'a <include> needs a name of 1 to 255 characters'),  # PyBullet's SIGSEGV
    ('a::b', "a model's name cannot hold ::"),
])
def test_an_include_name_gets_the_checks_of_a_model_name(tmp_path, name, problem):
    """Refuse in one line what <model name> refuses: the name becomes a PyBullet body's."""
    models = tmp_path / 'models'
    model_dir(models, 'crate', box_model('crate', static=True))
    with pytest.raises(RefusedError) as raised:
        read(sdf(f'<world name="w"><include><uri>model://crate</uri><name>{name}</name>'
                 '</include></world>'), tmp_path, [str(models)])
    assert raised.value.code == 'RESOURCE_PARSE_ERROR'
    assert problem in raised.value.message and '\n' not in raised.value.message
    assert len(raised.value.message) < 300  # the name is not echoed whole


def test_the_gazebo_variables_are_searched_after_model_paths(tmp_path):
    first, second = tmp_path / 'first', tmp_path / 'second'
    model_dir(first, 'thing', box_model('from_parameter', static=True))
    model_dir(second, 'thing', box_model('from_variable', static=True))
    model_dir(second, 'other', box_model('only_in_variable', static=True))
    world = sdf('<world name="w"><include><uri>model://thing</uri></include>'
                '<include><uri>model://other</uri></include></world>')
    for variable in ('GZ_SIM_RESOURCE_PATH', 'GAZEBO_MODEL_PATH', 'SDF_PATH'):
        scene = read(world, tmp_path, [str(first)], {variable: f'/nowhere:{second}'})
        assert [m.name for m in scene.models] == ['from_parameter', 'only_in_variable']


def test_model_config_chooses_the_newest_sdf_of_a_model(tmp_path):
    directory = model_dir(tmp_path / 'models', 'versions', box_model('old', static=True))
    with open(os.path.join(directory, 'model-1_9.sdf'), 'w') as handle:
        handle.write(sdf(box_model('new', static=True)))
    with open(os.path.join(directory, 'model.config'), 'w') as handle:
        handle.write('<model><sdf version="1.6">model.sdf</sdf>'
                     '<sdf version="1.9">model-1_9.sdf</sdf></model>')
    scene = read(sdf('<world name="w"><include><uri>model://versions</uri></include></world>'),
                 tmp_path, [str(tmp_path / 'models')])
    assert [m.name for m in scene.models] == ['new']


def fuel_model(cache, owner, name, version, model_name):
    directory = cache / 'fuel.gazebosim.org' / owner / 'models' / name / str(version)
    directory.mkdir(parents=True)
    (directory / 'model.config').write_text('<model><sdf version="1.9">model.sdf</sdf></model>')
    (directory / 'model.sdf').write_text(sdf(box_model(model_name, static=True)))


def test_fuel_urls_come_from_the_local_cache_newest_version_unless_one_is_named(tmp_path):
    cache = tmp_path / 'fuel'
    fuel_model(cache, 'openrobotics', 'crate', 1, 'crate_one')
    fuel_model(cache, 'openrobotics', 'crate', 2, 'crate_two')
    url = 'https://fuel.gazebosim.org/1.0/OpenRobotics/models/Crate'
    scene = read(sdf(f'<world name="w"><include><uri>{url}</uri></include>'
                     f'<include><uri>{url}/1</uri></include>'
                     f'<include><uri>{url}/tip</uri><name>tip</name></include></world>'),
                 tmp_path, environ={'GZ_FUEL_CACHE_PATH': str(cache)})
    assert [m.name for m in scene.models] == ['crate_two', 'crate_one', 'tip']


def test_the_ground_plane_and_the_sun_need_no_fuel_cache(tmp_path):
    scene = read(sdf('<world name="w">'
                     '<include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/models/Ground%20'
                     'Plane</uri></include><include><uri>https://fuel.gazebosim.org/1.0/'
                     'OpenRobotics/models/Sun</uri></include>'
                     '<include><uri>model://ground_plane</uri><name>g2</name></include></world>'),
                 tmp_path, environ={'GZ_FUEL_CACHE_PATH': str(tmp_path / 'empty')})
    assert [m.name for m in scene.models] == ['ground_plane', 'g2']
    assert scene.models[0].links[0].collisions[0].geometry.kind == 'plane'
    assert dict(scene.not_simulated) == {'light': 1}  # the sun


def test_a_fuel_model_missing_from_the_cache_is_named_and_never_downloaded(tmp_path):
    with pytest.raises(RefusedError) as raised:
        read(sdf('<world name="w"><include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/'
                 'models/Depot</uri></include></world>'), tmp_path,
             environ={'GZ_FUEL_CACHE_PATH': str(tmp_path)})
    assert raised.value.code == 'MISSING_ASSETS'
    assert 'Fuel model OpenRobotics/Depot is not in the local Fuel cache' in raised.value.message
    assert 'gz fuel download' in raised.value.message and '\n' not in raised.value.message


def test_nested_models_and_relative_to_frames_resolve_to_the_top_models_frame(tmp_path):
    """A door frame 1 m along x; its panel 0.5 m along the frame's y (turned 90 degrees)."""
    scene = read(sdf('''<world name="w"><model name="house"><pose>10 0 0 0 0 0</pose>
      <frame name="doorway"><pose>1 0 0 0 0 1.5707963267948966</pose></frame>
      <model name="door"><pose relative_to="doorway">0 0 0 0 0 0</pose>
        <link name="panel"><pose>0.5 0 1 0 0 0</pose></link>
        <frame name="handle" attached_to="panel"><pose>0 0.4 0 0 0 0</pose></frame>
      </model>
      <link name="marker"><pose relative_to="door::handle">0 0 0 0 0 0</pose></link>
    </model>
    <frame name="goal"><pose relative_to="house::door::panel">0 0 -1 0 0 0</pose></frame>
    </world>'''), tmp_path)
    house = scene.models[0]
    found = links(scene)
    assert sorted(found) == ['house/door::panel', 'house/marker']
    # doorway (11, 0) facing +y: the panel 0.5 m along it -> (11, 0.5, 1); the handle 0.4 m
    # along the panel's y (world -x) -> (10.6, 0.5, 1).
    assert world_position(house, found['house/door::panel']) == approx((11.0, 0.5, 1.0))
    assert world_position(house, found['house/marker']) == approx((10.6, 0.5, 1.0))
    assert [(f.name, f.pose.translation) for f in scene.frames] == [
        ('goal', approx((11.0, 0.5, 0.0)))]


def test_placement_frame_puts_a_frame_of_the_model_at_the_pose(tmp_path):
    scene = read(sdf('''<world name="w"><model name="m" placement_frame="corner">
      <pose>5 0 0 0 0 0</pose><frame name="corner"><pose>1 1 0 0 0 0</pose></frame>
      <link name="l"/></model></world>''', '1.8'), tmp_path)
    model = scene.models[0]
    assert apply(model.pose, (1.0, 1.0, 0.0)) == approx((5.0, 0.0, 0.0))


@pytest.mark.parametrize('version, axis_xml, expected', [
    ('1.4', '<axis><xyz>1 0 0</xyz></axis>', (1.0, 0.0, 0.0)),          # the model's frame
    ('1.6', '<axis><xyz>1 0 0</xyz></axis>', (0.0, 1.0, 0.0)),          # the joint's frame
    ('1.6', '<axis><xyz>1 0 0</xyz><use_parent_model_frame>true</use_parent_model_frame>'
            '</axis>', (1.0, 0.0, 0.0)),
    ('1.7', '<axis><xyz>1 0 0</xyz></axis>', (0.0, 1.0, 0.0)),
    ('1.7', '<axis><xyz expressed_in="__model__">1 0 0</xyz></axis>', (1.0, 0.0, 0.0)),
])
def test_a_joint_axis_is_in_the_frame_its_sdf_version_says(
        tmp_path, version, axis_xml, expected):
    """The child link is turned 90 degrees about z: its x is the model's y."""
    scene = read(sdf(f'''<model name="m"><link name="a"/>
      <link name="b"><pose>0 0 1 0 0 1.5707963267948966</pose></link>
      <joint name="j" type="revolute"><parent>a</parent><child>b</child>{axis_xml}</joint>
      </model>''', version), tmp_path)
    assert scene.models[0].joints[0].axis == approx(expected)


@pytest.mark.parametrize('axis_flag, axis2_flag', [(False, True), (True, False), (True, True)])
def test_axis_and_axis2_each_have_their_own_use_parent_model_frame_before_1_7(
        tmp_path, axis_flag, axis2_flag):
    """Read each flag for its own axis, as sdformat's 1.6 to 1.7 conversion does."""
    def axis(tag, flag):
        return (f'<{tag}><xyz>1 0 0</xyz><use_parent_model_frame>{str(flag).lower()}'
                f'</use_parent_model_frame></{tag}>')
    scene = read(sdf(f'''<model name="m"><link name="a"/>
      <link name="b"><pose>0 0 1 0 0 1.5707963267948966</pose></link>
      <joint name="j" type="universal"><parent>a</parent><child>b</child>
      {axis('axis', axis_flag)}{axis('axis2', axis2_flag)}</joint></model>''', '1.6'), tmp_path)
    joint = scene.models[0].joints[0]
    # The child is turned 90 degrees about z: the joint's x is the model's y.
    model_x, joint_x = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)
    assert joint.axis == approx(model_x if axis_flag else joint_x)
    assert joint.axis2 == approx(model_x if axis2_flag else joint_x)


@pytest.mark.parametrize('limit_xml, expected', [
    ('<lower>-inf</lower><upper>inf</upper><effort>inf</effort><velocity>inf</velocity>',
     (1.0, -1.0, 0.0, 0.0)),                         # SDF 1.10+'s defaults: no limit at all
    ('<lower>-inf</lower><upper>0.5</upper>', (1.0, -1.0, 0.0, 0.0)),  # one side: none
    ('<lower>-0.5</lower><upper>0.5</upper><effort>3</effort><velocity>inf</velocity>',
     (-0.5, 0.5, 3.0, 0.0)),  # effort and velocity 0: none
])
def test_infinite_joint_limits_are_no_limit(tmp_path, limit_xml, expected):
    """Read ±inf as sdformat does (joint_axis_infinite_limits.sdf): no limit, no refusal."""
    scene = read(sdf(f'''<model name="m"><link name="a"/><link name="b"/>
      <joint name="j" type="revolute"><parent>a</parent><child>b</child>
      <axis><xyz>0 0 1</xyz><limit>{limit_xml}</limit></axis></joint></model>''', '1.11'),
                 tmp_path)
    limits = scene.models[0].joints[0].limits
    assert (limits.lower, limits.upper, limits.effort, limits.velocity) == expected


def test_a_nan_joint_limit_is_still_refused(tmp_path):
    with pytest.raises(RefusedError, match='<upper> must be 1 finite number'):
        read(sdf('''<model name="m"><link name="a"/><link name="b"/>
          <joint name="j" type="revolute"><parent>a</parent><child>b</child>
          <axis><limit><lower>0</lower><upper>nan</upper></limit></axis></joint></model>''',
                 '1.11'), tmp_path)


@pytest.mark.parametrize('version, attribute, expected', [
    ('1.5', 'frame="l1"', (5.0, 3.0, 0.0)),         # relative to l1, at (5, 0, 0)
    ('1.6', 'frame="l1"', (5.0, 3.0, 0.0)),
    ('1.6', 'frame=""', (0.0, 3.0, 0.0)),           # empty: the default, the model's frame
    ('1.7', 'frame="l1"', (0.0, 3.0, 0.0)),         # 1.7 has no frame attribute
    ('1.7', 'relative_to="l1"', (5.0, 3.0, 0.0)),
])
def test_a_pose_frame_before_sdf_1_7_is_what_1_7_calls_relative_to(
        tmp_path, version, attribute, expected):
    """Read 1.5-1.6's //pose/@frame as relative_to, as sdformat does: in a world, included."""
    model = ('<model name="m"><static>true</static><link name="l1"><pose>5 0 0 0 0 0</pose>'
             f'</link><link name="l2"><pose {attribute}>0 3 0 0 0 0</pose></link></model>')
    model_dir(tmp_path / 'models', 'm', model, version)
    for scene in (read(sdf(f'<world name="w">{model}</world>', version), tmp_path),
                  read(sdf('<world name="w"><include><uri>model://m</uri></include></world>'),
                       tmp_path, [str(tmp_path / 'models')], name='including.sdf')):
        assert world_position(scene.models[0], links(scene)['m/l2']) == approx(expected)


def test_what_is_not_simulated_is_counted_by_what_it_is(tmp_path):
    scene = read(sdf('''<world name="w"><gravity>0 0 -9.81</gravity>
      <physics type="ode"><max_step_size>0.001</max_step_size><ode/></physics>
      <light name="l1" type="point"/><light name="l2" type="point"/>
      <plugin name="p" filename="x"/><actor name="walker"/><scene/>
      <model name="m"><plugin name="q" filename="y"/><link name="l">
        <sensor name="s" type="camera"/><collision name="c"><geometry><heightmap/></geometry>
        </collision></link></model></world>'''), tmp_path,
                 options=ReadOptions(1 / 240, (0.0, 0.0, -9.8)))
    counts = dict(scene.not_simulated)
    assert counts['light'] == 2 and counts['plugin'] == 2
    assert counts['actor'] == counts['scene'] == counts['sensor'] == 1
    assert counts['heightmap geometry'] == counts['physics ode settings'] == 1
    assert counts['physics max_step_size 0.001 s (r2d2_sim steps 0.00416667 s: '
                  'physics_rate)'] == 1
    assert any(what.startswith('gravity 0 0 -9.81') for what in counts)


def world_file(tmp_path, body, name='world.sdf'):
    path = tmp_path / name
    path.write_text(body)
    return str(path)


def test_a_world_with_things_not_simulated_notes_one_line_or_is_refused_when_strict(tmp_path):
    path = world_file(tmp_path, sdf('<world name="w"><light name="a" type="point"/>'
                                    '<light name="b" type="point"/><plugin name="p" '
                                    'filename="f"/>' + box_model('crate') + '</world>'))
    world = read_world(path, '', Places(), trusted=True)
    assert world.notes == ('not simulated: light x2, plugin',)
    assert 'not simulated: light x2, plugin' in world.description
    with pytest.raises(RefusedError) as raised:
        read_world(path, '', Places(), LoadOptions(fail_on_unsupported_element=True),
                   trusted=True)
    assert (raised.value.code, raised.value.message) == (
        'UNSUPPORTED_ELEMENTS', f'{path}: not simulated: light x2, plugin')


@pytest.mark.parametrize('text, code, problem', [
    (f'<!DOCTYPE sdf [<!ENTITY x "{SECRET}">]><sdf version="1.9"/>', 'RESOURCE_PARSE_ERROR',
     'declares a DOCTYPE or entities'),
    (f'<sdf version="1.9"><world name="{SECRET}"', 'RESOURCE_PARSE_ERROR',
     'not well-formed XML'),
    ('<sdf version="1.3"><model name="m"><link name="l"/></model></sdf>', 'UNSUPPORTED_FORMAT',
     "SDF version '1.3': r2d2_sim reads SDF 1.4 to 1.11"),
    (sdf(f'<model name="m"><link name="l"><collision name="c"><geometry><box><size>1 -1 '
         f'{SECRET}</size></box></geometry></collision></link></model>'),
     'RESOURCE_PARSE_ERROR', 'w.sdf: model m, link l, collision c, geometry, box: <size> must be '
                             '3 finite numbers'),
    (sdf('<model name="m"><link name="l"/><joint name="j" type="screwy"><parent>l</parent>'
         '<child>l2</child></joint></model>'), 'RESOURCE_PARSE_ERROR',
     "model m, joint j: unknown joint type 'screwy'"),
    (sdf('<model name="m"><link name="l"/><joint name="j" type="fixed"><parent>l</parent>'
         '<child>ghost</child></joint></model>'), 'RESOURCE_PARSE_ERROR',
     "joint j: 'ghost' names no link of the model"),
    (sdf('<model name="m"><link name="l"><pose relative_to="nowhere">0 0 0 0 0 0</pose>'
         '</link></model>'), 'RESOURCE_PARSE_ERROR',
     "relative to 'nowhere', which names no frame"),
    (sdf('<world name="w"><include><uri>http://example.com/models/x</uri></include></world>'),
     'UNSUPPORTED_ASSETS', 'only local files and Fuel models in the local cache'),
    (sdf('<world name="w"><include><uri>model://nothing_here</uri></include></world>'),
     'MISSING_ASSETS', 'model model://nothing_here is in none of the model search paths'),
])
def test_bad_sdf_gets_its_code_and_one_line_naming_the_place_not_the_text(tmp_path, text, code,
                                                                          problem):
    with pytest.raises(RefusedError) as raised:
        read(text, tmp_path)
    assert raised.value.code == code
    assert problem in raised.value.message
    assert SECRET not in raised.value.message and '\n' not in raised.value.message


def test_models_nested_too_deep_are_one_line_not_a_recursion_error(tmp_path):
    nested = '<link name="l"/>'
    for i in range(200):
        nested = f'<model name="m{i}">{nested}</model>'
    with pytest.raises(RefusedError, match='models nest deeper than 32') as raised:
        read(sdf(f'<world name="w">{nested}</world>'), tmp_path)
    assert raised.value.code == 'RESOURCE_PARSE_ERROR'


def test_a_pose_beyond_the_blow_up_bound_is_refused(tmp_path):
    with pytest.raises(RefusedError, match=r'model m, link l: <pose> is more than 10000 m out'):
        read(sdf('<model name="m"><link name="l"><pose>1e300 0 0 0 0 0</pose></link></model>'),
             tmp_path)


def test_a_model_that_includes_itself_stops_at_the_include_depth(tmp_path):
    model_dir(tmp_path / 'models', 'loop',
              '<model name="loop"><link name="l"/><include><uri>model://loop</uri>'
              '<name>again</name></include></model>')
    with pytest.raises(RefusedError, match='includes nest deeper than 16'):
        read(sdf('<world name="w"><include><uri>model://loop</uri></include></world>'),
             tmp_path, [str(tmp_path / 'models')])


def test_the_element_budget_counts_every_include(tmp_path, monkeypatch):
    model_dir(tmp_path / 'models', 'crate', box_model('crate', static=True))
    include = '<include><uri>model://crate</uri><name>c{}</name></include>'
    world = sdf('<world name="w">' + ''.join(include.format(i) for i in range(10)) + '</world>')
    read(world, tmp_path, [str(tmp_path / 'models')])
    monkeypatch.setattr(elements, 'MAX_SDF_ELEMENTS', 100)
    with pytest.raises(RefusedError, match='more than 100 XML elements in all its files'):
        read(world, tmp_path, [str(tmp_path / 'models')])


def test_a_file_over_the_size_bound_is_refused_unread(tmp_path, monkeypatch):
    monkeypatch.setattr(reader_module, 'MAX_SDF_BYTES', 300)
    model_dir(tmp_path / 'models', 'big', box_model('big', static=True, extra=' ' * 400))
    with pytest.raises(RefusedError, match=r'model://big/model.sdf is larger than 300 bytes'):
        read(sdf('<world name="w"><include><uri>model://big</uri></include></world>'),
             tmp_path, [str(tmp_path / 'models')])


def test_a_request_may_not_reach_files_outside_the_allowed_places(tmp_path):
    outside = tmp_path / 'outside'
    model_dir(outside, 'crate', box_model('crate', static=True))
    inside = tmp_path / 'worlds'
    inside.mkdir()
    path = world_file(inside, sdf(f'<world name="w"><include><uri>{outside}/crate</uri>'
                                  '</include></world>'))
    places = Places([str(inside)])
    assert read_world(path, '', places, trusted=True).models  # the operator's: anything
    with pytest.raises(RefusedError) as raised:
        read_world(path, '', places)
    assert raised.value.code == 'UNSUPPORTED_ASSETS'
    assert 'lies outside the places an SDF may use' in raised.value.message
    # ... unless the directory is on the model path, where Gazebo users keep models.
    assert read_world(path, '', places, sdf=SdfSettings(model_paths=(str(outside),))).models


def test_a_relative_mesh_in_text_sent_as_a_resource_string_is_refused(tmp_path):
    text = sdf('<world name="w"><model name="m"><static>true</static><link name="l">'
               '<collision name="c"><geometry><mesh><uri>meshes/wall.dae</uri></mesh>'
               '</geometry></collision></link></model></world>')
    with pytest.raises(RefusedError) as raised:
        read_world('', text, Places())
    assert raised.value.code == 'UNSUPPORTED_ASSETS'
    assert 'a relative path in text sent as a resource_string' in raised.value.message


def test_missing_assets_are_left_out_and_named_when_the_request_allows_it(tmp_path):
    path = world_file(tmp_path, sdf('<world name="w"><include><uri>model://gone</uri>'
                                    '</include>' + box_model('crate') + '</world>'))
    with pytest.raises(RefusedError) as raised:
        read_world(path, '', Places(), trusted=True)
    assert raised.value.code == 'MISSING_ASSETS'
    assert raised.value.message.startswith(f'{path}: world w, include: model model://gone is '
                                           'in none of the model search paths')
    world = read_world(path, '', Places(),
                       LoadOptions(ignore_missing_or_unsupported_assets=True), trusted=True)
    assert [m.name for m in world.models] == ['crate']
    assert any(note.startswith('left out: ') and 'model://gone' in note for note in world.notes)


def test_world_frames_are_named_poses_and_start_is_the_start_pose(tmp_path):
    path = world_file(tmp_path, sdf('''<world name="w">
      <frame name="start"><pose>1 2 0 0 0 1.5707963267948966</pose></frame>
      <frame name="goal"><pose relative_to="start">2 0 0 0 0 0</pose></frame></world>'''))
    world = read_world(path, '', Places(), trusted=True)
    assert [pose.name for pose in world.named_poses] == ['start', 'goal']
    assert world.start_pose.name == 'start'
    assert world.named_poses[1].position == approx((1.0, 4.0, 0.0))
    assert world.named_poses[1].orientation[2:] == approx(
        (math.sin(math.pi / 4), math.cos(math.pi / 4)))


def test_the_default_fuel_caches_are_gazebos_and_ignitions_in_the_home(tmp_path, monkeypatch):
    monkeypatch.setenv('HOME', str(tmp_path))
    directory = tmp_path / '.ignition' / 'fuel' / 'fuel.ignitionrobotics.org' / 'openrobotics' \
        / 'models' / 'crate' / '3'
    directory.mkdir(parents=True)
    (directory / 'model.sdf').write_text(sdf(box_model('old_crate', static=True)))
    scene = read(sdf('<world name="w"><include><uri>https://fuel.gazebosim.org/1.0/OpenRobotics/'
                     'models/crate</uri></include></world>'), tmp_path)
    assert [m.name for m in scene.models] == ['old_crate']
