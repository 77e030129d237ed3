"""
Meshes converted once into the OBJ files PyBullet loads, kept on disk by their content.

No ROS, no PyBullet. PyBullet reads OBJ most completely (a concave triangle
mesh for a static collision, one convex hull per object for a moving one), and
COLLADA's units and scene transforms only partly, so every mesh is converted
(:mod:`.meshes`) into OBJ files in metres: the whole mesh (``mesh.obj``,
vertices merged), one file per colour for the camera (``part_<i>.obj``), and,
when a moving body needs it, its connected pieces as separate objects
(``hulls.obj``: Bullet makes each a convex hull, a decomposition that keeps
a table's legs apart; a piece of more than :data:`HULL_POINTS` vertices is
given by its farthest points in that many fixed directions, since Bullet's
time to load a hull, and to collide with it, grows with its points: a sphere
of 10,242 vertices took PyBullet 0.8 s to load, under the simulator's lock).
They live in ``$R2D2_SIM_CACHE_DIR``, else
``$XDG_CACHE_HOME/r2d2_sim``, else ``~/.cache/r2d2_sim``, under ``meshes/``,
keyed by a hash of the source file's bytes and this converter's version: a
warm load reads no mesh file at all. Every file is written beside its final
name and renamed into place, ``info.json`` last, so two processes converting
the same mesh at once both end with whole files. What is cached becomes what
PyBullet loads, so the cache is held private, as the domain leases' lock
directory is (:mod:`r2d2_sim.files`): an entry another user could have
written is never used.
"""

import hashlib
import json
import os
import re
import tempfile
from typing import Any, List, NamedTuple, Optional, Tuple

import numpy

from r2d2_sim.errors import RefusedError
from r2d2_sim.files import check_private, make_private_directories, read_regular, UnsafeFile
from r2d2_sim.sim.sdf.meshes import check_triangles, read_mesh, read_mesh_bytes, Triangles

__all__ = ['MeshCache', 'Converted', 'cache_directory', 'CACHE_VARIABLE', 'CONVERTER_VERSION',
           'MAX_PARTS', 'MAX_HULLS', 'HULL_POINTS', 'hull_points']

CACHE_VARIABLE = 'R2D2_SIM_CACHE_DIR'
CONVERTER_VERSION = 2
# Visual pieces of one mesh (one per colour); beyond, the rest are drawn in one piece.
MAX_PARTS = 32
# Convex pieces of a moving mesh; a mesh of more (or larger) pieces is one convex hull.
MAX_HULLS = 64
MAX_HULL_TRIANGLES = 200_000
# Points a moving piece's convex hull is made of, at most (Bullet advises fewer
# than 100 for speed; 256 keep a sphere round to 0.4 % of its radius).
HULL_POINTS = 256
# An entry's info.json, and a converted mesh.obj read back (1,000,000 triangles: ~90 MB).
MAX_INFO_BYTES = 1 << 20
MAX_OBJ_BYTES = 256 << 20
_PART = re.compile(r'part_[0-9]{1,3}\.obj')

Rgba = Tuple[float, float, float, float]


def cache_directory(environ=None) -> str:
    """Return r2d2_sim's cache directory: R2D2_SIM_CACHE_DIR, else XDG's, else ~/.cache."""
    environ = os.environ if environ is None else environ
    if environ.get(CACHE_VARIABLE):
        return os.path.abspath(os.path.expanduser(environ[CACHE_VARIABLE]))
    base = environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return os.path.join(os.path.abspath(base), 'r2d2_sim')


class Converted(NamedTuple):
    """A converted mesh: its files, triangle count and visual pieces with their colours."""

    directory: str
    mesh: str                                    # the whole mesh (a concave collision)
    triangles: int
    parts: Tuple[Tuple[str, Optional[Rgba]], ...]


def _write(path: str, text: str) -> None:
    """Write ``text`` to ``path`` whole or not at all (a temporary file renamed into place)."""
    handle, temporary = tempfile.mkstemp(dir=os.path.dirname(path), prefix='.writing_')
    try:
        with os.fdopen(handle, 'w', encoding='utf-8') as stream:
            stream.write(text)
        os.replace(temporary, path)
    except BaseException:
        try:
            os.remove(temporary)
        except OSError:
            pass
        raise


def obj_text(vertices: numpy.ndarray, faces: numpy.ndarray,
             objects: Optional[List[numpy.ndarray]] = None) -> str:
    """Return OBJ text of vertices and faces; ``objects`` splits the faces into named objects."""
    # One format string for all the lines: 4 times as fast as numpy.savetxt, the same text.
    out = ['# written by r2d2_sim\n',
           ('v %.9g %.9g %.9g\n' * len(vertices)) % tuple(vertices.ravel().tolist())]
    for number, selected in enumerate(objects if objects is not None else [None]):
        chosen = faces if selected is None else faces[selected]
        if objects is not None:
            out.append(f'o piece_{number}\n')
        out.append(('f %d %d %d\n' * len(chosen)) % tuple((chosen + 1).ravel().tolist()))
    return ''.join(out)


def merged(vertices: numpy.ndarray, faces: numpy.ndarray
           ) -> Tuple[numpy.ndarray, numpy.ndarray, numpy.ndarray]:
    """Return vertices with repeats merged, faces on them, and which faces were kept."""
    unique, inverse = numpy.unique(vertices, axis=0, return_inverse=True)
    faces = inverse.reshape(-1)[faces]
    kept = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & \
        (faces[:, 0] != faces[:, 2])
    return unique, faces[kept], kept


def _used(vertices: numpy.ndarray, faces: numpy.ndarray
          ) -> Tuple[numpy.ndarray, numpy.ndarray]:
    """Return only the vertices ``faces`` use, and the faces renumbered onto them."""
    used, inverse = numpy.unique(faces, return_inverse=True)
    return vertices[used], inverse.reshape(faces.shape)


def _directions(count: int) -> numpy.ndarray:
    """Return ``count`` unit vectors spread evenly over the sphere (a Fibonacci lattice)."""
    i = numpy.arange(count, dtype=float) + 0.5
    z = 1.0 - 2.0 * i / count
    radius = numpy.sqrt(1.0 - z * z)
    angle = numpy.pi * (3.0 - numpy.sqrt(5.0)) * i
    return numpy.stack([radius * numpy.cos(angle), radius * numpy.sin(angle), z], axis=1)


def hull_points(points: numpy.ndarray, count: int = HULL_POINTS) -> numpy.ndarray:
    """
    Return ``points`` as they are when at most ``count``, else their extremes in ``count`` ways.

    Each chosen point is the farthest along one fixed direction, so it is a
    vertex of the true convex hull: the hull of the chosen points lies inside
    it and touches it in every direction. Deterministic, in the points' order.
    """
    if len(points) <= count:
        return points
    chosen = numpy.unique(numpy.argmax(points @ _directions(count).T, axis=0))
    return points[chosen]


def hull_text(vertices: numpy.ndarray, faces: numpy.ndarray,
              objects: Optional[List[numpy.ndarray]] = None) -> str:
    """Return OBJ text of each object's hull points (fans of triangles Bullet hulls)."""
    out = ['# written by r2d2_sim\n']
    offset = 1
    for number, selected in enumerate(objects if objects is not None else [None]):
        points = hull_points(_used(vertices, faces if selected is None else faces[selected])[0])
        if objects is not None:
            out.append(f'o piece_{number}\n')
        out.append(('v %.9g %.9g %.9g\n' * len(points)) % tuple(points.ravel().tolist()))
        fan = [(offset, offset + k, offset + k + 1) for k in range(1, len(points) - 1)]
        out.append(''.join('f %d %d %d\n' % corners for corners in fan))
        offset += len(points)
    return ''.join(out)


def pieces(faces: numpy.ndarray, vertex_count: int) -> List[numpy.ndarray]:
    """Return the faces of each connected piece (sharing vertices), largest first."""
    parent = list(range(vertex_count))

    def root(v: int) -> int:
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


class MeshCache:
    """
    Meshes converted into OBJ files under ``directory`` (default: :func:`cache_directory`).

    Its files become what PyBullet loads, so the cache is private: every
    directory down to an entry must be a real directory of ours that nobody
    else may write (made 0700; one of ours a looser umask made is tightened),
    else the conversion is refused in one line (OPERATION_FAILED); an entry
    is used only when its files are plain files of ours that nobody else may
    write and its ``info.json`` names only files of the entry, else it is
    converted again over them.
    """

    def __init__(self, directory: Optional[str] = None) -> None:
        self.root = directory or cache_directory()
        self.directory = os.path.join(self.root, 'meshes')

    def convert(self, path: str, shown: str) -> Converted:
        """
        Return ``path``'s mesh converted (from the cache when its content was converted before).

        RefusedError (naming ``shown``) for a mesh that cannot be read or is too
        big; OPERATION_FAILED when the cache is not a private directory.
        """
        data = read_mesh_bytes(path, shown)
        key = hashlib.sha256(b'r2d2_sim mesh %d %s\0' % (
            CONVERTER_VERSION, os.path.splitext(path)[1].lower().encode()) + data).hexdigest()
        directory = self._private(key[:2], key)
        cached = self._cached(directory)
        if cached is not None:
            check_triangles(cached.triangles, shown)  # the bound of today, not the writer's
            return cached
        return self._store(directory, read_mesh(path, shown, data), shown)

    def _private(self, *names: str) -> str:
        """Return ``meshes/names...`` in the cache, every level a private directory."""
        try:
            return make_private_directories(self.root, 'meshes', *names, tighten=True)
        except UnsafeFile as exc:
            raise RefusedError('OPERATION_FAILED', f'the mesh cache: {exc.strerror}: remove it '
                                                   f'or set {CACHE_VARIABLE} to a directory of '
                                                   'your own') from None

    @staticmethod
    def _cached(directory: str) -> Optional[Converted]:
        """Return the entry in ``directory`` if it is whole and only we could have written it."""
        try:
            check_private(os.path.join(directory, 'info.json'), directory=False)
            info = json.loads(read_regular(os.path.join(directory, 'info.json'), MAX_INFO_BYTES))
            names = [name for name, _ in info['parts']]
            if not all(isinstance(n, str) and _PART.fullmatch(n) for n in names):
                return None  # another's entry: parts elsewhere would have PyBullet load them
            parts = tuple((os.path.join(directory, name), None if colour is None
                           else _colour(colour)) for name, colour in info['parts'])
            mesh = os.path.join(directory, 'mesh.obj')
            for file in [mesh] + [p for p, _ in parts]:
                check_private(file, directory=False)
            triangles = info['triangles']
            if isinstance(triangles, int) and triangles > 0:
                return Converted(directory, mesh, triangles, parts)
        except (OSError, ValueError, KeyError, TypeError):
            pass
        return None

    @staticmethod
    def _store(directory: str, triangles: Triangles, shown: str) -> Converted:
        vertices, faces, kept = merged(triangles.vertices, triangles.faces)
        if not len(faces):  # Bullet's triangle mesh of no triangle is not a shape
            raise RefusedError('RESOURCE_PARSE_ERROR', f'mesh {shown} has no triangle of '
                                                       'three distinct corners')
        groups = triangles.groups[kept]
        mesh = os.path.join(directory, 'mesh.obj')
        _write(mesh, obj_text(vertices, faces))
        colours = list(triangles.colours)
        if len(colours) > MAX_PARTS:  # the rest drawn in the last piece's colour
            groups = numpy.minimum(groups, MAX_PARTS - 1)
            colours = colours[:MAX_PARTS]
        parts = []
        for index, colour in enumerate(colours):
            chosen = faces[groups == index]
            if not len(chosen):
                continue
            name = f'part_{index}.obj'
            _write(os.path.join(directory, name), obj_text(*_used(vertices, chosen)))
            parts.append((name, colour))
        _write(os.path.join(directory, 'info.json'), json.dumps(
            {'version': CONVERTER_VERSION, 'triangles': int(len(faces)), 'parts': parts}))
        return Converted(directory, mesh, int(len(faces)),
                         tuple((os.path.join(directory, n), c) for n, c in parts))

    @staticmethod
    def hulls(converted: Converted) -> str:
        """
        Return an OBJ of the mesh's connected pieces, each an object Bullet makes a hull of.

        A mesh of more than MAX_HULLS pieces, or too big to split quickly,
        is one piece (one convex hull). Written beside the mesh once.
        """
        path = os.path.join(converted.directory, 'hulls.obj')
        try:
            check_private(path, directory=False)
            return path
        except UnsafeFile:
            pass  # not written yet (or not by us): written now, over it
        vertices, faces = _read_obj(converted.mesh)
        found = None
        if len(faces) <= MAX_HULL_TRIANGLES:
            found = pieces(faces, len(vertices))
            if len(found) > MAX_HULLS:
                found = None
        if all(len(_used(vertices, faces if piece is None else faces[piece])[0]) <= HULL_POINTS
               for piece in (found if found is not None else [None])):
            _write(path, obj_text(vertices, faces, found))  # every piece as it is
        else:
            _write(path, hull_text(vertices, faces, found))
        return path


def _colour(colour: Any) -> Rgba:
    """Return an info.json colour as four numbers in [0, 1]; ValueError if it is not one."""
    r, g, b, a = (float(c) for c in colour)  # ValueError unless exactly four
    if not all(0.0 <= c <= 1.0 for c in (r, g, b, a)):
        raise ValueError('not a colour')
    return r, g, b, a


def _read_obj(path: str) -> Tuple[numpy.ndarray, numpy.ndarray]:
    """Read back an OBJ this module wrote (``v`` and ``f a b c`` lines only)."""
    vertices, faces = [], []
    for line in read_regular(path, MAX_OBJ_BYTES).decode('utf-8').splitlines():
        if line.startswith('v '):
            vertices.append([float(v) for v in line.split()[1:4]])
        elif line.startswith('f '):
            faces.append([int(v) - 1 for v in line.split()[1:4]])
    return (numpy.array(vertices, dtype=float).reshape(-1, 3),
            numpy.array(faces, dtype=numpy.int64).reshape(-1, 3))
