"""
Files a hostile world brings, or another user of the machine leaves, in the core.

No ROS. A security review found each of these: a mesh that is a FIFO (the load
waited for a writer forever), a zipped COLLADA file (pycollada unpacks it past
every bound), a URDF's meshes (loaded by PyBullet unbounded), an SDF model
spawned from outside the allowed places, and a mesh cache others can write.
Each must be refused at once in one line with the standard's code, naming the
file and never its contents. Calls that used to block run in a thread under a
deadline (5 s) that only a blocked call meets.
"""

import os
import threading

import pytest

from r2d2_sim.errors import RefusedError
from sdf_files import sdf

SIMULATION_DEFAULTS = {'scan_rate': 0.0, 'imu_rate': 0.0, 'cmd_vel_timeout': 0.0}
DEADLINE_S = 5.0


def within_deadline(call, unblock=lambda: None):
    """
    Return what ``call()`` raised (or returned) when it ends within DEADLINE_S.

    Fails the test when it does not end; ``unblock`` then releases it (a
    thread blocked in a system call cannot be stopped from outside).
    """
    outcome = {}

    def run():
        try:
            outcome['value'] = call()
        except BaseException as exc:  # handed to the test
            outcome['value'] = exc
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(DEADLINE_S)
    if thread.is_alive():
        unblock()
        thread.join(DEADLINE_S)
        pytest.fail(f'the call did not end within {DEADLINE_S:g} s')
    return outcome['value']


def release_fifo(path):
    """Open ``path`` for writing and close it: a reader blocked on the FIFO reads its end."""
    def unblock():
        try:
            os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
        except OSError:
            pass
    return unblock


def mesh_world(directory, uri, name='hostile'):
    """Write an SDF world of one static model with the mesh ``uri``; return its path."""
    path = directory / f'{name}.sdf'
    path.write_text(sdf(
        f'<world name="{name}"><model name="thing"><static>true</static><link name="l">'
        f'<collision name="c"><geometry><mesh><uri>{uri}</uri></mesh></geometry></collision>'
        '</link></model></world>'))
    return str(path)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """Keep meshes converted in a cache of the test's own."""
    monkeypatch.setenv('R2D2_SIM_CACHE_DIR', str(tmp_path / 'cache'))
    return tmp_path / 'cache'


def test_a_mesh_that_is_a_fifo_is_refused_at_once_not_waited_for(make, tmp_path, cache):
    os.mkfifo(tmp_path / 'wall.stl')
    world = mesh_world(tmp_path, 'wall.stl')
    simulation = make(world_paths=[str(tmp_path)])
    refused = within_deadline(lambda: simulation.load_world(world),
                              release_fifo(str(tmp_path / 'wall.stl')))
    assert isinstance(refused, RefusedError), refused
    assert refused.code == 'UNSUPPORTED_ASSETS'
    assert 'wall.stl is not a regular file' in refused.message
    assert simulation.worlds.current.name == 'empty'


def urdf_with_mesh(directory, mesh, uses=1, name='meshy'):
    """Write a URDF beside ``mesh`` (a file name in ``directory``) that uses it ``uses`` times."""
    visuals = ''.join(f'<visual><geometry><mesh filename="{mesh}"/></geometry></visual>'
                      for _ in range(uses))
    path = directory / f'{name}.urdf'
    path.write_text(f'<robot name="{name}"><link name="base"><inertial><mass value="1"/>'
                    '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'
                    f'</inertial>{visuals}</link></robot>')
    return str(path)


@pytest.mark.parametrize('bound, value, problem', [
    ('MAX_MESH_TRIANGLES', 11, 'has 12 triangles, more than 11'),
    ('MAX_MESH_BYTES', 100, 'larger than 100 bytes'),
], ids=['triangles', 'bytes'])
def test_a_urdfs_meshes_have_the_bounds_of_an_sdf_worlds_before_pybullet_sees_them(
        make, tmp_path, cache, monkeypatch, bound, value, problem):
    """A URDF beside a sparse 2 GB STL aborted the node (SIGABRT) when a peer spawned it."""
    from r2d2_sim.sim.sdf import meshes
    from r2d2_sim.sim.simulation import SpawnRequest
    from sdf_files import box, write_stl
    write_stl(tmp_path / 'box.stl', box((0.2, 0.2, 0.2)))  # 12 triangles, 684 bytes
    path = urdf_with_mesh(tmp_path, 'box.stl')
    simulation = make()
    assert simulation.spawn(SpawnRequest('fine', uri=path, position=(1.0, 0.0, 0.5))) == 'fine'
    monkeypatch.setattr(meshes, bound, value)
    with pytest.raises(RefusedError) as refused:
        simulation.spawn(SpawnRequest('big', uri=path, position=(-1.0, 0.0, 0.5)))
    assert refused.value.code == 'UNSUPPORTED_ASSETS' and problem in refused.value.message
    assert 'mesh box.stl' in refused.value.message
    assert 'big' not in simulation.entities.names()


def test_every_use_of_a_urdf_mesh_counts_against_the_triangles_of_a_world(
        make, tmp_path, cache, monkeypatch):
    from r2d2_sim.sim.sdf import loading
    from sdf_files import box, write_stl
    write_stl(tmp_path / 'box.stl', box((0.2, 0.2, 0.2)))
    urdf_with_mesh(tmp_path, 'box.stl', uses=2)
    (tmp_path / 'two.world.yaml').write_text(
        'r2d2_sim_world: 1\nmodels:\n  - {uri: meshy.urdf, name: a, position: [1, 0, 0]}\n'
        '  - {uri: meshy.urdf, name: b, position: [-1, 0, 0]}\n')
    simulation = make(world_paths=[str(tmp_path)])
    monkeypatch.setattr(loading, 'MAX_WORLD_TRIANGLES', 48)  # 2 models x 2 uses x 12
    assert simulation.load_world(str(tmp_path / 'two.world.yaml')).name == 'two'
    monkeypatch.setattr(loading, 'MAX_WORLD_TRIANGLES', 47)
    with pytest.raises(RefusedError, match='^UNSUPPORTED_ASSETS: .*more than 47 triangles in all'):
        simulation.load_world(str(tmp_path / 'two.world.yaml'))
    assert simulation.worlds.current.name == 'two'


def test_an_sdf_model_spawns_only_from_where_load_world_may_read_it(make, tmp_path, cache,
                                                                    monkeypatch):
    """By path, file://, a relative path or a link: outside the places it is NOT_FOUND."""
    from r2d2_sim.sim.simulation import SpawnRequest
    from sdf_files import box_model
    outside, allowed = tmp_path / 'outside', tmp_path / 'worlds'
    outside.mkdir()
    allowed.mkdir()
    (outside / 'crate.sdf').write_text(sdf(box_model('crate')))
    (allowed / 'crate.sdf').write_text(sdf(box_model('crate')))
    (allowed / 'link.sdf').symlink_to(outside / 'crate.sdf')
    simulation = make(world_paths=[str(allowed)])
    monkeypatch.chdir(outside)
    for uri in (str(outside / 'crate.sdf'), f'file://{outside}/crate.sdf', 'crate.sdf',
                str(allowed / 'link.sdf')):
        with pytest.raises(RefusedError) as refused:
            simulation.spawn(SpawnRequest('crate', uri=uri, position=(1.0, 0.0, 0.5)))
        assert refused.value.code == 'NOT_FOUND', (uri, refused.value)
        assert 'lies outside the places' in refused.value.message, uri
    assert simulation.spawn(SpawnRequest('crate', uri=str(allowed / 'crate.sdf'),
                                         position=(1.0, 0.0, 0.5))) == 'crate'
    beside = make(model_paths=[str(outside)])  # or among the model paths
    assert beside.spawn(SpawnRequest('crate', uri=str(outside / 'crate.sdf'),
                                     position=(1.0, 0.0, 0.5))) == 'crate'
    as_uri = make(model_paths=[f'file://{outside}'])  # given as the URI its reader takes
    assert as_uri.spawn(SpawnRequest('crate', uri=str(outside / 'crate.sdf'),
                                     position=(1.0, 0.0, 0.5))) == 'crate'


def meshes_of_every_format(directory, count):
    """
    Write ``count`` boxes of 12 triangles, each its own size (each one converted), as files.

    Binary STL, ASCII STL, OBJ and COLLADA in turn; return their file names.
    """
    from trimesh.exchange.stl import export_stl_ascii
    from sdf_files import box, write_dae, write_obj, write_stl
    names = []
    for index in range(count):
        shape = box((0.2 + 0.01 * index, 0.2, 0.2))
        kind = index % 4
        name = f'part{index}.' + ('stl', 'stl', 'obj', 'dae')[kind]
        if kind == 0:
            write_stl(directory / name, shape)
        elif kind == 1:
            (directory / name).write_text(export_stl_ascii(shape))
        elif kind == 2:
            write_obj(directory / name, shape)
        else:
            write_dae(directory / name, shape)
        names.append(name)
    return names


@pytest.fixture
def conversions(monkeypatch):
    """Return the list of meshes converted (read and parsed; a cached one is not) from now on."""
    from r2d2_sim.sim.sdf import mesh_cache
    converted = []
    real = mesh_cache.read_mesh

    def counted(path, shown, data=None):
        converted.append(shown)
        return real(path, shown, data)
    monkeypatch.setattr(mesh_cache, 'read_mesh', counted)
    return converted


def test_a_world_over_its_triangle_budget_is_refused_before_a_mesh_is_converted(
        make, tmp_path, cache, monkeypatch, conversions):
    """An over-budget world was refused only once its meshes had converted (20 s of work)."""
    from r2d2_sim.sim.sdf import loading
    from sdf_files import mesh_model
    names = meshes_of_every_format(tmp_path, 8)  # 8 models, mesh as collision and visual
    world = tmp_path / 'parts.sdf'
    world.write_text(sdf('<world name="parts">' + ''.join(
        mesh_model(f'm{i}', name, pose=f'{i} 0 0 0 0 0') for i, name in enumerate(names)) +
        '</world>'))
    simulation = make(world_paths=[str(tmp_path)])
    monkeypatch.setattr(loading, 'MAX_WORLD_TRIANGLES', 8 * 2 * 12 - 1)
    with pytest.raises(RefusedError, match='^UNSUPPORTED_ASSETS: .*more than 191 triangles in '
                                           'all'):
        simulation.load_world(str(world))
    assert conversions == []  # the files' own counts: no mesh parsed
    assert simulation.worlds.current.name == 'empty'
    monkeypatch.setattr(loading, 'MAX_WORLD_TRIANGLES', 8 * 2 * 12)  # each format counted exactly
    assert simulation.load_world(str(world)).name == 'parts'
    assert len(conversions) == 8


def test_a_manifest_over_its_triangle_budget_is_refused_before_a_mesh_is_converted(
        make, tmp_path, cache, monkeypatch, conversions):
    """URDF and SDF models of one manifest together, before the first model's meshes."""
    from r2d2_sim.sim.sdf import loading
    from sdf_files import mesh_model
    names = meshes_of_every_format(tmp_path, 6)
    entries = []
    for index, name in enumerate(names[:4]):  # four URDFs, each its mesh twice
        urdf_with_mesh(tmp_path, name, uses=2, name=f'urdf{index}')
        entries.append(f'  - {{uri: urdf{index}.urdf, position: [{index}, 0, 0]}}\n')
    for index, name in enumerate(names[4:]):  # two SDF models, collision and visual
        (tmp_path / f'sdf{index}.sdf').write_text(sdf(mesh_model(f'sdf{index}', name)))
        entries.append(f'  - {{uri: sdf{index}.sdf, position: [{index}, 2, 0]}}\n')
    (tmp_path / 'parts.world.yaml').write_text('r2d2_sim_world: 1\nmodels:\n' + ''.join(entries))
    simulation = make(world_paths=[str(tmp_path)])
    monkeypatch.setattr(loading, 'MAX_WORLD_TRIANGLES', 6 * 2 * 12 - 1)
    with pytest.raises(RefusedError, match='^UNSUPPORTED_ASSETS: .*more than 143 triangles in '
                                           'all'):
        simulation.load_world(str(tmp_path / 'parts.world.yaml'))
    assert conversions == []
    monkeypatch.setattr(loading, 'MAX_WORLD_TRIANGLES', 6 * 2 * 12)
    assert simulation.load_world(str(tmp_path / 'parts.world.yaml')).name == 'parts'
    assert len(conversions) == 6


def test_a_urdf_over_its_triangle_budget_is_refused_before_a_mesh_is_converted(
        make, tmp_path, cache, monkeypatch, conversions):
    from r2d2_sim.sim.sdf import loading
    from r2d2_sim.sim.simulation import SpawnRequest
    names = meshes_of_every_format(tmp_path, 4)
    visuals = ''.join(f'<visual><geometry><mesh filename="{n}"/></geometry></visual>'
                      for n in names)
    (tmp_path / 'parts.urdf').write_text(f'<robot name="parts"><link name="base">{visuals}'
                                         '</link></robot>')
    simulation = make()
    monkeypatch.setattr(loading, 'MAX_WORLD_TRIANGLES', 4 * 12 - 1)
    with pytest.raises(RefusedError, match='^UNSUPPORTED_ASSETS: .*more than 47 triangles in '
                                           'all'):
        simulation.spawn(SpawnRequest('parts', uri=str(tmp_path / 'parts.urdf')))
    assert conversions == []
