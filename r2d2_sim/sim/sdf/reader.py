"""
Reading an SDF world or model file, its includes followed, into a :class:`~.description.Scene`.

No ROS, no PyBullet. A :class:`Reader` owns one load: the
:class:`~r2d2_sim.sim.sdf.resources.Resources` its files come from, the
:class:`~r2d2_sim.sim.sdf.elements.Budget` they count against, and what was
not simulated (counted by what it is, for one summary line) or left out.
``<include>`` is followed through ``model://``, Fuel's cache, packages and
paths, nested up to 16 deep; world-level ``<frame>`` elements become named
frames; ``<physics>`` and ``<gravity>`` are compared with r2d2_sim's and
noted when they differ. SDF 1.4 to 1.11 are read (newer versions as 1.11).
"""

import os
from typing import Dict, List, NamedTuple, Optional, Tuple
import xml.etree.ElementTree as ElementTree

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.sdf_poses import FrameError, PoseGraph
from r2d2_sim.model.transforms import Vector3
from r2d2_sim.sim.sdf.description import NamedFrame, Scene
from r2d2_sim.sim.sdf.elements import (
    Budget, local_tag, MAX_INCLUDE_DEPTH, parse_xml, PARSE, Place, read_limited)
from r2d2_sim.sim.sdf.models import flatten, model_name, ModelTree, Origin, place_model, read_model
from r2d2_sim.sim.sdf.parts import QUIET
from r2d2_sim.sim.sdf.resources import Resources

__all__ = ['Reader', 'ReadOptions', 'MAX_SDF_BYTES', 'MAX_MODELS', 'OLDEST_VERSION',
           'NEWEST_VERSION']

# One file's size: as a world manifest's.
MAX_SDF_BYTES = 1_000_000
MAX_MODELS = 1000
OLDEST_VERSION = (1, 4)
NEWEST_VERSION = (1, 11)
ASSET_CODES = ('MISSING_ASSETS', 'UNSUPPORTED_ASSETS')
# What a world holds beside models and frames, all of it shown, none simulated.
_WORLD_READ = ('model', 'include', 'frame', 'physics', 'gravity')
_PHYSICS_QUIET = ('max_step_size', 'real_time_factor', 'real_time_update_rate', 'max_contacts',
                  'gravity', 'magnetic_field')


def _relative_to_from_frame(root: ElementTree.Element, version: Tuple[int, int]) -> None:
    """
    Make SDF 1.5-1.6's ``<pose frame="f">`` ``relative_to="f"``, as SDF 1.7 renamed it.

    As sdformat converts a file older than 1.7 (``sdf/1.7/1_6.convert``
    moves the attribute as it is): an empty ``frame`` becomes an empty
    ``relative_to``, which means the default frame, as no attribute does.
    """
    if version >= (1, 7):
        return
    for element in root.iter():
        if local_tag(element) == 'pose' and 'frame' in element.attrib:
            element.set('relative_to', element.attrib.pop('frame'))


class ReadOptions(NamedTuple):
    """
    How to read: r2d2_sim's physics step (s) and gravity to compare the world's with.

    ``ignore_missing``: leave out what is missing or unsupported (noted)
    instead of refusing, as LoadWorld's ``ignore_missing_or_unsupported_assets``.
    """

    time_step_s: Optional[float] = None
    gravity_m_s2: Optional[Vector3] = None
    ignore_missing: bool = False


class _Notes:
    """What parts of one file tell the reader: what they skip, which meshes they need."""

    def __init__(self, reader: 'Reader', origin: Origin) -> None:
        self._reader = reader
        self._origin = origin

    def note(self, what: str) -> None:
        self._reader.note(what)

    def mesh(self, uri: str, place: Place) -> Optional[str]:
        """Return a mesh's path; None (noted as left out) when missing and that is allowed."""
        origin = self._origin
        try:
            return self._reader.resources.file(uri, origin.directory, 'mesh', origin.model_dir)
        except RefusedError as exc:
            self._reader.missing(exc, place)
            return None


class Reader:
    """One load of SDF: its files, includes, budget, and what it did not simulate."""

    def __init__(self, resources: Resources, options: ReadOptions = ReadOptions()) -> None:
        self.resources = resources
        self.options = options
        self.budget = Budget()
        self.counts: Dict[str, int] = {}
        self.left_out: List[str] = []
        self._models_left = MAX_MODELS
        # Included files by path, read and parsed once (each use still counts its elements).
        self._files: Dict[str, Tuple[ElementTree.Element, Tuple[int, int]]] = {}

    # -- what parts tell the reader ------------------------------------------------------

    def note(self, what: str) -> None:
        """Count one element that is not simulated, by what it is."""
        self.counts[what] = self.counts.get(what, 0) + 1

    def notes_for(self, origin: Origin) -> _Notes:
        """Return what the parts of ``origin``'s file report to."""
        return _Notes(self, origin)

    def missing(self, exc: RefusedError, place: Place) -> None:
        """Leave a missing or unsupported asset out (noted) if allowed; else refuse, placed."""
        if self.options.ignore_missing and exc.code in ASSET_CODES:
            self.left_out.append(f'{place}: {exc.message}')
            return None
        raise RefusedError(exc.code, f'{place}: {exc.message}') from None

    def count_model(self, place: Place) -> None:
        """Count one model against MAX_MODELS."""
        self._models_left -= 1
        if self._models_left < 0:
            raise place.fail(f'the world has more than {MAX_MODELS} models, nested and '
                             'included ones counted')

    # -- files ----------------------------------------------------------------------------

    def _root(self, text: str, shown: str) -> Tuple[ElementTree.Element, Tuple[int, int]]:
        """Return a file's <sdf> element and version; UNSUPPORTED_FORMAT if it is not SDF."""
        root = parse_xml(text, shown)
        self.budget.take(root, shown)
        version = self._version(root, shown)
        _relative_to_from_frame(root, version)
        return root, version

    @staticmethod
    def _version(root: ElementTree.Element, shown: str) -> Tuple[int, int]:
        """Return an <sdf> element's version (newer than 1.11 read as 1.11)."""
        if local_tag(root) != 'sdf':
            raise RefusedError('UNSUPPORTED_FORMAT', f'{shown}: the root element is '
                                                     f'<{local_tag(root)[:40]}>, not <sdf>')
        try:
            version = tuple(int(v) for v in root.get('version', '').split('.'))[:2]
        except ValueError:
            version = ()
        if len(version) != 2 or version < OLDEST_VERSION:
            raise RefusedError('UNSUPPORTED_FORMAT', f'{shown}: SDF version '
                                                     f'{root.get("version", "")[:20]!r}: '
                                                     'r2d2_sim reads SDF 1.4 to 1.11')
        return min(version, NEWEST_VERSION)

    def read(self, text: str, path: Optional[str], shown: str) -> Scene:
        """
        Return what an SDF file describes: its world (or its models) with includes followed.

        ``path`` is None for text sent in a request (relative URIs then have
        nothing to be relative to). RefusedError with LoadWorld's codes.
        """
        root, version = self._root(text, shown)
        directory = os.path.dirname(path) if path else None
        origin = Origin(shown, directory, directory, version)
        place = Place(shown)
        worlds = [child for child in root if local_tag(child) == 'world']
        if worlds:
            for _ in worlds[1:]:
                self.note('second world')
            return self._world(worlds[0], place, origin)
        graph = PoseGraph('world')
        trees = []
        for child in root:
            tag = local_tag(child)
            if tag == 'model':
                tree = read_model(child, place, origin, self, 0)
                place_model(graph, tree, place)
                trees.append(tree)
            elif tag:
                self.note(tag)
        if not trees:
            raise place.fail('it holds no <world> and no <model>')
        return self._scene('', graph, trees, [], place)

    def include(self, element: ElementTree.Element, place: Place, origin: Origin,
                depth: int, nesting: int = 0) -> Optional[ModelTree]:
        """Return the model an <include> brings (its overrides applied); None for a light."""
        at = place.child(element)
        if depth > MAX_INCLUDE_DEPTH:
            raise at.fail(f'includes nest deeper than {MAX_INCLUDE_DEPTH} (does a model include '
                          'itself?)')
        uri = at.text(element, 'uri', '')
        if not uri:
            raise at.fail('an <include> needs a <uri>')
        try:
            source = self.resources.model(uri, origin.directory, origin.model_dir)
            key = source.path or source.shown
            if key not in self._files:
                text = source.text
                if text is None:
                    assert source.path is not None  # a model not built in is a file
                    text = read_limited(source.path, source.shown, 'MISSING_ASSETS',
                                        MAX_SDF_BYTES)
                root = parse_xml(text, source.shown)
                version = self._version(root, source.shown)
                _relative_to_from_frame(root, version)
                self._files[key] = (root, version)
        except RefusedError as exc:
            if exc.code == 'UNSUPPORTED_FORMAT':  # the world is SDF; this asset is not
                exc = RefusedError('UNSUPPORTED_ASSETS', exc.message)
            self.missing(exc, at)
            return None
        root, version = self._files[key]
        self.budget.take(root, source.shown)
        content = [child for child in root if local_tag(child) in ('model', 'light', 'actor')]
        if not content:
            raise RefusedError(PARSE, f'{at}: {source.shown} holds no <model>')
        if local_tag(content[0]) != 'model':
            self.note(local_tag(content[0]))
            return None
        included = Origin(source.shown, source.directory, source.directory, version)
        tree = read_model(content[0], Place(source.shown), included, self, depth, nesting)
        if element.get('merge', 'false').strip().lower() in ('true', '1'):
            self.note('merged include (read as a nested model)')
        name = at.text(element, 'name')
        if name:  # an empty <name/> keeps the model's own, as before
            tree.name = model_name(at, name, 'include')
        if element.find('pose') is not None:
            tree.pose, tree.relative_to = at.pose(element)
        tree.static = at.truth(element, 'static', tree.static)
        tree.placement = at.text(element, 'placement_frame') or tree.placement
        tree.where = f'model {tree.name[:100]}'  # in the including file's words
        for child in element:
            tag = local_tag(child)
            if tag not in ('uri', 'name', 'pose', 'static', 'placement_frame') and \
                    tag not in QUIET:
                self.note(tag)
        return tree

    # -- the world ------------------------------------------------------------------------

    def _world(self, world: ElementTree.Element, place: Place, origin: Origin) -> Scene:
        at = place.child(world)
        graph = PoseGraph('world')
        trees: List[ModelTree] = []
        frames: List[str] = []
        for child in world:
            tag = local_tag(child)
            if tag in ('model', 'include'):
                tree = (read_model(child, at, origin, self, 0) if tag == 'model'
                        else self.include(child, at, origin, 1))
                if tree is not None:
                    place_model(graph, tree, at)
                    trees.append(tree)
            elif tag == 'frame':
                within = at.child(child)
                pose, relative_to = within.pose(child)
                name = at.name(child)
                try:
                    graph.add(name, relative_to or child.get('attached_to', ''), pose)
                except FrameError as exc:
                    raise within.fail(str(exc)) from None
                frames.append(name)
            elif tag == 'physics':
                self._physics(child, at.child(child))
            elif tag == 'gravity':
                self._gravity(world, at)
            elif tag and tag not in QUIET:
                self.note(tag)
        return self._scene(world.get('name', ''), graph, trees, frames, at)

    def _physics(self, physics: ElementTree.Element, place: Place) -> None:
        """Note a physics step other than r2d2_sim's, and solver settings it cannot take."""
        step = place.number(physics, 'max_step_size', 0.001, 0.0, 10.0)
        ours = self.options.time_step_s
        if ours is not None and abs(step - ours) > 1e-9:
            self.note(f'physics max_step_size {step:g} s (r2d2_sim steps {ours:.6g} s: '
                      'physics_rate)')
        if physics.find('gravity') is not None:  # SDF 1.4 and 1.5 put it here
            self._gravity(physics, place)
        for child in physics:
            tag = local_tag(child)
            if tag and tag not in _PHYSICS_QUIET and tag not in QUIET:
                self.note(f'physics {tag} settings')

    def _gravity(self, element: ElementTree.Element, place: Place) -> None:
        gravity = place.numbers(element, 'gravity', 3)
        assert gravity is not None  # read only where a <gravity> is
        ours = self.options.gravity_m_s2
        if ours is not None and any(abs(a - b) > 1e-9 for a, b in zip(gravity, ours)):
            shown = ' '.join(f'{v:g}' for v in gravity)
            self.note(f'gravity {shown} (r2d2_sim\'s gravity parameter: '
                      f'{" ".join(f"{v:g}" for v in ours)})')

    def _scene(self, name: str, graph: PoseGraph, trees: List[ModelTree], frames: List[str],
               place: Place) -> Scene:
        try:
            models = tuple(flatten(tree, graph.pose(tree.name)) for tree in trees)
            named = tuple(NamedFrame(frame, graph.pose(frame)) for frame in frames)
        except FrameError as exc:
            raise place.fail(str(exc)) from None
        return Scene(name, models, named, tuple(self.counts.items()), tuple(self.left_out))
