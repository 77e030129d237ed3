"""
Worlds: what one is, where they come from, and reading one as the simulation standard asks.

No ROS here. A :class:`World` is what the ``world`` parameter or a
LoadWorld request names: its models (URDF files, each at a pose, with tags),
its named poses (:class:`~r2d2_sim.sim.world_manifest.NamedPose`), a name,
description and tags. Three formats are read, behind one function
(:func:`read_world`) that a new format joins by adding a :class:`WorldFormat`
to :data:`FORMATS`: a URDF (the whole world is that one model, as
``urdf/room.urdf``), r2d2_sim's world manifest
(:mod:`~r2d2_sim.sim.world_manifest`, ``*.world.yaml``) and SDF, Gazebo's
worlds and models (:mod:`~r2d2_sim.sim.sdf_world`, ``*.sdf``, ``*.world``),
whose models a manifest may list too.

A request may load worlds only from allowed places (:class:`Places`): this
package's ``urdf/``, the directories of the ``world_paths`` parameter,
pybullet_data, and any ROS package's share directory through ``package://``
(an SDF world's includes and meshes the model search paths and the Fuel cache
too). The ``world`` parameter is the operator's own and may name any file.
:func:`list_worlds` is GetAvailableWorlds: the manifests and SDF worlds of
those places and of the request's ``additional_sources``. Every refusal is a
:class:`~r2d2_sim.errors.RefusedError` with LoadWorld's (or
GetAvailableWorlds') code and a one-line message that names files, never
their contents.
"""

import os
import re
import stat
from typing import Callable, List, NamedTuple, Optional, Sequence, Tuple
import xml.etree.ElementTree as ElementTree

import pybullet_data

from r2d2_sim.errors import RefusedError
from r2d2_sim.physics.description import (
    DescriptionError, DescriptionFile, PACKAGE_NAME, PACKAGE_SCHEME, package_share_directory,
    SOURCE_TREE)
from r2d2_sim.sim.sdf.loading import SdfSettings
from r2d2_sim.sim.spawnables import check_description, MAX_DESCRIPTION_BYTES
from r2d2_sim.sim.tags import TagsFilter, tags_match
from r2d2_sim.sim.world_manifest import (
    load_yaml, MAX_WORLD_BYTES, NamedPose, read_manifest)

__all__ = ['World', 'WorldModel', 'WorldEntry', 'NamedPose', 'LoadOptions', 'Places',
           'SdfSettings', 'WorldFormat', 'FORMATS', 'read_world', 'list_worlds', 'empty_world',
           'PACKAGE_WORLDS', 'EMPTY_WORLD_URI', 'WORLD_SUFFIX', 'SDF_SUFFIXES',
           'MAX_WORLDS_PER_SOURCE']

PACKAGE_WORLDS = f'{PACKAGE_SCHEME}{PACKAGE_NAME}/urdf'
EMPTY_WORLD_URI = f'{PACKAGE_WORLDS}/empty.world.yaml'
WORLD_SUFFIX = '.world.yaml'
SDF_SUFFIXES = ('.sdf', '.world')
MAX_WORLDS_PER_SOURCE = 1000
FILE_SCHEME = 'file://'
# A URDF's top-level elements PyBullet reads; others (gazebo, transmission...) it ignores.
URDF_ELEMENTS = ('link', 'joint', 'material')
_SCHEME = re.compile(r'[A-Za-z][A-Za-z0-9+.-]*://')

Vec3 = Tuple[float, float, float]
Quat = Tuple[float, float, float, float]


class WorldModel(NamedTuple):
    """
    One model of a world: a URDF file to load at a pose, and what the standard says of it.

    ``sdf``: made from SDF, so loaded as Gazebo would simulate it (the file's
    inertias, true cylinders, joints free but for their friction).
    """

    name: Optional[str]      # None: the URDF's robot name, made unique
    path: str                # the file PyBullet loads
    source: str              # the URI as written ('resource_string' for text)
    position: Vec3
    orientation: Quat
    description: str
    tags: Tuple[str, ...]
    sdf: bool = False


class World(NamedTuple):
    """
    A world as read: its models, named poses and what GetCurrentWorld tells of it.

    ``uri`` and ``resource_string`` are the request's (or the ``world``
    parameter's); ``start_pose`` is the named pose the start-up robots stand
    at (None: the world's origin); ``notes`` say what was left out or
    ignored; ``resources`` are temporary files to close with the world.
    """

    name: str
    uri: str
    resource_string: str
    description: str
    tags: Tuple[str, ...]
    models: Tuple[WorldModel, ...]
    named_poses: Tuple[NamedPose, ...]
    start_pose: Optional[NamedPose]
    notes: Tuple[str, ...] = ()
    resources: Tuple[DescriptionFile, ...] = ()

    def named_pose(self, name: str) -> NamedPose:
        """Return the named pose ``name``; RefusedError NOT_FOUND listing the others."""
        for pose in self.named_poses:
            if pose.name == name:
                return pose
        known = ', '.join(p.name for p in self.named_poses) or 'none'
        raise RefusedError('NOT_FOUND', f'no named pose {name[:100]!r} in the world '
                                        f'{self.name}; it has: {known}')

    def close(self) -> None:
        """Delete the temporary files of a world given as text; safe to call twice."""
        for resource in self.resources:
            resource.close()


class WorldEntry(NamedTuple):
    """A world GetAvailableWorlds lists: its name, the URI that loads it, description, tags."""

    name: str
    uri: str
    description: str
    tags: Tuple[str, ...]


class LoadOptions(NamedTuple):
    """LoadWorld's two flags, as the standard defines them (both default to False)."""

    fail_on_unsupported_element: bool = False
    ignore_missing_or_unsupported_assets: bool = False


def empty_world() -> World:
    """Return the empty world: no models, no named poses (what ``world`` '' loads)."""
    return World('empty', EMPTY_WORLD_URI, '', 'The ground plane and the robots, nothing else.',
                 ('empty',), (), (), None)


def _stem(path: str) -> str:
    name = os.path.basename(path)
    for suffix in (WORLD_SUFFIX, '.yaml', '.yml', '.urdf') + SDF_SUFFIXES:
        if name.endswith(suffix):
            return name[:-len(suffix)] or name
    return name


def _inside(path: str, root: str) -> bool:
    return path == root or path.startswith(root.rstrip(os.sep) + os.sep)


class Places:
    """
    Where worlds and their models come from, and where a request may load them from.

    ``world_paths`` are the directories the operator listed (paths,
    ``file://`` or ``package://`` URIs). A world or model URI is a path (a
    relative one is looked for beside the world file, then in this package's
    ``urdf/``, the ``world_paths`` and pybullet_data), a ``file://`` URI or a
    ``package://`` URI.
    """

    def __init__(self, world_paths: Sequence[str] = ()) -> None:
        self.world_paths = tuple(world_paths)

    def package_directory(self) -> Optional[str]:
        """Return this package's ``urdf/`` (installed, else beside the sources); None if lost."""
        try:
            directory = os.path.join(package_share_directory(PACKAGE_NAME), 'urdf')
        except DescriptionError:
            directory = os.path.join(SOURCE_TREE, 'urdf')
        return directory if os.path.isdir(directory) else None

    def directory(self, source: str) -> Tuple[str, Optional[str]]:
        """
        Return (directory, package share or None) of a source: a path, file:// or package://.

        NOT_FOUND when it is not a directory, or leaves its package.
        """
        share = None
        if source.startswith(PACKAGE_SCHEME):
            package, _, relative = source[len(PACKAGE_SCHEME):].partition('/')
            try:
                share = os.path.realpath(package_share_directory(package))
            except DescriptionError:
                raise RefusedError('NOT_FOUND', f'{source[:200]}: no ROS package '
                                                f'{package[:100]!r}') from None
            path = os.path.join(share, relative)
            if not _inside(os.path.realpath(path), share):
                raise RefusedError('NOT_FOUND', f'{source[:200]} leaves its package')
        else:
            path = source[len(FILE_SCHEME):] if source.startswith(FILE_SCHEME) else source
        if not os.path.isdir(path):
            raise RefusedError('NOT_FOUND', f'{source[:200]} is not a directory')
        return os.path.abspath(path), share

    def roots(self) -> List[str]:
        """Return the real paths of the directories a request may load worlds from."""
        roots = [os.path.realpath(pybullet_data.getDataPath())]
        own = self.package_directory()
        for directory in (own, os.path.join(SOURCE_TREE, 'urdf')):
            if directory is not None and os.path.isdir(directory):
                roots.append(os.path.realpath(directory))
        for source in self.world_paths:
            try:
                roots.append(os.path.realpath(self.directory(source)[0]))
            except RefusedError:
                pass  # GetAvailableWorlds reports it
        return roots

    def search(self) -> List[str]:
        """Return where a relative name is looked for: ``urdf/``, world_paths, pybullet_data."""
        found = [d for d in [self.package_directory()] if d is not None]
        for source in self.world_paths:
            try:
                found.append(self.directory(source)[0])
            except RefusedError:
                pass
        return found + [pybullet_data.getDataPath()]

    def resolve(self, uri: str, base_dir: Optional[str] = None) -> Tuple[str, Optional[str]]:
        """
        Return (path, root) for a URI; root is the directory it may not leave, or None.

        A ``package://`` URI may not leave its package; a relative path is
        looked for beside the world file (``base_dir``), then in the working
        directory (the operator's ``world`` only makes use of it), then in
        :meth:`search`'s places. NOT_FOUND for a remote URI or a missing package.
        """
        if uri.startswith(PACKAGE_SCHEME):
            package, _, relative = uri[len(PACKAGE_SCHEME):].partition('/')
            if not package or not relative:
                raise RefusedError('NOT_FOUND', f'malformed package URI {uri[:200]!r}: expected '
                                                'package://pkg/path')
            try:
                share = package_share_directory(package)
            except DescriptionError:
                raise RefusedError('NOT_FOUND', f'{uri[:200]}: no ROS package '
                                                f'{package[:100]!r}') from None
            return os.path.join(share, relative), os.path.realpath(share)
        if uri.startswith(FILE_SCHEME):
            return uri[len(FILE_SCHEME):], None
        if _SCHEME.match(uri):
            raise RefusedError('NOT_FOUND', f'{uri[:200]}: only local files are loaded (paths, '
                                            'file:// and package:// URIs)')
        if os.path.isabs(uri):
            return uri, None
        if base_dir is not None and os.path.exists(os.path.join(base_dir, uri)):
            return os.path.join(base_dir, uri), None
        if base_dir is None and os.path.isfile(uri):
            return os.path.abspath(uri), None
        search = self.search()
        for directory in search:
            candidate = os.path.join(directory, uri)
            if os.path.isfile(candidate):
                return candidate, None
        # Nowhere: a name in the first place looked at, which says it is missing.
        return os.path.join(base_dir or search[0], uri), None

    def allowed(self, path: str, *anchors: Optional[str]) -> bool:
        """Return True when ``path`` (links followed) lies in an allowed place or an anchor."""
        real = os.path.realpath(path)
        return any(_inside(real, root) for root in self.roots() + [a for a in anchors if a])


def _read_text(path: str, shown: str, code: str, limit: int) -> str:
    """Read a regular file of at most ``limit`` bytes as UTF-8 text; ``code`` if it cannot be."""
    try:
        info = os.stat(path)
    except OSError:
        raise RefusedError(code, f'{shown}: no such file') from None
    if not stat.S_ISREG(info.st_mode):
        raise RefusedError(code, f'{shown} is not a regular file')
    if info.st_size > limit:
        raise RefusedError('RESOURCE_PARSE_ERROR', f'{shown} is larger than {limit} bytes')
    try:
        with open(path, 'rb') as handle:
            data = handle.read(limit + 1)
        return data.decode('utf-8')
    except OSError:
        raise RefusedError(code, f'{shown} cannot be read') from None
    except UnicodeDecodeError:
        raise RefusedError('RESOURCE_PARSE_ERROR', f'{shown} is not UTF-8 text') from None


class _Reading:
    """
    One world being read: where from, how trusted, the request's options, what was noted.

    ``sdf``: what an SDF world is searched and compared with (model paths,
    r2d2_sim's physics step, gravity and ground plane).
    """

    def __init__(self, places: Places, options: LoadOptions, trusted: bool,
                 sdf: SdfSettings = SdfSettings()) -> None:
        self.places = places
        self.options = options
        self.trusted = trusted
        self.sdf = sdf
        self.notes: List[str] = []
        self.resources: List[DescriptionFile] = []

    def not_simulated(self, line: str) -> None:
        """Note one summary line of what is not simulated, or refuse it (UNSUPPORTED_ELEMENTS)."""
        if self.options.fail_on_unsupported_element:
            raise RefusedError('UNSUPPORTED_ELEMENTS', line)
        self.notes.append(line)

    def unsupported(self, where: Sequence[str], what: str) -> None:
        """
        Note elements that mean nothing here, or refuse them (fail_on_unsupported_element).

        ``where`` has one entry per element: where it is (never its text, which is
        the file's); ``what`` says what they are (``unknown keys``).
        """
        if not where:
            return
        counts = {}
        for place in where:
            counts[place] = counts.get(place, 0) + 1
        places = [f'{count} at {place}' for place, count in counts.items()]
        listed = f'{what}: ' + ', '.join(places[:10]) + (' ...' if len(places) > 10 else '')
        if self.options.fail_on_unsupported_element:
            raise RefusedError('UNSUPPORTED_ELEMENTS', listed)
        self.notes.append(f'ignored: {listed}')

    def urdf(self, text: str, base_dir: Optional[str], shown: str) -> str:
        """Check a URDF's text; return its robot name. The world's own codes on refusal."""
        if self.trusted:
            if '<!DOCTYPE' in text or '<!ENTITY' in text:
                raise RefusedError('RESOURCE_PARSE_ERROR', f'{shown} declares a DOCTYPE or '
                                                           'entities, which a URDF does not need')
            try:
                root = ElementTree.fromstring(text)
            except ElementTree.ParseError as exc:
                raise RefusedError('RESOURCE_PARSE_ERROR', f'{shown}: not well-formed XML '
                                                           f'({exc})') from None
            if root.tag != 'robot':
                raise RefusedError('UNSUPPORTED_FORMAT', f'{shown}: the root element is '
                                                         f'<{root.tag[:40]}>, not <robot>')
        else:
            name = check_description(text, base_dir)  # size, DOCTYPE, links, meshes' places
            root = ElementTree.fromstring(text)
        self.unsupported([shown for child in root if child.tag not in URDF_ELEMENTS],
                         'elements PyBullet does not read')
        return root.get('name', '') if self.trusted else name

    def model(self, entry, base_dir: Optional[str], anchor: Optional[str]) -> List[WorldModel]:
        """
        Return a manifest's model, its file found and checked (none: left out, as asked).

        A URDF is one model; an SDF file is the bodies of its models (several
        when no joint joins them), at the entry's pose, named after the entry.
        """
        try:
            path, root = self.places.resolve(entry.uri, base_dir)
            shown = entry.uri[:200]
            if not self.trusted and not self.places.allowed(path, anchor, root):
                raise RefusedError('UNSUPPORTED_ASSETS', f'model {shown} lies outside the places '
                                                         'worlds are loaded from')
            if not os.path.isfile(path):
                raise RefusedError('MISSING_ASSETS', f'model {shown}: no such file')
            if path.lower().endswith(SDF_SUFFIXES):
                from r2d2_sim.sim.sdf_world import sdf_models  # it reads with this class
                try:
                    return sdf_models(entry, path, self, anchor or os.path.dirname(path))
                except RefusedError as exc:  # the world is a manifest: its asset is at fault
                    if exc.code != 'UNSUPPORTED_FORMAT':
                        raise
                    raise RefusedError('UNSUPPORTED_ASSETS', exc.message) from None
            if not path.lower().endswith('.urdf'):
                raise RefusedError('UNSUPPORTED_ASSETS', f'model {shown}: only URDF and SDF '
                                                         'models are loaded')
            text = _read_text(path, f'model {shown}', 'MISSING_ASSETS', MAX_DESCRIPTION_BYTES)
            try:
                self.urdf(text, os.path.dirname(path), f'model {shown}')
            except RefusedError as exc:
                code = {'UNSUPPORTED_FORMAT': 'UNSUPPORTED_ASSETS',
                        'NO_RESOURCE': 'MISSING_ASSETS'}.get(exc.code, exc.code)
                raise RefusedError(code, f'model {shown}: {exc.message}') from None
        except RefusedError as exc:
            if (self.options.ignore_missing_or_unsupported_assets
                    and exc.code in ('MISSING_ASSETS', 'UNSUPPORTED_ASSETS', 'NOT_FOUND')):
                self.notes.append(f'left out: {exc.message}')
                return []
            if exc.code == 'NOT_FOUND':
                raise RefusedError('MISSING_ASSETS', exc.message) from None
            raise
        return [WorldModel(entry.name, path, entry.uri, entry.position, entry.orientation,
                           entry.description or entry.uri, entry.tags)]


class WorldFormat(NamedTuple):
    """
    A format worlds are read in: its file suffixes, how its text looks, and its reader.

    ``read(text, path, uri, reading)`` returns the World; ``path`` is None
    for a world given as text.
    """

    name: str
    suffixes: Tuple[str, ...]
    sniff: Callable[[str], bool]
    read: Callable[[str, Optional[str], str, '_Reading', Optional[str]], World]


def _xml_root(text: str) -> Optional[str]:
    match = re.match(r'\s*(?:<\?xml[^>]*\?>\s*)?(?:<!--.*?-->\s*)*<([A-Za-z_][\w.-]*)', text,
                     re.S)
    return match.group(1) if match else None


def _read_urdf_world(text: str, path: Optional[str], uri: str, reading: _Reading,
                     anchor: Optional[str]) -> World:
    shown = uri[:200] if uri else 'the resource_string'
    name = reading.urdf(text, os.path.dirname(path) if path else None, shown)
    if path is None:
        description = DescriptionFile(text)
        reading.resources.append(description)
        path = description.path
    model = WorldModel(None, path, uri or 'resource_string', (0.0, 0.0, 0.0),
                       (0.0, 0.0, 0.0, 1.0), uri or 'resource_string', ())
    return World(name or (_stem(path) if uri else 'world'), uri, '' if uri else text, '', (),
                 (model,), (), None)


def _read_manifest_world(text: str, path: Optional[str], uri: str, reading: _Reading,
                         anchor: Optional[str]) -> World:
    data = load_yaml(text)
    manifest = read_manifest(data, _stem(path) if path else 'world')
    reading.unsupported(list(manifest.ignored), 'unknown keys')
    base_dir = os.path.dirname(path) if path else None
    models: List[WorldModel] = []
    for entry in manifest.models:
        for model in reading.model(entry, base_dir, anchor):
            if model.sdf and model.name in {m.name for m in models}:  # two files' "crate"
                model = model._replace(name=_unused_name(model.name, models))
            models.append(model)
    start = None
    if manifest.start_pose is not None:
        start = next(p for p in manifest.named_poses if p.name == manifest.start_pose)
    return World(manifest.name, uri, '' if uri else text, manifest.description, manifest.tags,
                 tuple(models), manifest.named_poses, start)


def _unused_name(wanted: str, models: Sequence[WorldModel]) -> str:
    taken = {m.name for m in models}
    number = 1
    while f'{wanted}_{number}' in taken:
        number += 1
    return f'{wanted}_{number}'


def _sniff_yaml(text: str) -> bool:
    return not text.lstrip().startswith('<')


def _sniff_urdf(text: str) -> bool:
    return _xml_root(text) == 'robot'


def _sniff_sdf(text: str) -> bool:
    return _xml_root(text) == 'sdf'


def _read_sdf_world(text: str, path: Optional[str], uri: str, reading: _Reading,
                    anchor: Optional[str]) -> World:
    from r2d2_sim.sim.sdf_world import read_sdf_world  # it builds this module's World
    return read_sdf_world(text, path, uri, reading, anchor)


# The formats read(), in the order a text given without a file name is tried in.
FORMATS: List[WorldFormat] = [
    WorldFormat('urdf', ('.urdf',), _sniff_urdf, _read_urdf_world),
    WorldFormat('sdf', SDF_SUFFIXES, _sniff_sdf, _read_sdf_world),
    WorldFormat('r2d2_sim world manifest', ('.yaml', '.yml'), _sniff_yaml,
                _read_manifest_world),
]


def _format_of(path: Optional[str], text: str, shown: str) -> WorldFormat:
    if path is not None:
        for world_format in FORMATS:
            if path.lower().endswith(world_format.suffixes):
                return world_format
        raise RefusedError('UNSUPPORTED_FORMAT', f'{shown}: worlds are URDF files, SDF files '
                                                 '(*.sdf, *.world) or r2d2_sim world manifests '
                                                 '(*.world.yaml)')
    if '<!DOCTYPE' in text or '<!ENTITY' in text:
        raise RefusedError('RESOURCE_PARSE_ERROR', 'the resource_string declares a DOCTYPE or '
                                                   'entities, which a world does not need')
    for world_format in FORMATS:
        if world_format.sniff(text):
            return world_format
    root = _xml_root(text)
    raise RefusedError('UNSUPPORTED_FORMAT', f'the resource_string is XML with the root '
                                             f'<{(root or "")[:40]}>: worlds are URDF, SDF or '
                                             'r2d2_sim world manifests')


def read_world(uri: str, resource_string: str, places: Places,
               options: LoadOptions = LoadOptions(), trusted: bool = False,
               sdf: SdfSettings = SdfSettings()) -> World:
    """
    Read and check a world as LoadWorld asks: ``uri`` wins over ``resource_string``.

    ``trusted`` (the ``world`` parameter) may name any file; a request may
    load only from ``places``. Every model file is found and checked (size,
    XML, links, meshes' places) before anything is loaded; ``sdf`` says what
    SDF worlds are searched and compared with. RefusedError with
    LoadWorld's codes: NO_RESOURCE (both empty), NOT_FOUND (no such world, or
    outside the allowed places), UNSUPPORTED_FORMAT, RESOURCE_PARSE_ERROR,
    MISSING_ASSETS, UNSUPPORTED_ASSETS, UNSUPPORTED_ELEMENTS.
    """
    reading = _Reading(places, options, trusted, sdf)
    try:
        if uri:
            path, root = places.resolve(uri)
            shown = uri[:200]
            if not trusted and not places.allowed(path, root):
                raise RefusedError('NOT_FOUND', f'{shown} lies outside the places worlds are '
                                                'loaded from (this package\'s urdf/, world_paths, '
                                                'pybullet_data, ROS packages)')
            if not os.path.isfile(path):
                raise RefusedError('NOT_FOUND', f'{shown}: no such world file')
            world_format = _format_of(path, '', shown)
            text = _read_text(path, shown, 'NOT_FOUND', MAX_WORLD_BYTES)
            anchor = root or os.path.dirname(os.path.realpath(path))
            try:
                world = world_format.read(text, path, uri, reading, anchor)
            except RefusedError as exc:
                raise RefusedError(exc.code, f'{shown}: {exc.message}') from None
        elif resource_string:
            if len(resource_string.encode('utf-8', errors='replace')) > MAX_WORLD_BYTES:
                raise RefusedError('RESOURCE_PARSE_ERROR', f'the resource_string is larger than '
                                                           f'{MAX_WORLD_BYTES} bytes')
            world_format = _format_of(None, resource_string, 'the resource_string')
            world = world_format.read(resource_string, None, '', reading, None)
        else:
            raise RefusedError('NO_RESOURCE', 'neither a uri nor a resource_string was given')
    except BaseException:
        for resource in reading.resources:
            resource.close()
        raise
    return world._replace(notes=tuple(reading.notes), resources=tuple(reading.resources))


def _is_remote(source: str) -> bool:
    return bool(_SCHEME.match(source)) and not source.startswith((FILE_SCHEME, PACKAGE_SCHEME))


def _scan(places: Places, source: str) -> List[WorldEntry]:
    """
    Return the worlds of one source: its ``*.world.yaml`` files, read and checked.

    Its ``*.sdf`` and ``*.world`` files too, those that hold a ``<world>``
    (model files are left out): named by the world, tagged ``sdf``.
    """
    directory = places.directory(source)[0]
    try:
        names = sorted(n for n in os.listdir(directory)
                       if n.endswith(WORLD_SUFFIX) or n.lower().endswith(SDF_SUFFIXES))
    except OSError:
        raise RefusedError('NOT_FOUND', f'{source[:200]} cannot be listed') from None
    prefix = source.rstrip('/') if source.startswith(PACKAGE_SCHEME) else \
        FILE_SCHEME + directory
    entries = []
    for name in names[:MAX_WORLDS_PER_SOURCE]:
        shown = f'{source[:200].rstrip("/")}/{name}'
        path = os.path.join(directory, name)
        if not os.path.isfile(path):
            continue
        try:
            text = _read_text(path, shown, 'NOT_FOUND', MAX_WORLD_BYTES)
            if not name.endswith(WORLD_SUFFIX):
                from r2d2_sim.sim.sdf_world import sdf_world_entry
                world = sdf_world_entry(text, shown)
                if world is not None:
                    entries.append(WorldEntry(world or _stem(name), f'{prefix}/{name}',
                                              'SDF world', ('sdf',)))
                continue
            manifest = read_manifest(load_yaml(text), _stem(name))
        except RefusedError as exc:
            raise RefusedError(exc.code, f'{shown}: {exc.message}') from None
        entries.append(WorldEntry(manifest.name, f'{prefix}/{name}', manifest.description,
                                  manifest.tags))
    return entries


def list_worlds(places: Places, additional_sources: Sequence[str] = (),
                tags: TagsFilter = TagsFilter(), offline_only: bool = False,
                continue_on_error: bool = False) -> Tuple[List[WorldEntry], str]:
    """
    Return GetAvailableWorlds' worlds (tags filtered) and a note of what was left out.

    The default sources are this package's ``urdf/`` and the ``world_paths``;
    ``additional_sources`` are directories (paths, ``file://``,
    ``package://``) within the places a request may load from. Every source
    is local, so ``offline_only`` only leaves out remote sources, which are
    never searched. A source that fails fails the call, with
    DEFAULT_SOURCES_FAILED for a default one, NOT_FOUND (or
    FEATURE_UNSUPPORTED, remote) for an additional one; with
    ``continue_on_error`` it is left out instead (named in the note), and the
    call fails only when no source yielded any world. A world file that does
    not read fails its source (OPERATION_FAILED for an additional one).
    """
    sources = [(PACKAGE_WORLDS, True)] + [(s, True) for s in places.world_paths] + \
        [(s, False) for s in additional_sources]
    worlds: List[WorldEntry] = []
    failures: List[Tuple[bool, RefusedError]] = []
    skipped = []
    yielded = False
    for source, default in sources:
        try:
            if _is_remote(source):
                if offline_only:
                    skipped.append(source[:200])
                    continue
                raise RefusedError('FEATURE_UNSUPPORTED', f'{source[:200]}: remote sources are '
                                                          'not searched, only local directories')
            if not default and not places.allowed(*places.directory(source)):
                raise RefusedError('NOT_FOUND', f'{source[:200]} lies outside the places worlds '
                                                'are loaded from')
            found = _scan(places, source)
        except RefusedError as exc:
            if default:
                exc = RefusedError('DEFAULT_SOURCES_FAILED', exc.message)
            elif exc.code not in ('NOT_FOUND', 'FEATURE_UNSUPPORTED'):
                exc = RefusedError('OPERATION_FAILED', exc.message)  # a world file in it
            if not continue_on_error:
                raise exc from None
            failures.append((default, exc))
            continue
        yielded = yielded or bool(found)
        worlds += [world for world in found if tags_match(world.tags, tags)]
    if failures and not yielded:
        default, first = next((f for f in failures if f[0]), failures[0])
        raise RefusedError(first.code, '; '.join(f.message for _, f in failures))
    notes = [f'left out: {exc.message}' for _, exc in failures]
    if skipped:
        notes.append(f'remote sources not searched (offline_only): {", ".join(skipped)}')
    return worlds, '; '.join(notes)
