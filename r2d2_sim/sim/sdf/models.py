"""
One SDF ``<model>``: read into a tree of its frames and parts, then flattened with poses resolved.

No ROS, no PyBullet. :func:`read_model` reads a model element (its links,
joints, frames, nested models and includes, through the reader that owns the
files) into a :class:`ModelTree` whose :class:`~r2d2_sim.model.sdf_poses.PoseGraph`
knows every frame of its scope; :func:`flatten` then resolves every pose into
the top-level model's frame and gives a
:class:`~r2d2_sim.sim.sdf.description.Model`: scoped link and joint names
(``nested::link``), shapes in their link's frame, joint axes in the model's
frame whichever frame the file's SDF version expresses them in.
"""

import dataclasses
import math
from typing import List, Optional, Protocol, Tuple
import xml.etree.ElementTree as ElementTree

from r2d2_sim.model.sdf_poses import FrameError, PoseGraph, SCOPE_SEPARATOR
from r2d2_sim.model.transforms import compose, inverse, rotate, Transform, Vector3
from r2d2_sim.sim.sdf.description import Joint, Link, Model, Shape
from r2d2_sim.sim.sdf.elements import FileNotes, local_tag, Place
from r2d2_sim.sim.sdf.parts import (
    AxisSpec, JointSpec, LinkSpec, QUIET, read_joint, read_link, ShapeSpec)

__all__ = ['ModelTree', 'Origin', 'read_model', 'place_model', 'flatten', 'MODEL_FRAME',
           'MAX_LINKS_PER_MODEL']

MODEL_FRAME = '__model__'
# Links of one top-level model, nested ones included (PyBullet's URDF limit is far above).
MAX_LINKS_PER_MODEL = 1000
# Models in models (a Gazebo world nests two or three deep).
MAX_NESTING = 32


@dataclasses.dataclass
class Origin:
    """The file a model was read from: as shown, its directory, the SDF version."""

    shown: str
    directory: Optional[str]   # where relative URIs start (None: text from a request)
    model_dir: Optional[str]   # the model's own directory (model://<its name>/... within)
    version: Tuple[int, int]


@dataclasses.dataclass
class ModelTree:
    """A model as read, nested models inside: its frames (``graph``), parts and placement."""

    name: str
    static: bool
    pose: Transform
    relative_to: str
    placement: str
    graph: PoseGraph
    links: List[LinkSpec]
    joints: List[JointSpec]
    nested: List['ModelTree']
    canonical: str
    origin: Origin
    where: str


def _add(graph: PoseGraph, place: Place, name: str, relative_to: str, pose: Transform,
         scope: Optional[PoseGraph] = None) -> None:
    try:
        graph.add(name, relative_to, pose, scope)
    except FrameError as exc:
        raise place.fail(str(exc)) from None


def place_model(graph: PoseGraph, tree: ModelTree, place: Place) -> None:
    """Add a (nested or top-level) model's frame to its parent scope, by its placement frame."""
    pose = tree.pose
    if tree.placement:
        try:
            pose = compose(pose, inverse(tree.graph.pose(tree.placement)))
        except FrameError as exc:
            raise place.fail(f'placement_frame: {exc}') from None
    _add(graph, place, tree.name, tree.relative_to, pose, tree.graph)


class ModelReader(Protocol):
    """What reading a model asks of the reader of its files (:class:`~.reader.Reader`)."""

    def notes_for(self, origin: Origin) -> FileNotes:
        """Return what the parts of ``origin``'s file report to."""

    def include(self, element: ElementTree.Element, place: Place, origin: Origin,
                depth: int, nesting: int = 0) -> Optional[ModelTree]:
        """Return the model an <include> brings (its overrides applied); None for a light."""

    def note(self, what: str) -> None:
        """Count one element that is not simulated, by what it is."""

    def count_model(self, place: Place) -> None:
        """Count one model against the world's limit."""


def model_name(place: Place, name: str, tag: str) -> str:
    """
    Return a model's name (from ``<model name>`` or ``<include><name>``) once checked.

    It becomes a PyBullet body name: 1 to 255 characters and no ``::``, as an entity's
    name; PyBullet's getBodyInfo overflows (SIGSEGV) on a name of about 1,024.
    """
    if not name or len(name) > 255:
        raise place.fail(f'a <{tag}> needs a name of 1 to 255 characters')
    if SCOPE_SEPARATOR in name:
        raise place.fail(f'a model\'s name cannot hold {SCOPE_SEPARATOR}')
    return name


def read_model(element: ElementTree.Element, place: Place, origin: Origin, reader: ModelReader,
               depth: int, nesting: int = 0) -> ModelTree:
    """
    Return a <model> read into a tree; ``reader`` reads includes and counts what it skips.

    ``depth`` is how deeply includes nest here (the reader refuses too deep),
    ``nesting`` how deeply models do (at most MAX_NESTING, includes counted).
    """
    reader.count_model(place)
    at = place.child(element)
    if nesting > MAX_NESTING:
        raise at.fail(f'models nest deeper than {MAX_NESTING}')
    name = model_name(place, element.get('name', ''), 'model')
    pose, relative_to = at.pose(element)
    graph = PoseGraph(MODEL_FRAME)
    tree = ModelTree(name, at.truth(element, 'static', False), pose, relative_to,
                     element.get('placement_frame', ''), graph, [], [], [], '', origin,
                     ', '.join(at.path))
    notes = reader.notes_for(origin)
    for child in element:
        tag = local_tag(child)
        if tag == 'link':
            link = read_link(child, at, notes)
            _add(graph, at, link.name, link.relative_to, link.pose)
            tree.links.append(link)
        elif tag == 'joint':
            joint = read_joint(child, at, notes)
            _add(graph, at, joint.name, joint.relative_to or joint.child, joint.pose)
            tree.joints.append(joint)
        elif tag in ('model', 'include'):
            nested = (read_model(child, at, origin, reader, depth, nesting + 1) if tag == 'model'
                      else reader.include(child, at, origin, depth + 1, nesting + 1))
            if nested is not None:
                place_model(graph, nested, at)
                tree.nested.append(nested)
        elif tag == 'frame':
            within = at.child(child)
            frame_pose, frame_relative = within.pose(child)
            _add(graph, within, at.name(child), frame_relative or child.get('attached_to', ''),
                 frame_pose)
        elif tag and tag not in QUIET:
            reader.note(tag)
    tree.canonical = element.get('canonical_link', '') or (
        tree.links[0].name if tree.links else
        f'{tree.nested[0].name}{SCOPE_SEPARATOR}{tree.nested[0].canonical}' if tree.nested
        else '')
    return tree


def _unit(vector: Vector3, where: str) -> Vector3:
    norm = math.sqrt(sum(v * v for v in vector))
    x, y, z = vector
    return x / norm, y / norm, z / norm


class _Flattening:
    """The links and joints of one top-level model, gathered through its nested models."""

    def __init__(self) -> None:
        self.links: List[Link] = []
        self.joints: List[Joint] = []

    def add(self, tree: ModelTree, frame: Transform, prefix: str, static: bool) -> None:
        """Add ``tree``'s parts, its frame at ``frame`` in the top model's, names ``prefix``ed."""
        graph, static = tree.graph, static or tree.static
        place = Place(tree.origin.shown, (tree.where,))
        try:
            for spec in tree.links:
                link_pose = compose(frame, graph.pose(spec.name))
                self.links.append(Link(
                    prefix + spec.name, link_pose, static, spec.inertial,
                    tuple(self._shape(s, graph, spec.name) for s in spec.collisions),
                    tuple(self._shape(s, graph, spec.name) for s in spec.visuals)))
            for joint in tree.joints:
                self.joints.append(self._joint(joint, tree, frame, prefix))
            for nested in tree.nested:
                self.add(nested, compose(frame, graph.pose(nested.name)),
                         f'{prefix}{nested.name}{SCOPE_SEPARATOR}', static)
        except FrameError as exc:
            raise place.fail(str(exc)) from None
        if len(self.links) > MAX_LINKS_PER_MODEL:
            raise place.fail(f'a model has more than {MAX_LINKS_PER_MODEL} links, nested '
                             'models included')

    @staticmethod
    def _shape(spec: ShapeSpec, graph: PoseGraph, link: str) -> Shape:
        if not spec.relative_to or spec.relative_to == link:
            return spec.shape
        pose = compose(inverse(graph.pose(link)), compose(graph.pose(spec.relative_to),
                                                          spec.shape.pose))
        return spec.shape._replace(pose=pose)

    @staticmethod
    def _joint(spec: JointSpec, tree: ModelTree, frame: Transform, prefix: str) -> Joint:
        graph = tree.graph
        for end in (spec.parent, spec.child):
            if end != 'world' and end not in graph:
                raise FrameError(f'joint {spec.name[:100]}: {end[:100]!r} names no link of the '
                                 'model')
        joint_pose = graph.pose(spec.name)
        version = tree.origin.version

        def direction(axis: AxisSpec) -> Vector3:
            if version >= (1, 7):
                name = axis.expressed_in or spec.name
            elif version >= (1, 5):
                name = MODEL_FRAME if axis.use_parent_model_frame else spec.name
            else:
                name = MODEL_FRAME  # SDF 1.4: the axis is in the model's frame
            rotation = compose(frame, graph.pose(name)).rotation
            return _unit(rotate(rotation, axis.xyz), spec.where)

        def scoped(link: str) -> str:
            return link if link == 'world' else prefix + link
        return Joint(prefix + spec.name, spec.kind, scoped(spec.parent), scoped(spec.child),
                     compose(frame, joint_pose), direction(spec.axis), spec.axis.limits,
                     direction(spec.axis2), spec.axis2.limits)


def flatten(tree: ModelTree, pose: Transform) -> Model:
    """Return a top-level model at ``pose`` in the world, nested models flattened into it."""
    gathered = _Flattening()
    gathered.add(tree, Transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)), '', False)
    names = {link.name for link in gathered.links}
    place = Place(tree.origin.shown, (tree.where,))
    for joint in gathered.joints:
        for end in (joint.parent, joint.child):
            if end != 'world' and end not in names:
                raise place.fail(f'joint {joint.name[:100]}: {end[:100]!r} names no link of '
                                 'the model')
    canonical = tree.canonical if tree.canonical in names else (
        gathered.links[0].name if gathered.links else '')
    if tree.canonical and tree.canonical not in names:
        raise place.fail(f'canonical_link {tree.canonical[:100]!r} names no link of the model')
    return Model(tree.name, pose, tree.static, tuple(gathered.links), tuple(gathered.joints),
                 canonical, tree.origin.shown)
