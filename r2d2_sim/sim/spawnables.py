"""
What a spawn request may load, read safely: a URDF or an SDF model from a file, a package or text.

No ROS here. Spawn requests come from anyone on the ROS domain, so what one
may cost is bounded: the description's size, its links, no XML entities or
DOCTYPE (the billion-laughs bomb), and meshes only from the description's own
directory, a ROS package or pybullet_data. Every refusal is a
:class:`~r2d2_sim.errors.RefusedError` with the standard's result code and a
one-line message that names neither a file's content nor more than the
offending path. SDF models (a ``.sdf`` file, ``model://``, a Fuel URL from the
local cache, ``<sdf>`` text) are read in :mod:`r2d2_sim.sim.sdf.spawning` and
spawn as the URDF written from them.
"""

import errno
import functools
import math
import os
from stat import S_ISREG
from typing import FrozenSet, List, NamedTuple, Optional, Protocol, Sequence, Tuple
import xml.etree.ElementTree as ElementTree
from xml.sax.saxutils import quoteattr

import pybullet_data

from r2d2_sim.errors import RefusedError
from r2d2_sim.files import read_regular, UnsafeFile
from r2d2_sim.model.transforms import IDENTITY, Transform
from r2d2_sim.physics.description import (
    check_robot_inertias, check_urdf, DescriptionError, DescriptionFile, PACKAGE_SCHEME,
    package_share_directory, resolve_description_path)
from r2d2_sim.sim.sdf.loading import SdfSettings, TriangleBudget
from r2d2_sim.sim.sdf.mesh_cache import MeshCache
from r2d2_sim.sim.sdf.spawning import is_sdf_spawn, read_sdf_spawnable

__all__ = ['check_description', 'check_tree', 'check_driven', 'read_description',
           'convert_meshes', 'MeshUse', 'read_spawnable', 'spawnable_uris',
           'directory_spawnables', 'Spawnable', 'Closable', 'box_urdf', 'MAX_DESCRIPTION_BYTES',
           'MAX_LINKS']


class MeshUse(NamedTuple):
    """One use of a mesh in a URDF: the file's path, and its name as the URDF wrote it."""

    path: str
    shown: str


# What one spawn request may cost (a URDF of R2D2 is 14 kB and 16 links).
MAX_DESCRIPTION_BYTES = 1_000_000
MAX_LINKS = 200
# What GetSpawnables lists of one directory a request names.
MAX_LISTED = 1000


def check_description(text: str, base_dir: Optional[str], shown: str,
                      triangles: Optional[TriangleBudget] = None) -> str:
    """
    Return the URDF's robot name if ``text`` is one a domain peer may have us load.

    ``base_dir`` is the description file's directory (None for text sent in
    a request), ``shown`` what a refusal calls it (the request's URI, or "the
    resource_string"). Its meshes are held to the bounds of an SDF world's before
    PyBullet sees them (a regular file, size, triangles: read and converted
    through the mesh cache), every use counted against ``triangles`` (a
    world's, shared by its models; by default this description's own), first
    from what the files say they hold, before any is converted.
    RefusedError otherwise: RESOURCE_PARSE_ERROR, UNSUPPORTED_FORMAT,
    MISSING_ASSETS or UNSUPPORTED_ASSETS, naming neither a file's content nor
    more than the offending path.
    """
    name, meshes = read_description(text, base_dir, shown)
    budget = triangles if triangles is not None else TriangleBudget()
    budget.expect([path for path, _ in meshes], '')
    convert_meshes(meshes, budget)
    return name


def read_description(text: str, base_dir: Optional[str], shown: str
                     ) -> Tuple[str, List[MeshUse]]:
    """
    Return the URDF's robot name and its meshes, checked as :func:`check_description` does.

    Every use of a mesh, its path found and checked to lie where it may;
    nothing converted yet (:func:`convert_meshes`).
    """
    if len(text.encode('utf-8', errors='replace')) > MAX_DESCRIPTION_BYTES:
        raise RefusedError('RESOURCE_PARSE_ERROR', f'the description is larger than '
                           f'{MAX_DESCRIPTION_BYTES} bytes')
    if '<!DOCTYPE' in text or '<!ENTITY' in text:
        raise RefusedError('RESOURCE_PARSE_ERROR', 'the description declares a DOCTYPE or '
                           'entities, which a URDF does not need')
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as exc:
        raise RefusedError('RESOURCE_PARSE_ERROR', f'not well-formed XML ({exc})') from None
    if root.tag != 'robot':
        raise RefusedError('UNSUPPORTED_FORMAT', f'the root element is <{root.tag[:40]}>, '
                           'not a URDF <robot>')
    links = root.findall('link')
    if not links:
        raise RefusedError('RESOURCE_PARSE_ERROR', 'the URDF has no <link>')
    if len(links) > MAX_LINKS:
        raise RefusedError('RESOURCE_PARSE_ERROR', f'the URDF has {len(links)} links, more '
                           f'than {MAX_LINKS}')
    check_tree(root, shown)
    meshes = []
    for mesh in root.iter('mesh'):
        filename = mesh.get('filename', '')
        meshes.append(MeshUse(_check_mesh(filename, base_dir), filename[:200]))
    return root.get('name', ''), meshes


def check_tree(root: ElementTree.Element, shown: str) -> None:
    """Raise RefusedError RESOURCE_PARSE_ERROR for a URDF tree or number PyBullet misreads."""
    try:
        check_urdf(root, shown)
    except DescriptionError as exc:
        raise RefusedError('RESOURCE_PARSE_ERROR', str(exc)) from None


def check_driven(text: str, shown: str) -> None:
    """
    Refuse (RESOURCE_PARSE_ERROR) a spawned robot's URDF whose inertias PyBullet reads as 0.

    ``text`` is a checked description (:func:`check_description`); a driven
    robot loads its inertias from it (:func:`check_robot_inertias`).
    """
    try:
        check_robot_inertias(ElementTree.fromstring(text), shown)
    except DescriptionError as exc:
        raise RefusedError('RESOURCE_PARSE_ERROR', str(exc)) from None


def convert_meshes(meshes: Sequence[MeshUse], triangles: TriangleBudget) -> None:
    """Convert a URDF's meshes through the mesh cache, each use counted against ``triangles``."""
    cache = MeshCache()
    for path, shown in meshes:
        triangles.take(cache.convert(path, shown).triangles, f'mesh {shown}')


def _check_mesh(filename: str, base_dir: Optional[str]) -> str:
    """Return a mesh's path: from the description's directory, a ROS package or pybullet_data."""
    shown = filename[:200]
    if filename.startswith(PACKAGE_SCHEME):
        package, _, relative = filename[len(PACKAGE_SCHEME):].partition('/')
        try:
            root = package_share_directory(package)
        except DescriptionError:
            raise RefusedError('MISSING_ASSETS', f'mesh {shown}: no package {package!r}') from None
        path = os.path.join(root, relative)
    elif filename.startswith('file://') or os.path.isabs(filename) or base_dir is None:
        raise RefusedError('UNSUPPORTED_ASSETS', f'mesh {shown}: meshes must be relative to the '
                           'URDF file or package:// URIs')
    else:
        root = base_dir
        path = os.path.join(base_dir, filename)
    real = os.path.realpath(path)
    roots = (os.path.realpath(root), os.path.realpath(pybullet_data.getDataPath()))
    if not any(real == r or real.startswith(r + os.sep) for r in roots):
        raise RefusedError('UNSUPPORTED_ASSETS', f'mesh {shown} lies outside the URDF\'s '
                           'directory and package')
    if not os.path.lexists(real):
        raise RefusedError('MISSING_ASSETS', f'mesh {shown} does not exist')
    return real


class Closable(Protocol):
    """What a spawn keeps open while its body lives (a temporary file, an SDF model's files)."""

    def close(self) -> None:
        """Remove what was written; closing twice does nothing."""


class Spawnable(NamedTuple):
    """
    What a spawn loads: a URDF file and its text, a temporary file to close, the name it gives.

    ``base`` is where the URDF's base link stands in the frame the request
    places (an SDF model's frame; the identity for a URDF); ``sdf``: made from
    SDF (loaded as Gazebo simulates it); ``notes``: what it does not simulate.
    """

    path: str
    file: Optional[Closable]   # the temporary file(s), or None
    name: str
    text: str
    base: Transform = IDENTITY
    sdf: bool = False
    notes: str = ''


def read_spawnable(uri: str, resource_string: str, sdf: SdfSettings = SdfSettings()
                   ) -> Spawnable:
    """
    Return what a spawn loads (see :class:`Spawnable`).

    ``uri`` wins over ``resource_string`` (the standard's rule): a file path,
    ``file://``, ``package://`` or a pybullet_data name, resolved as the
    ``urdf`` parameter is; an SDF model as ``sdf`` says where to look.
    RefusedError NOT_FOUND (no such file), NO_RESOURCE (nothing named),
    UNSUPPORTED_FORMAT...
    """
    if is_sdf_spawn(uri, resource_string):
        found = read_sdf_spawnable(uri, resource_string, sdf)
        return Spawnable(found.path, found.files, found.name, found.text, found.base, True,
                         found.notes)
    if uri:
        path = uri[len('file://'):] if uri.startswith('file://') else uri
        try:
            path = resolve_description_path(path)
        except DescriptionError as exc:
            # No match for the input: the generic NOT_FOUND, as LoadWorld answers; the
            # standard keeps NO_RESOURCE for a request that names nothing at all.
            raise RefusedError('NOT_FOUND', str(exc)) from None
        if not path.lower().endswith('.urdf'):
            raise RefusedError('UNSUPPORTED_FORMAT', f'{uri[:200]}: only .urdf and .sdf files '
                               'can be spawned')
        try:
            text = read_regular(path, MAX_DESCRIPTION_BYTES).decode('utf-8')
        except UnsafeFile as exc:  # too large, or not a regular file (a FIFO would hang)
            problem = (f'is larger than {MAX_DESCRIPTION_BYTES} bytes'
                       if exc.errno == errno.EFBIG else 'is not a regular file')
            raise RefusedError('RESOURCE_PARSE_ERROR', f'{uri[:200]} {problem}') from None
        except (OSError, UnicodeDecodeError):
            raise RefusedError('RESOURCE_PARSE_ERROR', f'{uri[:200]} cannot be read as '
                               'text') from None
        return Spawnable(path, None, check_description(text, os.path.dirname(path), uri[:200]),
                         text)
    if not resource_string:
        raise RefusedError('NO_RESOURCE', 'neither a uri nor a resource_string was given')
    name = check_description(resource_string, None, 'the resource_string')
    description = DescriptionFile(resource_string)
    return Spawnable(description.path, description, name, resource_string)


@functools.lru_cache(maxsize=1)
def spawnable_uris() -> Tuple[str, ...]:
    """
    Return the URDFs GetSpawnables offers: this package's and pybullet_data's a spawn takes.

    Each is read once per process and checked as a spawn checks it
    (:func:`read_spawnable`): pybullet_data also holds files a spawn refuses
    (``torus_deform.urdf``, a deformable body with no ``<link>``), which the
    standard's "valid as SpawnEntity uri fields" leaves out.
    """
    uris = []
    try:
        share = package_share_directory('r2d2_sim')
        uris += [f'{PACKAGE_SCHEME}r2d2_sim/urdf/{name}'
                 for name in sorted(os.listdir(os.path.join(share, 'urdf')))
                 if name.endswith('.urdf')]
    except (DescriptionError, OSError):
        pass
    data = pybullet_data.getDataPath()
    uris += sorted(name for name in os.listdir(data) if name.endswith('.urdf'))
    return tuple(uri for uri in uris if _spawns(uri))


def _spawns(uri: str, sdf: SdfSettings = SdfSettings()) -> bool:
    """Return True when a spawn of ``uri`` would be taken: read and checked as one is."""
    try:
        spawnable = read_spawnable(uri, '', sdf)
    except RefusedError:
        return False
    if spawnable.file is not None:
        spawnable.file.close()
    return True


@functools.lru_cache(maxsize=4096)
def _file_spawns(path: str, size: int, mtime_ns: int, sdf: SdfSettings) -> bool:
    """Return :func:`_spawns` of a file as it is now (its size and time): asked again, kept."""
    return _spawns(path, sdf)


@functools.lru_cache(maxsize=1)
def _default_paths() -> FrozenSet[str]:
    """Return the real paths of the files :func:`spawnable_uris` lists."""
    paths = set()
    for uri in spawnable_uris():
        try:
            paths.add(os.path.realpath(resolve_description_path(uri)))
        except DescriptionError:  # gone since: nothing to leave out for it
            pass
    return frozenset(paths)


def directory_spawnables(source: str, sdf: SdfSettings = SdfSettings()) -> Optional[List[str]]:
    """
    Return the model files a spawn takes by path from a directory a GetSpawnables source names.

    ``source``: an absolute path, ``file://`` or ``package://`` (a package's
    share directory). Its ``.urdf`` and ``.sdf`` files that a spawn takes,
    each read and checked as a spawn reads it (a world SDF, a URDF with no
    link are left out; an SDF model only where ``sdf`` lets SDF models be
    read from), and not among :func:`spawnable_uris`' (listed already, under
    their short names); their paths, sorted, at most MAX_LISTED. A file's
    verdict is kept while its size and time stay. None when the source names
    no directory.
    """
    path = source[len('file://'):] if source.startswith('file://') else source
    if path.startswith(PACKAGE_SCHEME):
        package, _, relative = path[len(PACKAGE_SCHEME):].partition('/')
        try:
            path = os.path.join(package_share_directory(package), relative)
        except DescriptionError:
            return None
    if not os.path.isabs(path) or not os.path.isdir(path):
        return None
    try:
        names = sorted(os.listdir(path))
    except OSError:
        return None
    listed, defaults = [], _default_paths()
    for name in names:
        file = os.path.join(path, name)
        if not name.lower().endswith(('.urdf', '.sdf')) or os.path.realpath(file) in defaults:
            continue
        try:
            stat = os.stat(file)
        except OSError:
            continue
        if S_ISREG(stat.st_mode) and _file_spawns(file, stat.st_size, stat.st_mtime_ns, sdf):
            listed.append(file)
            if len(listed) == MAX_LISTED:
                break
    return listed


def box_urdf(size_m: Sequence[float] = (0.2, 0.2, 0.2), *, mass_kg: float = 0.0,
             name: str = 'box', rgba: Sequence[float] = (0.8, 0.5, 0.2, 1.0)) -> str:
    """
    Return the URDF text of a solid box, its base link at its centre.

    ``mass_kg`` 0 (the default) makes it fixed: PyBullet gives a base link of
    mass 0 a fixed base, so robots cannot push it (a wall, a dock, a pillar;
    the standard's ``GetEntityInfo`` reports it as STATIC_OBJECT). A positive
    mass makes it a pushable box with a uniform solid's inertia. ``rgba`` is
    its colour in the camera and the live view.
    """
    x, y, z = (float(v) for v in size_m)
    if not all(math.isfinite(v) and v > 0.0 for v in (x, y, z)):
        raise ValueError(f'a box needs three positive sizes, got {tuple(size_m)}')
    if not (math.isfinite(mass_kg) and mass_kg >= 0.0):
        raise ValueError(f'a box needs a mass >= 0 kg, got {mass_kg}')
    geometry = f'<geometry><box size="{x!r} {y!r} {z!r}"/></geometry>'
    # PyBullet takes a link without <inertial> as 1 kg: a fixed box says mass 0.
    m = mass_kg / 12.0
    inertial = (f'<inertial><mass value="{mass_kg!r}"/><inertia ixx="{m * (y * y + z * z)!r}" '
                f'iyy="{m * (x * x + z * z)!r}" izz="{m * (x * x + y * y)!r}" ixy="0" '
                'ixz="0" iyz="0"/></inertial>')
    colour = ' '.join(repr(float(c)) for c in rgba)
    return (f'<robot name={quoteattr(name)}><link name={quoteattr(name)}>{inertial}'
            f'<collision>{geometry}</collision><visual>{geometry}<material name="colour">'
            f'<color rgba="{colour}"/></material></visual></link></robot>')
