"""
Meshes from SDF: DAE, STL and OBJ read in metres, bounded, converted once and kept by content.

No ROS, no physics. The tests write meshes with mesh libraries (pycollada
with a unit and a node transform, trimesh's STL and OBJ writers) and check
what comes back against the shapes they wrote, then the cache: where it is,
that a warm read converts nothing, and that two processes converting at
once both end with whole files.
"""

import io
import json
import os
import subprocess
import sys
import zipfile

import numpy
import pytest

from common import REPO
from r2d2_sim.errors import RefusedError
from r2d2_sim.sim.sdf import mesh_cache, meshes
from r2d2_sim.sim.sdf.mesh_cache import cache_directory, MeshCache
from r2d2_sim.sim.sdf.meshes import read_mesh
from sdf_files import box, write_dae, write_obj, write_stl

SECRET = b'do-not-echo-7f3a'


def bounds(triangles):
    return [triangles.vertices.min(axis=0).tolist(), triangles.vertices.max(axis=0).tolist()]


def test_a_collada_mesh_comes_back_in_metres_with_its_unit_and_node_transform(tmp_path):
    """Written in centimetres and shifted by its node: read back, it is the 1 x 2 x 3 m box."""
    path = write_dae(tmp_path / 'box.dae', box((1.0, 2.0, 3.0), (0.5, 1.0, 1.5)),
                     rgba=(0.9, 0.1, 0.2, 1.0), unit_m=0.01, node_offset=(10.0, 0.0, 0.0))
    triangles = read_mesh(path, 'model://x/box.dae')
    assert bounds(triangles) == [pytest.approx([0.0, 0.0, 0.0], abs=1e-9),
                                 pytest.approx([1.0, 2.0, 3.0], abs=1e-9)]
    assert len(triangles.faces) == 12
    assert triangles.colours == ((0.9, 0.1, 0.2, 1.0),)


def test_stl_and_obj_come_back_as_written_obj_with_its_material_colour(tmp_path):
    shape = box((0.4, 0.6, 0.8))
    stl = read_mesh(write_stl(tmp_path / 'b.stl', shape), 'b.stl')
    obj = read_mesh(write_obj(tmp_path / 'b.obj', shape, rgba=(0.0, 0.5, 1.0, 1.0)), 'b.obj')
    for triangles in (stl, obj):
        assert bounds(triangles) == [pytest.approx([-0.2, -0.3, -0.4], abs=1e-6),
                                     pytest.approx([0.2, 0.3, 0.4], abs=1e-6)]  # STL: float32
        assert len(triangles.faces) == 12
    assert stl.colours == (None,)
    assert obj.colours[0][:3] == pytest.approx((0.0, 0.5, 1.0), abs=0.01)


def test_an_obj_reads_no_material_file_outside_its_own_directory(tmp_path):
    (tmp_path / 'secret.mtl').write_text('newmtl paint\nKd 1 0 0\n')
    inner = tmp_path / 'meshes'
    inner.mkdir()
    path = write_obj(inner / 'b.obj', box((1.0, 1.0, 1.0)))
    text = open(path).read()
    with open(path, 'w') as handle:
        handle.write('mtllib ../secret.mtl\nusemtl paint\n' + text)
    assert read_mesh(path, 'b.obj').colours == (None,)


@pytest.mark.parametrize('name, data, code, problem', [
    ('bomb.dae', b'<?xml version="1.0"?><!DOCTYPE c [<!ENTITY a "' + SECRET + b'">]><COLLADA/>',
     'RESOURCE_PARSE_ERROR', 'declares a DOCTYPE or entities'),
    ('junk.dae', b'<COLLADA>' + SECRET, 'RESOURCE_PARSE_ERROR',
     'is not a COLLADA file r2d2_sim can read'),
    ('junk.stl', b'solid x\nfacet normal ' + SECRET, 'RESOURCE_PARSE_ERROR',
     'is not an STL file r2d2_sim can read'),
    ('shape.ply', b'ply\n' + SECRET, 'UNSUPPORTED_ASSETS', 'r2d2_sim reads DAE, STL and OBJ'),
])
def test_a_bad_mesh_gets_one_line_naming_it_never_its_bytes(tmp_path, name, data, code,
                                                            problem):
    path = tmp_path / name
    path.write_bytes(data)
    with pytest.raises(RefusedError) as raised:
        read_mesh(str(path), f'model://m/{name}')
    assert raised.value.code == code
    assert problem in raised.value.message and f'model://m/{name}' in raised.value.message
    assert SECRET.decode() not in raised.value.message and '\n' not in raised.value.message


def _zipped(name, data):
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, 'w', zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(name, data)
    return buffer.getvalue()


def _bomb(encoding):
    """Return a COLLADA file that is valid but for its DOCTYPE, written in ``encoding``."""
    return (f'<?xml version="1.0" encoding="{encoding}"?><!DOCTYPE c [<!ENTITY a "'
            f'{SECRET.decode()}">]><COLLADA/>').encode(encoding)


@pytest.mark.parametrize('data, problem', [
    (_zipped('m.dae', b'<COLLADA>' + b' ' * 1_000_000 + b'</COLLADA>'), 'a zip archive'),
    (_zipped('m.dae', _bomb('utf-8')), 'a zip archive'),
    (b'<COLLADA/>' + _zipped('m.dae', _bomb('utf-8')), 'a zip archive'),  # read from its end
    (_bomb('utf-16'), 'is not UTF-8'),
    (_bomb('utf-32'), 'is not UTF-8'),
    (_bomb('cp037'), 'is not UTF-8'),
], ids=['zipped', 'zipped DOCTYPE', 'zip after XML', 'UTF-16 DOCTYPE', 'UTF-32 DOCTYPE',
        'EBCDIC DOCTYPE'])
def test_collada_that_pycollada_would_unzip_or_decode_past_the_checks_is_refused(
        tmp_path, data, problem):
    """
    Zipped (pycollada unpacks any data with a zip directory at its end) or not UTF-8.

    Both passed the size bound and the DOCTYPE check unseen: 40 kB of zip became
    ~950 MB, and a DOCTYPE in UTF-16 loaded. Gazebo reads no zipped COLLADA either.
    """
    path = tmp_path / 'm.dae'
    path.write_bytes(data)
    with pytest.raises(RefusedError) as raised:
        read_mesh(str(path), 'model://m/m.dae')
    assert raised.value.code == 'UNSUPPORTED_ASSETS', raised.value
    assert problem in raised.value.message and 'model://m/m.dae' in raised.value.message
    assert SECRET.decode() not in raised.value.message and '\n' not in raised.value.message


def test_a_mesh_of_no_real_triangle_or_of_missing_corners_is_refused(tmp_path):
    import trimesh
    flat = trimesh.Trimesh([[0, 0, 0], [0, 0, 0], [0, 0, 0]], [[0, 1, 2]], process=False)
    path = write_stl(tmp_path / 'point.stl', flat)
    with pytest.raises(RefusedError, match='mesh point.stl has no triangle of three distinct'):
        MeshCache(str(tmp_path / 'cache')).convert(path, 'point.stl')
    text = open(write_dae(tmp_path / 'box.dae', box((1.0, 1.0, 1.0)))).read()
    broken = tmp_path / 'broken.dae'
    start = text.index('<p>') + 3
    broken.write_text(text[:start] + '0 1 99 ' + text[start:].split(' ', 3)[3])
    with pytest.raises(RefusedError) as raised:
        read_mesh(str(broken), 'broken.dae')
    assert raised.value.code == 'RESOURCE_PARSE_ERROR' and 'broken.dae' in raised.value.message


@pytest.mark.parametrize('text, problem', [
    ('v 0 0\nv 1 0\nv 0 1\nv 1 1\nf 1 2 3\n', 'do not read as points and triangles'),
    ('v 0 0 0\nv 1 0\nv 0 1 0 0 0\nf 1 2 3\n', 'a triangle of a vertex it does not have'),
])
def test_an_obj_of_broken_points_is_one_line(tmp_path, text, problem):
    """Cases a run of random mutations found (a traceback each, before)."""
    (tmp_path / 'q.obj').write_text(text)
    with pytest.raises(RefusedError, match=problem) as raised:
        read_mesh(str(tmp_path / 'q.obj'), 'q.obj')
    assert raised.value.code == 'RESOURCE_PARSE_ERROR'


@pytest.mark.parametrize('write', [write_stl, write_obj, write_dae])
def test_a_mesh_over_the_triangle_budget_is_refused(tmp_path, monkeypatch, write):
    extension = {write_stl: 'stl', write_obj: 'obj', write_dae: 'dae'}[write]
    path = write(tmp_path / f'b.{extension}', box((1.0, 1.0, 1.0)))  # 12 triangles
    monkeypatch.setattr(meshes, 'MAX_MESH_TRIANGLES', 11)
    with pytest.raises(RefusedError) as raised:
        read_mesh(path, 'big')
    assert raised.value.code == 'UNSUPPORTED_ASSETS'
    assert 'mesh big has' in raised.value.message and 'more than 11' in raised.value.message
    monkeypatch.setattr(meshes, 'MAX_MESH_TRIANGLES', 12)
    assert len(read_mesh(path, 'big').faces) == 12


@pytest.mark.parametrize('extension, text, count', [
    ('.stl', 'solid s\n' + 'facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n'
     'vertex 0 1 0\nendloop\nendfacet\n' * 3 + 'endsolid s\n', 3),  # ASCII: one a facet
    ('.obj', 'f 1 2 3\nv 0 0 0\nf\t1 2 3\n# f 1 2 3\nf 1 2 3 4\n', 3),  # a quad: 1 at least
    ('.dae', '<COLLADA><triangles material="m" count="12"><p/></triangles><c:polylist '
     'count = \'5\' material="n"><vcount/></c:polylist><polygons count="2"/><lines '
     'count="9"/><triangles/><tristrips count="4"/></COLLADA>', 19),
    ('.ply', 'ply\nelement face 12\n', 0),
], ids=['ascii-stl', 'obj', 'dae', 'other'])
def test_a_mesh_files_declared_triangles_are_read_without_parsing_it(extension, text, count):
    """What a world's triangle budget is checked with before any mesh is converted."""
    assert meshes.declared_triangles(text.encode(), extension) == count


@pytest.mark.parametrize('write', [write_stl, write_obj, write_dae])
def test_the_triangles_a_written_mesh_declares_are_those_it_has(tmp_path, write):
    extension = {write_stl: '.stl', write_obj: '.obj', write_dae: '.dae'}[write]
    path = write(tmp_path / f'b{extension}', box((1.0, 1.0, 1.0)))
    with open(path, 'rb') as handle:
        assert meshes.declared_triangles(handle.read(), extension) == 12


def test_a_mesh_file_over_the_size_bound_is_refused_unread(tmp_path, monkeypatch):
    path = write_stl(tmp_path / 'b.stl', box((1.0, 1.0, 1.0)))
    monkeypatch.setattr(meshes, 'MAX_MESH_BYTES', 100)
    with pytest.raises(RefusedError, match='larger than 100 bytes'):
        MeshCache(str(tmp_path / 'cache')).convert(path, 'b.stl')


def test_the_cache_directory_follows_the_override_then_xdg_then_home():
    assert cache_directory({'R2D2_SIM_CACHE_DIR': '/a', 'XDG_CACHE_HOME': '/b'}) == '/a'
    assert cache_directory({'XDG_CACHE_HOME': '/b'}) == '/b/r2d2_sim'
    assert cache_directory({}) == os.path.join(os.path.expanduser('~'), '.cache', 'r2d2_sim')


def test_a_mesh_is_converted_once_and_found_again_by_its_content(tmp_path, monkeypatch):
    cache = MeshCache(str(tmp_path / 'cache'))
    first = write_dae(tmp_path / 'a.dae', box((1.0, 1.0, 1.0)), rgba=(1.0, 0.0, 0.0, 1.0))
    converted = cache.convert(first, 'a.dae')
    assert converted.triangles == 12
    assert converted.parts == ((os.path.join(converted.directory, 'part_0.obj'),
                                (1.0, 0.0, 0.0, 1.0)),)
    with open(converted.mesh) as handle:
        text = handle.read()
    assert text.count('\nv ') == 8 and text.count('\nf ') == 12  # corners merged
    copy = tmp_path / 'elsewhere.dae'
    copy.write_bytes(open(first, 'rb').read())

    def no_reading(*args):
        raise AssertionError('a warm load read the mesh again')
    monkeypatch.setattr(mesh_cache, 'read_mesh', no_reading)
    assert cache.convert(str(copy), 'elsewhere.dae') == converted
    other = write_dae(tmp_path / 'b.dae', box((2.0, 1.0, 1.0)))
    with pytest.raises(AssertionError, match='read the mesh again'):
        cache.convert(other, 'b.dae')  # other content: converted anew


def test_an_objs_colours_come_from_its_mtl_whatever_the_cache_converted_before(tmp_path):
    """Byte-identical OBJs with other .mtl files, and an edited .mtl, are converted anew."""
    cache = MeshCache(str(tmp_path / 'cache'))

    def colours(name, rgba, within=cache):
        directory = tmp_path / name
        directory.mkdir(exist_ok=True)
        path = write_obj(directory / 'crate.obj', box((1.0, 1.0, 1.0)), rgba=rgba)
        return [colour for _, colour in within.convert(path, name).parts]
    assert colours('red', (1.0, 0.0, 0.0, 1.0)) == [(1.0, 0.0, 0.0, 1.0)]
    assert colours('blue', (0.0, 0.0, 1.0, 1.0)) == [(0.0, 0.0, 1.0, 1.0)]  # was red
    assert colours('red', (0.0, 1.0, 0.0, 1.0)) == [(0.0, 1.0, 0.0, 1.0)]   # edited .mtl
    fresh = MeshCache(str(tmp_path / 'fresh'))
    assert colours('blue', (0.0, 0.0, 1.0, 1.0), fresh) == [(0.0, 0.0, 1.0, 1.0)]  # as cold
    (tmp_path / 'red' / 'crate.mtl').unlink()
    converted = cache.convert(str(tmp_path / 'red' / 'crate.obj'), 'red')
    assert [colour for _, colour in converted.parts] == [None]  # not the cached green


def test_the_moving_collision_of_a_mesh_is_one_hull_per_piece(tmp_path):
    """Two cubes 1 m apart: two convex pieces (one hull would fill the gap between them)."""
    import trimesh
    pair = trimesh.util.concatenate([box((0.2, 0.2, 0.2), (-0.5, 0, 0)),
                                     box((0.2, 0.2, 0.2), (0.5, 0, 0))])
    cache = MeshCache(str(tmp_path / 'cache'))
    converted = cache.convert(write_stl(tmp_path / 'pair.stl', pair), 'pair.stl')
    with open(cache.hulls(converted)) as handle:
        assert handle.read().count('\no piece_') == 2
    many = trimesh.util.concatenate([box((0.1, 0.1, 0.1), (i, 0, 0)) for i in range(70)])
    converted = cache.convert(write_stl(tmp_path / 'many.stl', many), 'many.stl')
    with open(cache.hulls(converted)) as handle:
        assert '\no piece_' not in handle.read()  # more than MAX_HULLS pieces: one hull


def test_a_piece_of_many_points_is_hulled_from_its_extremes():
    """A sphere of 10,242 vertices: at most HULL_POINTS of them, each the farthest one way."""
    import trimesh
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=1.0)
    points = numpy.asarray(sphere.vertices)
    chosen = mesh_cache.hull_points(points)
    assert 100 < len(chosen) <= mesh_cache.HULL_POINTS
    assert {tuple(p) for p in chosen} <= {tuple(p) for p in points}
    # Every direction still reaches (almost) the whole radius: the hull did not shrink.
    directions = numpy.random.default_rng(7).normal(size=(2000, 3))
    directions /= numpy.linalg.norm(directions, axis=1)[:, None]
    assert (chosen @ directions.T).max(axis=0).min() > 0.97
    assert numpy.array_equal(mesh_cache.hull_points(points[:50]), points[:50])  # few: as they are


def test_a_big_moving_mesh_loads_as_a_small_hull_and_a_small_one_as_it_was(tmp_path):
    """hulls.obj keeps a box's points (bytes as before) and cuts a sphere's to HULL_POINTS."""
    import trimesh
    cache = MeshCache(str(tmp_path / 'cache'))
    converted = cache.convert(write_stl(tmp_path / 'cube.stl', box((0.2, 0.2, 0.2))), 'cube.stl')
    vertices, faces = mesh_cache._read_obj(converted.mesh)
    with open(cache.hulls(converted)) as handle:
        assert handle.read() == mesh_cache.obj_text(vertices, faces, [numpy.arange(len(faces))])
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.3)
    converted = cache.convert(write_stl(tmp_path / 'ball.stl', sphere), 'ball.stl')
    with open(cache.hulls(converted)) as handle:
        text = handle.read()
    assert text.count('\nv ') <= mesh_cache.HULL_POINTS and text.count('\nf ') < 300


def pieces_one_face_at_a_time(faces, vertex_count):
    """Return the pieces as the converter found them before (union-find, a loop over faces)."""
    parent = list(range(vertex_count))

    def root(v):
        while parent[v] != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v
    for a, b, c in faces.tolist():
        ra, rb, rc = root(a), root(b), root(c)
        parent[rb] = ra
        parent[root(rc)] = ra
    labels = numpy.array([root(int(f)) for f in faces[:, 0]])
    found = [numpy.flatnonzero(labels == label) for label in numpy.unique(labels)]
    return sorted(found, key=lambda indices: (-len(indices), int(indices[0])))


def test_conversion_steps_that_let_other_threads_run_give_the_same_results():
    """
    Whole-array steps in place of numpy's record sort and Python loops: nothing else changes.

    numpy.unique(axis=0) sorts rows as records, holding the interpreter lock (2 s
    for a 600,000-triangle STL, the node's physics and services waiting: a user saw
    replies delayed 1.6-2.2 s); the pieces were found in a loop over faces.
    """
    rng = numpy.random.default_rng(3)
    for _ in range(30):
        points = rng.normal(size=(int(rng.integers(1, 400)), 3))
        points[rng.random(points.shape) < 0.3] = 0.25
        rows = points[rng.integers(0, len(points), int(rng.integers(1, 2000)))]
        unique, inverse = mesh_cache.unique_rows(rows)
        expected, expected_inverse = numpy.unique(rows, axis=0, return_inverse=True)
        assert unique.tobytes() == expected.tobytes()
        assert numpy.array_equal(inverse, expected_inverse.reshape(-1))
        faces = rng.integers(0, len(rows), size=(int(rng.integers(1, 300)), 3))
        found = mesh_cache.pieces(faces, len(rows))
        assert [p.tolist() for p in found] == \
            [p.tolist() for p in pieces_one_face_at_a_time(faces, len(rows))]
    signed = numpy.array([[0.0, 1.0, 2.0], [-0.0, 1.0, 2.0], [0.0, 1.0, 2.0]])
    unique, inverse = mesh_cache.unique_rows(signed)  # 0.0 and -0.0: as numpy keeps them
    expected, expected_inverse = numpy.unique(signed, axis=0, return_inverse=True)
    assert unique.tobytes() == expected.tobytes() and inverse.tolist() == [0, 0, 0]


def test_merging_a_meshs_corners_sorts_no_records(monkeypatch):
    """Only rows with a -0.0 go to numpy.unique(axis=0), whose sort holds the lock."""
    sorted_as_records = []
    real = numpy.unique

    def spy(values, *args, **kwargs):
        if kwargs.get('axis') is not None:
            sorted_as_records.append(len(values))
        return real(values, *args, **kwargs)
    monkeypatch.setattr(numpy, 'unique', spy)
    shape = box((1.0, 2.0, 3.0), (0.5, 1.0, 1.5))
    corners = numpy.asarray(shape.vertices)[numpy.asarray(shape.faces)].reshape(-1, 3)
    vertices, faces, kept = mesh_cache.merged(corners, numpy.arange(36).reshape(-1, 3))
    assert len(vertices) == 8 and len(faces) == 12 and kept.all()
    assert sorted_as_records == []


def test_obj_text_in_blocks_is_the_text_of_one_format_and_reads_back(tmp_path, monkeypatch):
    monkeypatch.setattr(mesh_cache, 'LINES_A_BLOCK', 7)
    rng = numpy.random.default_rng(5)
    vertices = rng.normal(size=(50, 3))
    faces = rng.integers(0, 50, size=(40, 3))
    text = mesh_cache.obj_text(vertices, faces, [numpy.arange(17), numpy.arange(17, 40)])
    assert text == ('# written by r2d2_sim\n' +
                    ('v %.9g %.9g %.9g\n' * 50) % tuple(vertices.ravel().tolist()) +
                    'o piece_0\n' + ('f %d %d %d\n' * 17) % tuple((faces[:17] + 1).ravel()) +
                    'o piece_1\n' + ('f %d %d %d\n' * 23) % tuple((faces[17:] + 1).ravel()))
    (tmp_path / 'mesh.obj').write_text(text)
    read_vertices, read_faces = mesh_cache._read_obj(str(tmp_path / 'mesh.obj'))
    assert numpy.array_equal(read_faces, faces) and read_faces.dtype == numpy.int64
    assert read_vertices.tolist() == [[float('%.9g' % v) for v in row] for row in vertices]


CONVERT = '''
import sys
sys.path.insert(0, sys.argv[1])
from r2d2_sim.sim.sdf.mesh_cache import MeshCache
cache = MeshCache(sys.argv[2])
for path in sys.argv[3:]:
    cache.convert(path, path)
'''


def test_two_processes_converting_at_once_both_leave_whole_files(tmp_path):
    import trimesh
    paths = []
    for i in range(6):
        sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.5 + i)
        paths.append(write_stl(tmp_path / f's{i}.stl', sphere))
    command = [sys.executable, '-c', CONVERT, REPO, str(tmp_path / 'cache')] + paths
    children = [subprocess.Popen(command, stderr=subprocess.PIPE) for _ in range(2)]
    for child in children:
        _, errors = child.communicate(timeout=120)
        assert child.returncode == 0, errors.decode()[-2000:]
    cache = MeshCache(str(tmp_path / 'cache'))
    for path in paths:
        converted = cache.convert(path, path)
        with open(os.path.join(converted.directory, 'info.json')) as handle:
            assert json.load(handle)['triangles'] == converted.triangles == 5120
        vertices = numpy.loadtxt(converted.mesh, comments=('#', 'f'), usecols=(1, 2, 3))
        assert len(vertices) == 2562
    leftovers = [n for d, _, names in os.walk(tmp_path / 'cache') for n in names
                 if n.startswith('.writing_')]
    assert leftovers == []


def _plant(converted, tmp_path, how):
    """Change a cached entry as another user of the machine could have; return the bait."""
    info_path = os.path.join(converted.directory, 'info.json')
    info = json.load(open(info_path))
    bait = tmp_path / 'bait.obj'
    bait.write_text('v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n')
    if how == 'parts elsewhere':  # PyBullet would load any file named here
        info['parts'] = [[str(bait), None]]
    else:
        info['triangles'] = 3
    with open(info_path, 'w') as handle:
        json.dump(info, handle)
    if how == "another user's file":
        if os.getuid() == 0:
            os.chown(info_path, 65534, 65534)
        else:  # only root can give a file away: one others may write is as untrusted
            os.chmod(info_path, 0o666)
    elif how == 'writable by others':
        os.chmod(info_path, 0o666)
    return str(bait)


@pytest.mark.parametrize('how', ["another user's file", 'writable by others', 'parts elsewhere'])
def test_a_cache_entry_someone_else_could_have_written_is_converted_again(tmp_path, how):
    """A planted entry changed a mesh's triangle count, or had PyBullet load any file."""
    cache = MeshCache(str(tmp_path / 'cache'))
    mesh = write_dae(tmp_path / 'a.dae', box((1.0, 1.0, 1.0)))
    converted = cache.convert(mesh, 'a.dae')
    bait = _plant(converted, tmp_path, how)
    again = cache.convert(mesh, 'a.dae')
    assert again == converted and again.triangles == 12
    assert all(os.path.dirname(path) == converted.directory for path, _ in again.parts)
    assert bait not in open(os.path.join(converted.directory, 'info.json')).read()
    facts = os.lstat(os.path.join(converted.directory, 'info.json'))
    assert facts.st_uid == os.getuid() and facts.st_mode & 0o022 == 0


def test_the_cache_is_private_and_one_others_own_or_reach_through_a_link_is_refused(
        tmp_path, monkeypatch):
    mesh = write_stl(tmp_path / 'b.stl', box((1.0, 1.0, 1.0)))
    root = tmp_path / 'cache'
    converted = MeshCache(str(root)).convert(mesh, 'b.stl')
    for level in (root, root / 'meshes', os.path.dirname(converted.directory),
                  converted.directory):
        assert os.stat(level).st_mode & 0o077 == 0, level  # 0700 each
    os.chmod(root, 0o777)  # ours, made with a loose umask: tightened, not refused
    assert MeshCache(str(root)).convert(mesh, 'b.stl') == converted
    assert os.stat(root).st_mode & 0o077 == 0
    link = tmp_path / 'link'
    link.symlink_to(root)
    with pytest.raises(RefusedError) as refused:
        MeshCache(str(link)).convert(mesh, 'b.stl')
    assert refused.value.code == 'OPERATION_FAILED' and 'symbolic link' in refused.value.message
    real_uid = os.getuid()
    monkeypatch.setattr(os, 'getuid', lambda: real_uid + 1)  # the cache is now another's
    with pytest.raises(RefusedError) as refused:
        MeshCache(str(root)).convert(mesh, 'b.stl')
    assert refused.value.code == 'OPERATION_FAILED'
    assert f'belongs to user id {real_uid}' in refused.value.message
    assert 'R2D2_SIM_CACHE_DIR' in refused.value.message and '\n' not in refused.value.message


def test_sim_nodes_lean_imports_read_meshes_alike_without_importing_scipy(tmp_path):
    """A fresh interpreter: trimesh without scipy, the meshes read alike, scipy still free."""
    stl = write_stl(tmp_path / 'box.stl', box((1.0, 2.0, 3.0)))
    obj = write_obj(tmp_path / 'box.obj', box((1.0, 2.0, 3.0)), rgba=(0.2, 0.4, 0.6, 1.0))
    script = f'''
import importlib.util, json, sys
from r2d2_sim.sim.sdf import meshes
meshes.lean_mesh_imports()
found = [meshes.read_mesh(p, 'x') for p in ({stl!r}, {obj!r})]
facts = {{'trimesh': 'trimesh' in sys.modules,
          'spared': [n for n in meshes.TRIMESH_SPARED if n in sys.modules],
          'triangles': [t.vertices[t.faces].round(9).tolist() for t in found],
          'colours': [list(t.colours) for t in found]}}
for name in meshes.TRIMESH_SPARED:  # refused only while trimesh imported
    if importlib.util.find_spec(name) is not None:
        importlib.import_module(name)
print(json.dumps(facts))
'''
    lean = json.loads(subprocess.run([sys.executable, '-c', script], cwd=REPO, check=True,
                                     capture_output=True, text=True).stdout)
    whole = [read_mesh(str(p), 'x') for p in (stl, obj)]
    assert lean['trimesh'] and lean['spared'] == []
    assert lean['triangles'] == [t.vertices[t.faces].round(9).tolist() for t in whole]
    assert lean['colours'] == [[list(c) if c else None for c in t.colours] for t in whole]
