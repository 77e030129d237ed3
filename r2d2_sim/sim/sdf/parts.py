"""
A model's parts as SDF writes them: links (inertia, collisions, visuals, geometry) and joints.

No ROS, no PyBullet. Each function reads one element through a
:class:`~r2d2_sim.sim.sdf.elements.Place` (one-line RESOURCE_PARSE_ERROR
naming file and element for a bad value) and tells ``notes`` (the
:class:`~r2d2_sim.sim.sdf.reader.Reader`) of every element it does not
simulate, and asks it for mesh files. Poses stay as written (with their
``relative_to``): the reader resolves them once the model's frames are known.
"""

import math
from typing import Collection, List, NamedTuple, Optional, Tuple
import xml.etree.ElementTree as ElementTree

from r2d2_sim.model.transforms import Transform, Vector3
from r2d2_sim.physics.description import MAX_INERTIA_KG_M2, MAX_MASS_KG
from r2d2_sim.sim.sdf.description import (
    DEFAULT_INERTIAL, Geometry, Inertial, JOINT_TYPES, JointLimits, Shape)
from r2d2_sim.sim.sdf.elements import FileNotes, local_tag, Notes, Place

__all__ = ['ShapeSpec', 'LinkSpec', 'AxisSpec', 'JointSpec', 'read_link', 'read_joint',
           'QUIET', 'MAX_SIZE_M', 'MAX_SHAPES_PER_LINK']

# Beyond this a length is a typo (the robots' blow-up bound).
MAX_SIZE_M = 10_000.0
MAX_SHAPES_PER_LINK = 1000
# SDF's "no limit": limits at or beyond this are none.
UNLIMITED = 1e15
# Elements that change nothing in a Bullet world seen by a laser and a camera
# (rendering hints, solver hints, Gazebo's own bookkeeping): read past without a note.
QUIET = {'pose', 'name', 'static', 'self_collide', 'allow_auto_disable', 'enable_wind',
         'laser_retro', 'max_contacts', 'cast_shadows', 'transparency', 'meta',
         'visibility_flags', 'must_be_base_link', 'render_order', 'double_sided', 'lighting',
         'specular', 'emissive', 'shader'}
# Gazebo's classic named materials, as the colours they draw.
NAMED_COLOURS = {
    'gazebo/grey': (0.7, 0.7, 0.7, 1.0), 'gazebo/gray': (0.7, 0.7, 0.7, 1.0),
    'gazebo/darkgrey': (0.35, 0.35, 0.35, 1.0), 'gazebo/darkgray': (0.35, 0.35, 0.35, 1.0),
    'gazebo/white': (1.0, 1.0, 1.0, 1.0), 'gazebo/black': (0.05, 0.05, 0.05, 1.0),
    'gazebo/red': (1.0, 0.0, 0.0, 1.0), 'gazebo/green': (0.0, 1.0, 0.0, 1.0),
    'gazebo/blue': (0.0, 0.0, 1.0, 1.0), 'gazebo/yellow': (1.0, 1.0, 0.0, 1.0),
    'gazebo/orange': (1.0, 0.5, 0.0, 1.0), 'gazebo/purple': (1.0, 0.0, 1.0, 1.0),
    'gazebo/turquoise': (0.0, 1.0, 1.0, 1.0), 'gazebo/wood': (0.6, 0.4, 0.2, 1.0),
    'gazebo/woodfloor': (0.6, 0.45, 0.3, 1.0), 'gazebo/bricks': (0.6, 0.3, 0.2, 1.0),
}


class ShapeSpec(NamedTuple):
    """A collision or visual, its pose relative to ``relative_to`` ('' for its link)."""

    shape: Shape
    relative_to: str


class LinkSpec(NamedTuple):
    """A link as written: its pose (relative to ``relative_to``), inertia, shapes."""

    name: str
    pose: Transform
    relative_to: str
    inertial: Inertial
    collisions: Tuple[ShapeSpec, ...]
    visuals: Tuple[ShapeSpec, ...]


class AxisSpec(NamedTuple):
    """
    A joint axis as written: direction, the frame it is in ('': the version's), limits.

    ``use_parent_model_frame``: SDF 1.5-1.6's flag of this axis (``<axis>`` and
    ``<axis2>`` each have their own, as sdformat's 1.6 to 1.7 conversion reads them).
    """

    xyz: Tuple[float, float, float]
    expressed_in: str
    limits: JointLimits
    use_parent_model_frame: bool = False


class JointSpec(NamedTuple):
    """A joint as written: type, parent and child (names in its model), pose, axes."""

    name: str
    kind: str
    parent: str
    child: str
    pose: Transform
    relative_to: str
    axis: AxisSpec
    axis2: AxisSpec
    where: str


_NO_AXIS = AxisSpec((0.0, 0.0, 1.0), '', JointLimits(1.0, -1.0, 0.0, 0.0))


def _others(element: ElementTree.Element, known: Collection[str], notes: Notes) -> None:
    """Tell ``notes`` of every child not in ``known`` nor QUIET (one count per element)."""
    for child in element:
        tag = local_tag(child)
        if tag and tag not in known and tag not in QUIET:
            notes.note(tag)


def _vector3(values: Tuple[float, ...]) -> Vector3:
    """Return the three numbers :meth:`Place.numbers` read with a count of 3."""
    x, y, z = values
    return x, y, z


def _positive(place: Place, element: ElementTree.Element, tag: str,
              default: Optional[float] = None) -> float:
    value = place.number(element, tag, default, 0.0, MAX_SIZE_M)
    if value is None or not value > 0.0:
        raise place.fail(f'<{tag}> must be a positive length of at most {MAX_SIZE_M:g} m')
    return value


def read_geometry(element: ElementTree.Element, place: Place, notes: FileNotes
                  ) -> Optional[Geometry]:
    """Return a ``<geometry>``'s shape; None (noted) for one not simulated or left out."""
    shapes = [child for child in element if local_tag(child)]
    if len(shapes) != 1:
        raise place.fail('a <geometry> holds exactly one shape')
    shape = shapes[0]
    kind, at = local_tag(shape), place.child(shape)
    if kind == 'box':
        size = at.numbers(shape, 'size', 3, (1.0, 1.0, 1.0))
        if not all(0.0 < v <= MAX_SIZE_M for v in size):
            raise at.fail(f'<size> must be 3 positive lengths of at most {MAX_SIZE_M:g} m')
        return Geometry('box', size)
    if kind == 'sphere':
        return Geometry('sphere', (_positive(at, shape, 'radius', 1.0),))
    if kind in ('cylinder', 'capsule'):
        return Geometry(kind, (_positive(at, shape, 'radius', 1.0),
                               _positive(at, shape, 'length', 1.0)))
    if kind == 'plane':
        normal = at.numbers(shape, 'normal', 3, (0.0, 0.0, 1.0))
        norm = math.sqrt(sum(v * v for v in normal))
        if not norm > 0.0:
            raise at.fail('<normal> must not be zero')
        size = at.numbers(shape, 'size', 2, (1.0, 1.0))
        if not all(0.0 < v <= 2 * MAX_SIZE_M for v in size):
            raise at.fail('<size> must be 2 positive lengths')
        return Geometry('plane', tuple(v / norm for v in normal) + size)
    if kind == 'mesh':
        uri = at.text(shape, 'uri', '')
        if not uri:
            raise at.fail('a <mesh> needs a <uri>')
        scale = _vector3(at.numbers(shape, 'scale', 3, (1.0, 1.0, 1.0)))
        if not all(0.0 < abs(v) <= MAX_SIZE_M for v in scale):
            raise at.fail('<scale> must be 3 numbers, none of them 0')
        _others(shape, ('uri', 'scale'), notes)
        path = notes.mesh(uri, at)
        return None if path is None else Geometry('mesh', (), path, scale, uri[:200])
    notes.note(f'{kind} geometry')
    return None


def _colour(material: Optional[ElementTree.Element], place: Place, notes: Notes
            ) -> Optional[Tuple[float, float, float, float]]:
    """Return a visual's colour: <diffuse>, else <ambient>, else a named Gazebo material."""
    if material is None:
        return None
    at = place.child(material)
    _others(material, ('diffuse', 'ambient', 'script', 'pbr'), notes)
    for tag in ('diffuse', 'ambient'):
        text = at.text(material, tag)
        if text is None:
            continue
        count = len(text.split())
        values = at.numbers(material, tag, 4 if count == 4 else 3)
        assert values is not None  # the element is there: its text was read above
        red, green, blue, *alpha = (min(1.0, max(0.0, v)) for v in values)
        return red, green, blue, alpha[0] if alpha else 1.0
    script = material.find('script')
    if script is not None:
        name = (at.text(script, 'name', '') or '').lower()
        return NAMED_COLOURS.get(name)
    return None


def _surface(element: Optional[ElementTree.Element], place: Place, notes: Notes
             ) -> Tuple[Optional[float], Optional[float]]:
    """Return a collision's (friction, restitution) where its <surface> gives them."""
    if element is None:
        return None, None
    at = place.child(element)
    friction = restitution = None
    rubbing = element.find('friction')
    if rubbing is not None:
        for path in ('ode', 'bullet'):
            engine = rubbing.find(path)
            if engine is not None and friction is None:
                friction = at.child(rubbing).child(engine).number(
                    engine, 'mu' if path == 'ode' else 'friction', None, 0.0, 1e6)
    bounce = element.find('bounce')
    if bounce is not None:
        restitution = at.child(bounce).number(bounce, 'restitution_coefficient', None, 0.0, 1.0)
    contact = element.find('contact')
    if contact is not None and any(local_tag(c) for c in contact.iter() if c is not contact
                                   and (c.text or '').strip()):
        notes.note('surface contact settings')  # stiffness, bitmasks: Bullet's own apply
    _others(element, ('friction', 'bounce', 'contact'), notes)
    return friction, restitution


def _shape(element: ElementTree.Element, place: Place, notes: FileNotes, visual: bool
           ) -> Optional[ShapeSpec]:
    """Return a <collision> or <visual>; None when its geometry is not simulated."""
    at = place.child(element)
    geometry_element = element.find('geometry')
    if geometry_element is None:
        raise at.fail('it needs a <geometry>')
    pose, relative_to = at.pose(element)
    geometry = read_geometry(geometry_element, at.child(geometry_element), notes)
    known = ('geometry', 'material') if visual else ('geometry', 'surface')
    _others(element, known, notes)
    if geometry is None:
        return None
    name = element.get('name', '')[:255]
    if visual:
        return ShapeSpec(Shape(name, pose, geometry,
                               colour=_colour(element.find('material'), at, notes)), relative_to)
    friction, restitution = _surface(element.find('surface'), at, notes)
    return ShapeSpec(Shape(name, pose, geometry, friction, restitution), relative_to)


def _inertial(element: Optional[ElementTree.Element], place: Place, notes: Notes
              ) -> Inertial:
    if element is None:
        return DEFAULT_INERTIAL
    at = place.child(element)
    if element.get('auto', 'false').strip().lower() in ('true', '1'):
        notes.note('automatic inertia (the file\'s mass and inertia, or 1 kg, are used)')
    mass = at.number(element, 'mass', 1.0, 0.0, MAX_MASS_KG)
    pose, _ = at.pose(element)
    inertia = element.find('inertia')
    values = DEFAULT_INERTIAL.inertia
    if inertia is not None:
        within = at.child(inertia)
        ixx, ixy, ixz, iyy, iyz, izz = (
            within.number(inertia, tag, default, -MAX_INERTIA_KG_M2, MAX_INERTIA_KG_M2)
            for tag, default in zip(('ixx', 'ixy', 'ixz', 'iyy', 'iyz', 'izz'), values))
        values = (ixx, ixy, ixz, iyy, iyz, izz)
        if not all(values[i] >= 0.0 for i in (0, 3, 5)):
            raise within.fail('the moments ixx, iyy and izz cannot be negative')
    return Inertial(mass, pose, values)


def read_link(element: ElementTree.Element, place: Place, notes: FileNotes) -> LinkSpec:
    """Return a <link>: its pose, inertia, collisions and visuals (others noted)."""
    at = place.child(element)
    name = place.name(element)
    pose, relative_to = at.pose(element)
    collisions: List[ShapeSpec] = []
    visuals: List[ShapeSpec] = []
    for child in element:
        tag = local_tag(child)
        if tag in ('collision', 'visual'):
            spec = _shape(child, at, notes, tag == 'visual')
            if spec is not None:
                (visuals if tag == 'visual' else collisions).append(spec)
        elif tag == 'kinematic' and at.truth(element, 'kinematic', False):
            notes.note('kinematic link')
        elif tag == 'gravity' and not at.truth(element, 'gravity', True):
            notes.note('link without gravity')
        elif tag and tag not in ('inertial', 'kinematic', 'gravity') and tag not in QUIET:
            notes.note(tag)
    if len(collisions) + len(visuals) > MAX_SHAPES_PER_LINK:
        raise at.fail(f'a link has more than {MAX_SHAPES_PER_LINK} collisions and visuals')
    return LinkSpec(name, pose, relative_to, _inertial(element.find('inertial'), at, notes),
                    tuple(collisions), tuple(visuals))


def _limit(at: Place, element: ElementTree.Element, tag: str, default: float) -> float:
    """Return a <limit> value; ±inf (SDF 1.10+'s defaults, written out by Gazebo) is none."""
    text = at.text(element, tag)
    if text is not None and text.lstrip('+-').lower() in ('inf', 'infinity'):
        return float(text)  # NaN stays refused by number()
    return at.number(element, tag, default)


def _axis(element: Optional[ElementTree.Element], place: Place, notes: Notes) -> AxisSpec:
    """Return an <axis> (or <axis2>), with its own 1.5-1.6 use_parent_model_frame flag."""
    if element is None:
        return _NO_AXIS
    at = place.child(element)
    xyz = _vector3(at.numbers(element, 'xyz', 3, (0.0, 0.0, 1.0)))
    if not any(xyz):
        raise at.fail('<xyz> must not be zero')
    xyz_element = element.find('xyz')
    expressed_in = '' if xyz_element is None else xyz_element.get('expressed_in', '')
    lower, upper, effort, velocity = -math.inf, math.inf, -1.0, -1.0
    limit = element.find('limit')
    if limit is not None:
        within = at.child(limit)
        lower = _limit(within, limit, 'lower', -1e16)
        upper = _limit(within, limit, 'upper', 1e16)
        effort = _limit(within, limit, 'effort', -1.0)
        velocity = _limit(within, limit, 'velocity', -1.0)
        effort, velocity = (-1.0 if v >= UNLIMITED else v for v in (effort, velocity))
        _others(limit, ('lower', 'upper', 'effort', 'velocity'), notes)
    if not (-UNLIMITED < lower <= upper < UNLIMITED):
        lower, upper = 1.0, -1.0  # none: Bullet adds a limit only for lower <= upper
    damping = friction = 0.0
    dynamics = element.find('dynamics')
    if dynamics is not None:
        within = at.child(dynamics)
        damping = within.number(dynamics, 'damping', 0.0, 0.0, 1e9)
        friction = within.number(dynamics, 'friction', 0.0, 0.0, 1e9)
        if within.number(dynamics, 'spring_stiffness', 0.0) != 0.0:
            notes.note('joint spring')
    _others(element, ('xyz', 'limit', 'dynamics', 'use_parent_model_frame',
                      'initial_position'), notes)
    limits = JointLimits(lower, upper, max(effort, 0.0), max(velocity, 0.0), damping, friction)
    return AxisSpec(xyz, expressed_in, limits, at.truth(element, 'use_parent_model_frame',
                                                        False))


def read_joint(element: ElementTree.Element, place: Place, notes: Notes) -> JointSpec:
    """Return a <joint> as written; a type PyBullet cannot represent is held fixed (noted)."""
    at = place.child(element)
    name = place.name(element)
    kind = element.get('type', '')
    if kind not in JOINT_TYPES:
        if kind not in ('screw', 'gearbox'):
            raise at.fail(f'unknown joint type {kind[:40]!r}')
        notes.note(f'{kind} joint (held fixed)')
        kind = 'fixed'
    parent, child = at.text(element, 'parent', ''), at.text(element, 'child', '')
    if not parent or not child:
        raise at.fail('a joint needs a <parent> and a <child>')
    if parent == child:
        raise at.fail('a joint\'s parent and child are the same link')
    pose, relative_to = at.pose(element)
    axis = _axis(element.find('axis'), at, notes)
    axis2 = _axis(element.find('axis2'), at, notes)
    _others(element, ('parent', 'child', 'axis', 'axis2', 'thread_pitch', 'gearbox_ratio',
                      'gearbox_reference_body'), notes)
    return JointSpec(name, kind, parent, child, pose, relative_to, axis, axis2, str(at))
