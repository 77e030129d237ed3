"""
Reading a world as the simulation standard asks: :func:`read_world`, one function for every format.

No ROS, no PyBullet. A :class:`~r2d2_sim.sim.worlds.world.World` is what the
``world`` parameter or a LoadWorld request names. Three formats are read,
and a new format joins by adding a :class:`WorldFormat` to :data:`FORMATS`:
a URDF (the whole world is that one model, as ``urdf/room.urdf``),
r2d2_sim's world manifest (:mod:`~r2d2_sim.sim.worlds.manifest`,
``*.world.yaml``) and SDF, Gazebo's worlds and models
(:mod:`~r2d2_sim.sim.worlds.sdf_format`, ``*.sdf``, ``*.world``), whose
models a manifest may list too.

A request may load worlds only from allowed places
(:class:`~r2d2_sim.sim.worlds.places.Places`): this package's ``urdf/``, the
directories of the ``world_paths`` parameter, pybullet_data, and any ROS
package's share directory through ``package://`` (an SDF world's includes
and meshes the model search paths and the Fuel cache too). The ``world``
parameter is the operator's own and may name any file. Every refusal is a
:class:`~r2d2_sim.errors.RefusedError` with LoadWorld's code and a one-line
message that names files, never their contents.
"""

import os
from typing import Callable, Dict, List, NamedTuple, Optional, Sequence, Tuple, TypeVar
import xml.etree.ElementTree as ElementTree

from r2d2_sim.errors import RefusedError
from r2d2_sim.physics.description import check_mesh_files, DescriptionError, DescriptionFile
from r2d2_sim.sim.sdf.elements import root_tag
from r2d2_sim.sim.sdf.loading import scene_meshes, SdfSettings, TriangleBudget
from r2d2_sim.sim.worlds.sdf_format import read_sdf_model, read_sdf_world, sdf_models
from r2d2_sim.sim.spawnables import (
    check_tree, Closable, convert_meshes, MAX_DESCRIPTION_BYTES, MeshUse, read_description)
from r2d2_sim.sim.worlds.manifest import (
    load_yaml, MAX_WORLD_BYTES, ModelEntry, read_manifest)
from r2d2_sim.sim.worlds.world import World, WorldModel
from r2d2_sim.sim.worlds.places import (
    file_stem, PACKAGE_WORLDS, Places, read_text, SDF_SUFFIXES)

__all__ = ['LoadOptions', 'WorldFormat', 'FORMATS', 'read_world', 'empty_world',
           'EMPTY_WORLD_URI']

EMPTY_WORLD_URI = f'{PACKAGE_WORLDS}/empty.world.yaml'
T = TypeVar('T')
# A URDF's top-level elements PyBullet reads; others (gazebo, transmission...) it ignores.
URDF_ELEMENTS = ('link', 'joint', 'material')


class LoadOptions(NamedTuple):
    """LoadWorld's two flags, as the standard defines them (both default to False)."""

    fail_on_unsupported_element: bool = False
    ignore_missing_or_unsupported_assets: bool = False


def empty_world() -> World:
    """Return the empty world: no models, no named poses (what ``world`` '' loads)."""
    return World('empty', EMPTY_WORLD_URI, '', 'The ground plane and the robots, nothing else.',
                 ('empty',), (), (), None)


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
        self.resources: List[Closable] = []
        # The mesh triangles of all its models together, URDF and SDF, each use counted.
        self.triangles = TriangleBudget()

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
        counts: Dict[str, int] = {}
        for place in where:
            counts[place] = counts.get(place, 0) + 1
        places = [f'{count} at {place}' for place, count in counts.items()]
        listed = f'{what}: ' + ', '.join(places[:10]) + (' ...' if len(places) > 10 else '')
        if self.options.fail_on_unsupported_element:
            raise RefusedError('UNSUPPORTED_ELEMENTS', listed)
        self.notes.append(f'ignored: {listed}')

    def urdf(self, text: str, path: Optional[str], shown: str
             ) -> Tuple[str, List[MeshUse]]:
        """
        Check a URDF's text; return its robot name and its meshes, none converted yet.

        ``path``: its file (None for text). The world's own codes on refusal;
        a trusted world's meshes may lie anywhere and are not converted
        (PyBullet reads them as they are), but each must be a regular file
        (PyBullet crashed on a directory, and waited for ever on a FIFO).
        """
        base_dir = os.path.dirname(path) if path else None
        meshes: List[MeshUse] = []
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
            check_tree(root, shown)
            try:
                check_mesh_files(root, path, shown)
            except DescriptionError as exc:
                raise RefusedError('UNSUPPORTED_ASSETS', str(exc)) from None
        else:
            name, meshes = read_description(text, base_dir, shown)  # size, DOCTYPE, links, meshes
            root = ElementTree.fromstring(text)
        self.unsupported([shown for child in root if child.tag not in URDF_ELEMENTS],
                         'elements PyBullet does not read')
        return (root.get('name', '') if self.trusted else name), meshes

    def convert(self, meshes: Sequence[MeshUse]) -> None:
        """Convert a URDF's meshes: the world's triangles counted from the files first."""
        self.triangles.expect([mesh.path for mesh in meshes], '')
        convert_meshes(meshes, self.triangles)

    def model(self, entry: ModelEntry, base_dir: Optional[str], anchor: Optional[str]) -> '_Model':
        """
        Return a manifest's model, its file found, read and checked, its meshes not converted.

        A URDF is one model; an SDF file is the bodies of its models (several
        when no joint joins them), at the entry's pose, named after the entry.
        A model that cannot be had, now or when built, is left out (noted)
        when the request allows it.
        """
        try:
            return self._model(entry, base_dir, anchor)
        except RefusedError as exc:
            self._left_out(exc)
            return _Model((), list)

    def _model(self, entry: ModelEntry, base_dir: Optional[str], anchor: Optional[str]
               ) -> '_Model':
        path, root = self.places.resolve(entry.uri, base_dir)
        shown = entry.uri[:200]
        if not self.trusted and not self.places.allowed(path, anchor, root):
            raise RefusedError('UNSUPPORTED_ASSETS', f'model {shown} lies outside the places '
                                                     'worlds are loaded from')
        if not os.path.isfile(path):
            raise RefusedError('MISSING_ASSETS', f'model {shown}: no such file')
        if path.lower().endswith(SDF_SUFFIXES):
            read = _as_asset(lambda: read_sdf_model(entry, path, self,
                                                    anchor or os.path.dirname(path)))
            return _Model(tuple(scene_meshes(read.scene)), lambda: self._built(
                lambda: _as_asset(lambda: sdf_models(entry, read, self))))
        if not path.lower().endswith('.urdf'):
            raise RefusedError('UNSUPPORTED_ASSETS', f'model {shown}: only URDF and SDF '
                                                     'models are loaded')
        text = read_text(path, f'model {shown}', 'MISSING_ASSETS', MAX_DESCRIPTION_BYTES)
        _, meshes = _as_asset(lambda: self.urdf(text, path, f'model {shown}'), shown)
        model = WorldModel(entry.name, path, entry.uri, entry.position, entry.orientation,
                           entry.description or entry.uri, entry.tags)

        def build() -> List[WorldModel]:
            _as_asset(lambda: self.convert(meshes), shown)
            return [model]
        return _Model(tuple(mesh.path for mesh in meshes), lambda: self._built(build))

    def _built(self, build: Callable[[], List[WorldModel]]) -> List[WorldModel]:
        """Return a model's bodies, its meshes converted; none when it is left out."""
        try:
            return build()
        except RefusedError as exc:
            self._left_out(exc)
            return []

    def _left_out(self, exc: RefusedError) -> None:
        """Note a model that cannot be had as left out, if the request allows; else refuse."""
        if (self.options.ignore_missing_or_unsupported_assets
                and exc.code in ('MISSING_ASSETS', 'UNSUPPORTED_ASSETS', 'NOT_FOUND')):
            self.notes.append(f'left out: {exc.message}')
            return
        if exc.code == 'NOT_FOUND':
            raise RefusedError('MISSING_ASSETS', exc.message) from None
        raise exc


class _Model(NamedTuple):
    """A manifest's model read and checked; ``build()`` converts its meshes: its bodies."""

    meshes: Tuple[str, ...]   # the mesh file of every use of a mesh
    build: Callable[[], List[WorldModel]]


def _as_asset(call: Callable[[], T], urdf: Optional[str] = None) -> T:
    """
    Return ``call()``, a refusal made a manifest's model's: the world's asset is at fault.

    ``urdf``: the model is that URDF, named in front of the message.
    """
    try:
        return call()
    except RefusedError as exc:
        if urdf is not None:
            code = {'UNSUPPORTED_FORMAT': 'UNSUPPORTED_ASSETS',
                    'NO_RESOURCE': 'MISSING_ASSETS'}.get(exc.code, exc.code)
            named = exc.message.startswith(f'model {urdf}: ')  # self.urdf names it already
            raise RefusedError(code, exc.message if named else f'model {urdf}: {exc.message}'
                               ) from None
        if exc.code != 'UNSUPPORTED_FORMAT':
            raise
        raise RefusedError('UNSUPPORTED_ASSETS', exc.message) from None


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
    return root_tag(text) or None  # a linear scan: no pattern that backtracks over comments


def _read_urdf_world(text: str, path: Optional[str], uri: str, reading: _Reading,
                     anchor: Optional[str]) -> World:
    shown = uri[:200] if uri else 'the resource_string'
    name, meshes = reading.urdf(text, path, shown)
    reading.convert(meshes)
    given_as = None
    if path is None:
        description = DescriptionFile(text)
        reading.resources.append(description)
        path, given_as = description.path, 'the resource_string'
    model = WorldModel(None, path, uri or 'resource_string', (0.0, 0.0, 0.0),
                       (0.0, 0.0, 0.0, 1.0), uri or 'resource_string', (), given_as=given_as)
    return World(name or (file_stem(path) if uri else 'world'), uri, '' if uri else text, '', (),
                 (model,), (), None)


def _read_manifest_world(text: str, path: Optional[str], uri: str, reading: _Reading,
                         anchor: Optional[str]) -> World:
    data = load_yaml(text)
    manifest = read_manifest(data, file_stem(path) if path else 'world')
    reading.unsupported(list(manifest.ignored), 'unknown keys')
    base_dir = os.path.dirname(path) if path else None
    read = [reading.model(entry, base_dir, anchor) for entry in manifest.models]
    if not reading.options.ignore_missing_or_unsupported_assets:  # else each model on its own
        reading.triangles.expect([mesh for model in read for mesh in model.meshes], '')
    models: List[WorldModel] = []
    for entry in read:
        for model in entry.build():
            # two files' "crate" (an SDF model always has its name)
            if model.sdf and model.name is not None and model.name in {m.name for m in models}:
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
                                                'pybullet_data, ROS packages): add its directory '
                                                'to the world_paths parameter')
            if not os.path.isfile(path):
                raise RefusedError('NOT_FOUND', f'{shown}: no such world file')
            world_format = _format_of(path, '', shown)
            text = read_text(path, shown, 'NOT_FOUND', MAX_WORLD_BYTES)
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
