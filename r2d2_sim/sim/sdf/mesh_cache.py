"""
Meshes converted once into the OBJ files PyBullet loads, kept on disk by their content.

No ROS, no PyBullet. PyBullet reads OBJ most completely (a concave triangle
mesh for a static collision, one convex hull per object for a moving one), and
COLLADA's units and scene transforms only partly, so every mesh is converted
(:mod:`.meshes`) into OBJ files in metres: the whole mesh (``mesh.obj``,
vertices merged; in a large mesh, each flat face's triangles merged too:
:mod:`.planes`), one file per colour for the camera (``part_<i>.obj``), and,
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
import io
import json
import os
import re
import tempfile
from typing import Any, List, Mapping, NamedTuple, Optional, Tuple

import numpy

from r2d2_sim.errors import RefusedError
from r2d2_sim.files import check_private, make_private_directories, read_regular, UnsafeFile
from r2d2_sim.sim.sdf.components import lowest_labels
from r2d2_sim.sim.sdf.meshes import (
    check_triangles, obj_materials, read_mesh, read_mesh_bytes, Triangles)
from r2d2_sim.sim.sdf.planes import merge_coplanar

__all__ = ['MeshCache', 'Converted', 'cache_directory', 'CACHE_VARIABLE', 'CONVERTER_VERSION',
           'MAX_PARTS', 'MAX_HULLS', 'HULL_POINTS', 'MERGE_PLANES_FROM', 'hull_points',
           'unique_rows', 'pieces']

CACHE_VARIABLE = 'R2D2_SIM_CACHE_DIR'
CONVERTER_VERSION = 3
# A mesh of this many triangles or more has its flat faces' triangles merged
# (planes.merge_coplanar): the same surface, loaded and collided with in a
# fraction of the time (the warehouse walls of bench/sdf_world.py: 73,728 -> 72).
MERGE_PLANES_FROM = 4096
# Visual pieces of one mesh (one per colour); beyond, the rest are drawn in one piece.
MAX_PARTS = 32
# Convex pieces of a moving mesh; a mesh of more (or larger) pieces is one convex hull.
MAX_HULLS = 64
MAX_HULL_TRIANGLES = 200_000
# Points a moving piece's convex hull is made of, at most (Bullet advises fewer
# than 100 for speed; 256 keep a sphere round to 0.4 % of its radius).
HULL_POINTS = 256
# Lines of OBJ text formatted at once (a few milliseconds; see _lines).
LINES_A_BLOCK = 5_000
# An entry's info.json, and a converted mesh.obj read back (1,000,000 triangles: ~90 MB).
MAX_INFO_BYTES = 1 << 20
MAX_OBJ_BYTES = 256 << 20
_PART = re.compile(r'part_[0-9]{1,3}\.obj')

Rgba = Tuple[float, float, float, float]


def cache_directory(environ: Optional[Mapping[str, str]] = None) -> str:
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


def _lines(line: str, values: numpy.ndarray) -> List[str]:
    """
    Return ``values`` (one row a line) formatted with ``line``, in blocks of LINES_A_BLOCK.

    One format string for a block's lines: 4 times as fast as numpy.savetxt,
    the same text. In blocks, because one ``%`` of a whole mesh holds the
    interpreter lock for as long as it runs (0.15 s for 600,000 lines):
    between blocks the physics and the services run.
    """
    return [(line * len(block)) % tuple(block.ravel().tolist())
            for block in (values[start:start + LINES_A_BLOCK]
                          for start in range(0, len(values), LINES_A_BLOCK))]


def obj_text(vertices: numpy.ndarray, faces: numpy.ndarray,
             objects: Optional[List[numpy.ndarray]] = None) -> str:
    """Return OBJ text of vertices and faces; ``objects`` splits the faces into named objects."""
    out = ['# written by r2d2_sim\n'] + _lines('v %.9g %.9g %.9g\n', vertices)
    for number, selected in enumerate(objects if objects is not None else [None]):
        chosen = faces if selected is None else faces[selected]
        if objects is not None:
            out.append(f'o piece_{number}\n')
        out += _lines('f %d %d %d\n', chosen + 1)
    return ''.join(out)


def merged(vertices: numpy.ndarray, faces: numpy.ndarray
           ) -> Tuple[numpy.ndarray, numpy.ndarray, numpy.ndarray]:
    """Return vertices with repeats merged, faces on them, and which faces were kept."""
    unique, inverse = unique_rows(vertices)
    faces = inverse[faces]
    kept = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & \
        (faces[:, 0] != faces[:, 2])
    return unique, faces[kept], kept


def unique_rows(rows: numpy.ndarray) -> Tuple[numpy.ndarray, numpy.ndarray]:
    """
    Return ``numpy.unique(rows, axis=0, return_inverse=True)``, the inverse flat.

    The same rows in the same order (sorted by x, then y, then z), found
    with the interpreter lock released: numpy sorts rows as records through a
    comparison that holds it (2 s for the 1.8 million corners of a 600,000
    triangle STL, with the physics and every service waiting), where a
    stable sort of the columns (``lexsort``) lets them run, and takes a
    third of the time. Rows equal in value but not in bits (0.0 and -0.0)
    go to numpy.unique itself: which of them it keeps follows from its own
    sort, which only it gives.
    """
    if not len(rows) or numpy.any((rows == 0.0) & numpy.signbit(rows)):
        unique, inverse = numpy.unique(rows, axis=0, return_inverse=True)
        return unique, inverse.reshape(-1)
    order = numpy.lexsort(rows.T[::-1])
    ordered = rows[order]
    first = numpy.empty(len(rows), dtype=bool)
    first[0] = True
    numpy.any(ordered[1:] != ordered[:-1], axis=1, out=first[1:])
    inverse = numpy.empty(len(rows), dtype=numpy.intp)
    inverse[order] = numpy.cumsum(first) - 1
    return ordered[first], inverse


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
    if not len(faces):
        return []
    parent = lowest_labels(vertex_count, numpy.concatenate([faces[:, 0], faces[:, 0]]),
                           numpy.concatenate([faces[:, 1], faces[:, 2]]))
    labels = parent[faces[:, 0]]
    order = numpy.argsort(labels, kind='stable')
    starts = numpy.flatnonzero(numpy.diff(labels[order])) + 1
    found = numpy.split(order, starts)
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
        extension = os.path.splitext(path)[1].lower()
        # An OBJ's colours come from its .mtl: its digest is in the key (a fixed 32
        # bytes), so the colours never depend on what the cache converted before.
        materials = hashlib.sha256(obj_materials(data, os.path.dirname(path))).digest() \
            if extension == '.obj' else b''
        key = hashlib.sha256(b'r2d2_sim mesh %d %s\0' % (CONVERTER_VERSION, extension.encode())
                             + materials + data).hexdigest()
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
        if len(faces) >= MERGE_PLANES_FROM:
            faces, groups = merge_coplanar(vertices, faces, groups)
            vertices, faces = _used(vertices, faces)
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
    """
    Read back an OBJ this module wrote (``v x y z`` and ``f a b c`` lines only).

    A line at a time, then the numbers in blocks of LINES_A_BLOCK lines: no
    call holds the interpreter lock for the whole file (splitting 25 MB of
    lines at once held it 0.1 s), and numpy parses the numbers.
    """
    vertices, faces = [], []
    for line in io.BytesIO(read_regular(path, MAX_OBJ_BYTES)):
        if line.startswith(b'v '):
            vertices.append(line)
        elif line.startswith(b'f '):
            faces.append(line)
    return _numbers(vertices, float), _numbers(faces, numpy.int64) - 1


def _numbers(lines: List[bytes], dtype: Any) -> numpy.ndarray:
    """Return the three numbers after the letter of each line, as an N x 3 array."""
    blocks = [numpy.array(b' '.join(lines[start:start + LINES_A_BLOCK]).split())
              .reshape(-1, 4)[:, 1:].astype(dtype)
              for start in range(0, len(lines), LINES_A_BLOCK)]
    return numpy.concatenate(blocks) if blocks else numpy.zeros((0, 3), dtype=dtype)
