"""
A large mesh's flat faces are merged into a few triangles: the same surface, a fraction to load.

``planes.merge_coplanar`` re-triangulates each connected set of coplanar
triangles of one colour from its outline's corners. The tests hold it to the
surface it was given: the same area and volume, every ray hitting the same
point in PyBullet's concave mesh of it, curved meshes and faces with holes
left as they were, colours kept apart; and the mesh cache applies it to a
large mesh only.
"""

import numpy
import pybullet
import pytest
import trimesh

from r2d2_sim.sim.sdf.mesh_cache import merged, MERGE_PLANES_FROM, MeshCache
from r2d2_sim.sim.sdf.planes import merge_coplanar
from sdf_files import write_obj


def tessellated(mesh, times):
    """Return a trimesh's vertices (merged) and faces, each triangle split in four ``times``."""
    vertices, faces = numpy.asarray(mesh.vertices), numpy.asarray(mesh.faces)
    for _ in range(times):
        vertices, faces = trimesh.remesh.subdivide(vertices, faces)
    vertices, faces, _ = merged(numpy.asarray(vertices), numpy.asarray(faces))
    return vertices, faces


def walls():
    """Return an L of two boxes that overlap, as exported walls are: not one solid."""
    first = trimesh.creation.box((4.0, 0.2, 1.5))
    second = trimesh.creation.box((0.2, 3.0, 1.5))
    second.apply_translation((1.9, 1.4, 0.0))
    return trimesh.util.concatenate([first, second])


def ray_hits(vertices, faces):
    """Cast a fan of rays at a concave PyBullet mesh of the triangles; return hit points."""
    client = pybullet.connect(pybullet.DIRECT)
    try:
        shape = pybullet.createCollisionShape(
            pybullet.GEOM_MESH, vertices=vertices.tolist(), indices=faces.reshape(-1).tolist(),
            flags=pybullet.GEOM_FORCE_CONCAVE_TRIMESH, physicsClientId=client)
        pybullet.createMultiBody(0.0, shape, physicsClientId=client)
        angles = numpy.linspace(-numpy.pi, numpy.pi, 181)
        heights = numpy.linspace(-0.7, 0.7, 5)
        starts = [(0.5, 0.5, z) for z in heights for _ in angles]
        ends = [(0.5 + 9 * numpy.cos(a), 0.5 + 9 * numpy.sin(a), z) for z in heights
                for a in angles]
        results = pybullet.rayTestBatch(starts, ends, physicsClientId=client)
        return numpy.array([r[3] if r[0] >= 0 else (numpy.nan,) * 3 for r in results])
    finally:
        pybullet.disconnect(client)


def test_tessellated_walls_come_back_as_their_corners_and_the_same_surface():
    vertices, faces = tessellated(walls(), 4)
    groups = numpy.zeros(len(faces), dtype=int)
    new_faces, new_groups = merge_coplanar(vertices, faces, groups)
    assert len(faces) == 24 * 256 and len(new_faces) < 60  # two boxes: 12 faces each
    assert len(new_groups) == len(new_faces)
    before = trimesh.Trimesh(vertices, faces, process=False)
    after = trimesh.Trimesh(vertices, new_faces, process=False)
    assert after.area == pytest.approx(before.area, rel=1e-12)
    assert after.volume == pytest.approx(before.volume, rel=1e-12)
    assert after.is_winding_consistent  # every new triangle faces out as the old ones
    hits_before, hits_after = ray_hits(vertices, faces), ray_hits(vertices, new_faces)
    hit = ~numpy.isnan(hits_before[:, 0])
    assert hit.sum() > 300  # the rays towards the L's two walls
    assert numpy.array_equal(~numpy.isnan(hits_after[:, 0]), hit)
    assert numpy.allclose(hits_after[hit], hits_before[hit], atol=1e-6)


def test_curved_meshes_and_faces_with_holes_are_kept_as_they_are():
    sphere = trimesh.creation.icosphere(3)
    faces, _ = merge_coplanar(sphere.vertices, sphere.faces, numpy.zeros(len(sphere.faces)))
    assert numpy.array_equal(faces, sphere.faces)
    # A flat square ring: one facet whose outline is two loops.
    vertices, faces = tessellated(ring_plate(), 2)
    new_faces, _ = merge_coplanar(vertices, faces, numpy.zeros(len(faces), dtype=int))
    assert numpy.array_equal(new_faces, faces)


def ring_plate():
    """Return a flat square ring (a hole in the middle) of one layer of triangles."""
    outer = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    inner = [(-0.25, -0.25), (0.25, -0.25), (0.25, 0.25), (-0.25, 0.25)]
    vertices = [(x, y, 0.0) for x, y in outer + inner]
    faces = []
    for i in range(4):
        j = (i + 1) % 4
        faces += [(i, j, 4 + j), (i, 4 + j, 4 + i)]
    return trimesh.Trimesh(vertices, faces, process=False)


def test_each_colour_is_merged_on_its_own():
    vertices, faces = tessellated(trimesh.creation.box((1.0, 1.0, 1.0)), 3)
    groups = (vertices[faces].mean(axis=1)[:, 0] > 0).astype(int)  # two colours per face
    new_faces, new_groups = merge_coplanar(vertices, faces, groups)
    assert len(new_faces) < len(faces) // 10
    for colour in (0, 1):
        before = trimesh.Trimesh(vertices, faces[groups == colour], process=False)
        after = trimesh.Trimesh(vertices, new_faces[new_groups == colour], process=False)
        assert after.area == pytest.approx(before.area, rel=1e-12)


def test_the_cache_merges_a_large_mesh_only(tmp_path):
    cache = MeshCache(str(tmp_path / 'cache'))
    big = trimesh.Trimesh(*tessellated(trimesh.creation.box((1.0, 2.0, 3.0)), 5))
    small = trimesh.Trimesh(*tessellated(trimesh.creation.box((1.0, 2.0, 3.0)), 2))
    assert len(big.faces) >= MERGE_PLANES_FROM > len(small.faces)
    for mesh, expected in ((big, 12), (small, len(small.faces))):
        path = write_obj(tmp_path / f'{len(mesh.faces)}.obj', mesh)
        converted = cache.convert(str(path), 'box')
        assert converted.triangles == expected
        loaded = trimesh.load(converted.mesh, process=False)
        assert loaded.area == pytest.approx(mesh.area, rel=1e-9)


def staircase_on_a_ramp(tilt_deg, cells=((0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (0, 2))):
    """Return a flat staircase of half-cells (two triangles each), tilted and far from 0."""
    import math
    index, faces = {}, []

    def corner(point):
        return index.setdefault(point, len(index))
    for cx, cy in cells:
        for i in range(2):
            for j in range(2):
                x, y = 2 * cx + i, 2 * cy + j
                a, b = corner((x, y)), corner((x + 1, y))
                c, d = corner((x + 1, y + 1)), corner((x, y + 1))
                faces += [(a, b, c), (a, c, d)]
    flat = numpy.array(sorted(index, key=index.get), dtype=float) / 2.0
    tilt = math.radians(tilt_deg)
    vertices = numpy.column_stack([flat[:, 0] * math.cos(tilt) + 12.0, flat[:, 1] + 7.0,
                                   flat[:, 0] * math.sin(tilt) + 0.5])
    return vertices, numpy.array(faces)


@pytest.mark.parametrize('tilt_deg', [0.0, 10.0, 30.0])
def test_a_tilted_staircase_comes_back_with_no_sliver_and_none_turned_over(tilt_deg):
    vertices, faces = staircase_on_a_ramp(tilt_deg)
    new_faces, _ = merge_coplanar(vertices, faces, numpy.zeros(len(faces), dtype=int))
    assert len(new_faces) < len(faces)
    normals = numpy.cross(vertices[new_faces[:, 1]] - vertices[new_faces[:, 0]],
                          vertices[new_faces[:, 2]] - vertices[new_faces[:, 0]])
    first = numpy.cross(vertices[faces[0, 1]] - vertices[faces[0, 0]],
                        vertices[faces[0, 2]] - vertices[faces[0, 0]])
    assert (numpy.linalg.norm(normals, axis=1) > 1e-6).all()  # no triangle of no area
    assert (normals @ first > 0).all()  # each faces the way the old ones did
    assert (trimesh.Trimesh(vertices, new_faces, process=False).area
            == pytest.approx(trimesh.Trimesh(vertices, faces, process=False).area, rel=1e-12))


def test_an_outline_of_too_many_corners_is_kept_as_it_was():
    teeth = 80  # a comb: 4 corners a tooth, 320 in all
    cells = [(x, 0) for x in range(2 * teeth)] + [(2 * t, 1) for t in range(teeth)]
    vertices, faces = staircase_on_a_ramp(0.0, cells)
    new_faces, _ = merge_coplanar(vertices, faces, numpy.zeros(len(faces), dtype=int))
    assert numpy.array_equal(new_faces, faces)
