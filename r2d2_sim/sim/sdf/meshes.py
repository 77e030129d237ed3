"""
Mesh files as triangles in metres, with a colour per triangle where the file gives one.

No ROS, no PyBullet. COLLADA (``.dae``) is read with pycollada, the way
Gazebo reads it: the scene's node transforms applied and its ``<unit meter>``
scale too (``<up_axis>`` ignored, as Gazebo does), each primitive's material
colour kept (a texture counts as no colour). STL and OBJ (with its ``.mtl``
colours, from the OBJ's own directory only) are read with trimesh's parsers.
Every file is bounded before it is parsed: its size, no DOCTYPE or entities
in a COLLADA file (pycollada's XML parser would expand them), and the
triangle count (:data:`MAX_MESH_TRIANGLES`). Errors name the mesh as the SDF
wrote it, never the file's contents.
"""

import errno
import io
import logging
import os
import re
import struct
import sys
import warnings
import zipfile
from typing import Any, List, NamedTuple, Optional, Tuple

import numpy

from r2d2_sim.errors import RefusedError
from r2d2_sim.files import read_regular, UnsafeFile

__all__ = ['Triangles', 'read_mesh', 'read_mesh_bytes', 'obj_materials', 'check_triangles',
           'declared_triangles', 'lean_mesh_imports', 'MESH_FORMATS', 'MAX_MESH_BYTES',
           'MAX_MESH_TRIANGLES', 'TRIMESH_SPARED']

MESH_FORMATS = ('.dae', '.stl', '.obj')
# One mesh file (AWS's small house: 140 DAE files of 87 MB in all, the largest 6 MB).
MAX_MESH_BYTES = 64 << 20
MAX_MESH_TRIANGLES = 1_000_000
MAX_MTL_BYTES = 1 << 20
# A vertex farther out is a broken file (a mesh in millimetres of a 1,000 km thing).
MAX_COORDINATE = 1e9
PARSE, UNSUPPORTED = 'RESOURCE_PARSE_ERROR', 'UNSUPPORTED_ASSETS'
_XML_DECLARATIONS = re.compile(rb'<!\s*(DOCTYPE|ENTITY)', re.IGNORECASE)
# The encoding an XML declaration names, read from its first 1 kB (bounded, linear).
_DECLARED_ENCODING = re.compile(rb'<\?xml[^>]{0,1000}?encoding\s*=\s*["\']([A-Za-z0-9._-]{1,40})')
# Encodings in which markup is ASCII, byte for byte, so the DOCTYPE check reads it as the
# parser does; another (UTF-16, UTF-32, EBCDIC, UTF-7 with lxml) could hide a DOCTYPE.
_ASCII_MARKUP = ('utf-8', 'utf8', 'us-ascii', 'ascii', 'iso-8859-1', 'latin-1', 'latin1')
# The count of each COLLADA primitive read as triangles (bounded, so linear in the file).
_COLLADA_COUNT = re.compile(
    rb'<(?:[A-Za-z_][A-Za-z0-9_.-]{0,40}:)?(?:triangles|polylist|polygons)\s[^<>]{0,200}?'
    rb'(?<=\s)count\s*=\s*["\']\s*([0-9]{1,12})\s*["\']')

# What trimesh imports when it is installed and its STL and OBJ parsers never use.
# Importing scipy held the interpreter for 20 ms at a time (an extension's set-up, on
# a quiet machine): in sim_node, the first LoadWorld with meshes stopped /clock for up
# to 58 ms while trimesh was imported (bench/clock_gaps.py).
TRIMESH_SPARED = ('scipy', 'networkx')
_lean = False

Rgba = Tuple[float, float, float, float]


class Triangles(NamedTuple):
    """A mesh: vertices (N x 3, metres), triangles (M x 3 indices), each triangle's colour."""

    vertices: numpy.ndarray
    faces: numpy.ndarray
    colours: Tuple[Optional[Rgba], ...]   # one per group of faces, in order
    groups: numpy.ndarray                 # per face: its index in ``colours``


def lean_mesh_imports() -> None:
    """
    Import trimesh without :data:`TRIMESH_SPARED` from now on, in a process of r2d2_sim's own.

    ``sim_node`` calls it: nothing else there uses trimesh, whose parsers
    do not need them. A process that shares trimesh with other code (a test
    with ``SimHarness``) keeps trimesh whole: a module trimesh imported
    without scipy goes on without it.
    """
    global _lean
    _lean = True


def _import_trimesh() -> None:
    """Import trimesh (lean when asked, the spared modules refused only while it imports)."""
    if 'trimesh' in sys.modules:
        return
    spared = [name for name in TRIMESH_SPARED if _lean and name not in sys.modules]
    for name in spared:
        sys.modules[name] = None  # type: ignore[assignment]  # ImportError at once
    try:
        import trimesh  # noqa: F401
    finally:
        for name in spared:
            if name in sys.modules and sys.modules[name] is None:
                del sys.modules[name]


def _quiet_trimesh() -> None:
    # trimesh logs what it cannot do without scipy (which it does not need here).
    logging.getLogger('trimesh').setLevel(logging.ERROR)


def check_triangles(count: int, shown: str) -> None:
    """Refuse a mesh of more than MAX_MESH_TRIANGLES triangles (UNSUPPORTED_ASSETS)."""
    if count > MAX_MESH_TRIANGLES:
        raise RefusedError(UNSUPPORTED, f'mesh {shown} has {count} triangles, more than '
                                        f'{MAX_MESH_TRIANGLES}')


def declared_triangles(data: bytes, extension: str) -> int:
    """
    Return how many triangles a mesh file says it holds, read without parsing it.

    A binary STL's header count; an ASCII STL's facets; an OBJ's face lines
    (a polygon is more than one triangle: at least this many); COLLADA's
    ``count`` of its ``<triangles>``, ``<polylist>`` and ``<polygons>``
    (each polygon at least one triangle). Milliseconds for a large file, so a
    world over its triangle budget is refused before a mesh is converted;
    0 for another format.
    """
    if extension == '.stl':
        if len(data) >= 84 and not data[:5].lower() == b'solid':
            return int(struct.unpack('<I', data[80:84])[0])
        return data.count(b'endfacet')  # 'facet normal' ... 'endfacet': one each
    if extension == '.obj':
        return (data.count(b'\nf ') + data.count(b'\nf\t') +
                int(data.startswith((b'f ', b'f\t'))))
    if extension == '.dae':
        return sum(map(int, _COLLADA_COUNT.findall(data)))
    return 0


def _join(pieces: List[Tuple[numpy.ndarray, numpy.ndarray, Optional[Rgba]]], shown: str
          ) -> Triangles:
    """Join (vertices, faces, colour) pieces into one mesh, faces grouped by colour."""
    pieces = [(v, f, c) for v, f, c in pieces if len(f)]
    if not pieces:
        raise RefusedError(PARSE, f'mesh {shown} has no triangles')
    check_triangles(sum(len(f) for _, f, _ in pieces), shown)
    colours: List[Optional[Rgba]] = []
    vertices, faces, groups = [], [], []
    offset = 0
    for v, f, colour in pieces:
        if colour not in colours:
            colours.append(colour)
        try:
            vertices.append(numpy.asarray(v, dtype=float).reshape(-1, 3))
            faces.append(numpy.asarray(f, dtype=numpy.int64).reshape(-1, 3) + offset)
        except (ValueError, TypeError):  # a parser's arrays of a broken file
            raise RefusedError(PARSE, f'mesh {shown}: its vertices or triangles do not read as '
                                      'points and triangles') from None
        groups.append(numpy.full(len(faces[-1]), colours.index(colour)))
        offset += len(vertices[-1])
    # One piece (an STL, most meshes) is not copied: 40 MB copied hold the interpreter lock.
    joined = vertices[0] if len(vertices) == 1 else numpy.concatenate(vertices)
    if not numpy.all(numpy.isfinite(joined)) or numpy.abs(joined).max() > MAX_COORDINATE:
        raise RefusedError(PARSE, f'mesh {shown} has a vertex that is not finite or more than '
                                  f'{MAX_COORDINATE:g} from its origin')
    joined_faces = faces[0] if len(faces) == 1 else numpy.concatenate(faces)
    if joined_faces.min() < 0 or joined_faces.max() >= len(joined):
        raise RefusedError(PARSE, f'mesh {shown} has a triangle of a vertex it does not have')
    return Triangles(joined, joined_faces, tuple(colours),
                     groups[0] if len(groups) == 1 else numpy.concatenate(groups))


def _check_collada_bytes(data: bytes, shown: str) -> None:
    """
    Refuse COLLADA that pycollada would unzip, or read in an encoding that hides markup.

    pycollada opens any data with a zip directory at its end as an archive
    and parses the .dae inside, past the size bound and the DOCTYPE check
    (40 kB became 950 MB); Gazebo reads no zipped COLLADA either. The DOCTYPE
    check reads bytes, so the markup must be ASCII: UTF-8 (or ASCII, Latin-1).
    """
    if data.startswith(b'PK\x03\x04') or zipfile.is_zipfile(io.BytesIO(data)):
        raise RefusedError(UNSUPPORTED, f'mesh {shown} is a zip archive: r2d2_sim reads '
                                        'COLLADA (.dae) files unzipped, as Gazebo does')
    text = data[3:] if data.startswith(b'\xef\xbb\xbf') else data
    text = text[:1024].lstrip(b' \t\r\n')
    declared = _DECLARED_ENCODING.match(text)
    if not text.startswith(b'<') or (declared is not None and declared.group(1).decode(
            'ascii').lower() not in _ASCII_MARKUP):
        raise RefusedError(UNSUPPORTED, f'mesh {shown} is not UTF-8 text: r2d2_sim reads '
                                        'COLLADA in UTF-8')


def _dae(data: bytes, shown: str) -> Triangles:
    _check_collada_bytes(data, shown)
    if _XML_DECLARATIONS.search(data):
        raise RefusedError(PARSE, f'mesh {shown} declares a DOCTYPE or entities, which COLLADA '
                                  'does not need')
    import collada
    import collada.polylist
    import collada.triangleset
    ignore = [collada.common.DaeUnsupportedError, collada.common.DaeBrokenRefError]
    with warnings.catch_warnings():  # pycollada still uses numpy.matrix
        warnings.simplefilter('ignore', PendingDeprecationWarning)
        return _join(_dae_pieces(collada, data, ignore, shown), shown)


def _dae_pieces(collada: Any, data: bytes, ignore: List[type], shown: str
                ) -> List[Tuple[numpy.ndarray, numpy.ndarray, Optional[Rgba]]]:
    """Return a COLLADA file's triangle sets in metres, each with its material's colour."""
    try:
        document = collada.Collada(io.BytesIO(data), ignore=ignore)
        scene = document.scene
        if scene is None:
            raise RefusedError(PARSE, f'mesh {shown}: the COLLADA file has no <scene>')
        unit = document.assetInfo.unitmeter or 1.0
        pieces: List[Tuple[numpy.ndarray, numpy.ndarray, Optional[Rgba]]] = []
        for geometry in scene.objects('geometry'):
            for primitive in geometry.primitives():
                if isinstance(primitive, collada.polylist.BoundPolylist):  # polygons too
                    primitive = primitive.triangleset()
                if not isinstance(primitive, collada.triangleset.BoundTriangleSet):
                    continue  # lines: nothing to collide with or draw
                if primitive.vertex is None or not len(primitive.vertex_index):
                    continue
                diffuse = getattr(getattr(primitive.material, 'effect', None), 'diffuse', None)
                colour: Optional[Rgba] = None
                if isinstance(diffuse, tuple) and len(diffuse) >= 3:
                    rgba = [float(c) for c in diffuse[:4]] + [1.0]  # opaque unless given
                    colour = (rgba[0], rgba[1], rgba[2], rgba[3])
                pieces.append((primitive.vertex * unit, primitive.vertex_index, colour))
                check_triangles(sum(len(p[1]) for p in pieces), shown)
    except RefusedError:
        raise
    except Exception as exc:  # pycollada raises many kinds on a malformed file
        raise RefusedError(PARSE, f'mesh {shown} is not a COLLADA file r2d2_sim can read '
                                  f'({type(exc).__name__})') from None
    return pieces


def _stl(data: bytes, shown: str) -> Triangles:
    check_triangles(declared_triangles(data, '.stl'), shown)
    _import_trimesh()
    from trimesh.exchange.stl import load_stl
    try:
        loaded = load_stl(io.BytesIO(data))
        vertices, faces = loaded['vertices'], loaded['faces']
    except Exception as exc:
        raise RefusedError(PARSE, f'mesh {shown} is not an STL file r2d2_sim can read '
                                  f'({type(exc).__name__})') from None
    return _join([(vertices, faces, None)], shown)


class _MaterialFiles:
    """What an OBJ may read beside itself: its .mtl files in its own directory, bounded."""

    def __init__(self, directory: str) -> None:
        self._directory = os.path.realpath(directory)

    def get(self, name: str) -> bytes:
        path = os.path.realpath(os.path.join(self._directory, name))
        if not name.lower().endswith('.mtl') or os.path.dirname(path) != self._directory:
            raise OSError('not served')  # textures and anything elsewhere: no colour
        return read_regular(path, MAX_MTL_BYTES)  # OSError: no colour, as trimesh takes it

    __getitem__ = get


def obj_materials(data: bytes, directory: str) -> bytes:
    """
    Return what an OBJ's colours come from besides its bytes: its .mtl file's name and bytes.

    The .mtl trimesh reads (the rest of the line after the first ``mtllib``), as
    :class:`_MaterialFiles` serves it (empty when it serves none), so a cache key
    holding it changes whenever the colours could.
    """
    text = data.replace(b'\r\n', b'\n').replace(b'\\\n', b'')
    at = text.find(b'mtllib')
    if at < 0:
        return b''
    end = text.find(b'\n', at)
    name = text[at + 6:end if end >= 0 else len(text)].strip()
    try:
        content = _MaterialFiles(directory).get(name.decode('utf-8', 'replace'))
    except OSError:
        content = b''
    return b'%d:%s%d:%s' % (len(name), name, len(content), content)


def _obj(data: bytes, shown: str, directory: str) -> Triangles:
    check_triangles(declared_triangles(data, '.obj'), shown)
    _import_trimesh()
    from trimesh.exchange.obj import load_obj
    try:
        loaded = load_obj(io.BytesIO(data),
                          # trimesh reads a resolver by [] and get(); its hint names its classes
                          resolver=_MaterialFiles(directory),  # type: ignore[arg-type]
                          group_material=True, maintain_order=True)
    except Exception as exc:
        raise RefusedError(PARSE, f'mesh {shown} is not an OBJ file r2d2_sim can read '
                                  f'({type(exc).__name__})') from None
    geometries = loaded.get('geometry', {'': loaded}) if 'geometry' in loaded else {'': loaded}
    pieces: List[Tuple[numpy.ndarray, numpy.ndarray, Optional[Rgba]]] = []
    for name in sorted(geometries):
        geometry = geometries[name]
        if 'faces' not in geometry:
            continue
        material = getattr(geometry.get('visual'), 'material', None)
        diffuse = getattr(material, 'diffuse', None)
        colour: Optional[Rgba] = None
        if diffuse is not None:  # trimesh's materials hold RGBA
            red, green, blue, alpha = (float(c) / 255.0 for c in diffuse[:4])
            colour = (red, green, blue, alpha)
        pieces.append((geometry['vertices'], geometry['faces'], colour))
    return _join(pieces, shown)


def read_mesh(path: str, shown: str, data: Optional[bytes] = None) -> Triangles:
    """
    Return a mesh file's triangles in metres; RefusedError (naming ``shown``) if it is bad.

    UNSUPPORTED_ASSETS for a format other than DAE, STL and OBJ, a file over
    MAX_MESH_BYTES or more than MAX_MESH_TRIANGLES triangles;
    RESOURCE_PARSE_ERROR for one that does not read.
    """
    extension = os.path.splitext(path)[1].lower()
    if extension not in MESH_FORMATS:
        raise RefusedError(UNSUPPORTED, f'mesh {shown}: r2d2_sim reads DAE, STL and OBJ '
                                        'meshes')
    if data is None:
        data = read_mesh_bytes(path, shown)
    _quiet_trimesh()
    if extension == '.dae':
        return _dae(data, shown)
    if extension == '.stl':
        return _stl(data, shown)
    return _obj(data, shown, os.path.dirname(path))


def read_mesh_bytes(path: str, shown: str) -> bytes:
    """
    Return a mesh file's bytes, at most MAX_MESH_BYTES; RefusedError if it cannot be had.

    A regular file only (a FIFO would hold the load, and SIGINT, forever):
    UNSUPPORTED_ASSETS for anything else or a file too large, MISSING_ASSETS
    for one that cannot be opened.
    """
    try:
        return read_regular(path, MAX_MESH_BYTES)
    except UnsafeFile as exc:
        if exc.errno == errno.EFBIG:
            raise RefusedError(UNSUPPORTED, f'mesh {shown} is larger than {MAX_MESH_BYTES} '
                                            'bytes') from None
        raise RefusedError(UNSUPPORTED, f'mesh {shown} is not a regular file') from None
    except OSError:
        raise RefusedError('MISSING_ASSETS', f'mesh {shown} cannot be read') from None
