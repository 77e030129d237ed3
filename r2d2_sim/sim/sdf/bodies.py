"""
An SDF model as the bodies PyBullet can load: one URDF tree per body, frames and joints placed.

No ROS, no PyBullet. A URDF is one tree of links; an SDF model is links and
joints in any shape. So a model becomes bodies (:func:`plan_bodies`):

- a static model is one static body, every shape of every link (nested
  models' too) in one massless link at the model's frame; static links of a
  moving model likewise make one static body;
- the moving links, split where no joint joins them (Gazebo simulates those
  apart), each piece a body rooted at its canonical link, or at the link a
  joint ties to the world (a fixed joint: that link is the massless base; any
  other: a massless anchor at the joint, the joint below it);
- a joint traversed against its direction is turned round (the axis and the
  limits negated); a joint that closes a loop is left out (noted);
- ``ball`` becomes Bullet's spherical joint, ``universal`` and ``revolute2``
  two revolute joints through a small link at the joint, ``revolute`` without
  limits ``continuous``.

A URDF child link's frame is its joint's frame (a joint turns about its own
origin), so every link gets a frame of its own (:class:`BodyLink.frame`) and
its shapes and inertia are moved into it. The first body of a model takes the
model's name; others add ``__<root link>`` (``__static`` for the static part).
"""

import re
from typing import Dict, List, NamedTuple, Tuple

import numpy

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.transforms import (
    compose, IDENTITY, inverse, rotate_inverse, Transform, Vector3)
from r2d2_sim.sim.sdf.description import Inertial, Joint, JointLimits, Link, Model, Shape
from r2d2_sim.sim.sdf.elements import Notes, Place

__all__ = ['BodyLink', 'BodyJoint', 'BodyPlan', 'plan_bodies', 'entity_name', 'MASSLESS']

ANCHOR = 'world_anchor'
MASSLESS = Inertial(0.0, IDENTITY, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
# The small link between a universal joint's two axes (kg, kg m^2).
_BETWEEN = Inertial(1e-3, IDENTITY, (1e-7, 0.0, 0.0, 1e-7, 0.0, 1e-7))
_INVALID = re.compile(r'[^A-Za-z0-9_\-]')


def entity_name(name: str) -> str:
    """Return ``name`` as an entity or URDF name may be: ``::`` -> ``__``, others -> ``_``."""
    cleaned = _INVALID.sub('_', name.replace('::', '__')) or 'model'
    return cleaned if cleaned[0].isalpha() or cleaned[0] == '_' else '_' + cleaned


class BodyLink(NamedTuple):
    """A URDF link: its name, frame in the model's frame, inertia and shapes in that frame."""

    name: str
    frame: Transform
    inertial: Inertial
    collisions: Tuple[Shape, ...]
    visuals: Tuple[Shape, ...]


class BodyJoint(NamedTuple):
    """A URDF joint: type, links, the child frame in the parent's, axis in the child's."""

    name: str
    kind: str   # fixed, revolute, continuous, prismatic, spherical
    parent: str
    child: str
    origin: Transform
    axis: Vector3
    limits: JointLimits


class BodyPlan(NamedTuple):
    """One body to load: its entity name, base frame in the model's frame, links, joints."""

    name: str
    base: Transform
    static: bool        # massless base and nothing moving: concave meshes allowed
    links: Tuple[BodyLink, ...]
    joints: Tuple[BodyJoint, ...]


def valid_inertia(inertia: Tuple[float, float, float, float, float, float]) -> bool:
    """
    Tell whether an inertia (ixx, ixy, ixz, iyy, iyz, izz) is one a body can have.

    As sdformat's LINK_INERTIA_INVALID (gz-math's MassMatrix3::IsValid): principal
    moments above 0, each at most the sum of the other two (within 1e-6 of the largest).
    PyBullet zeroes any other, and the link then never rotates, with no word.
    """
    ixx, ixy, ixz, iyy, iyz, izz = inertia
    moments = sorted(float(m) for m in numpy.linalg.eigvalsh(
        numpy.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])))
    tolerance = 1e-6 * max(abs(m) for m in moments)
    return moments[0] > 0.0 and moments[0] + moments[1] + tolerance >= moments[2]


def _moved(link: Link, frame: Transform, static: bool) -> BodyLink:
    """Return ``link`` with its inertia and shapes in ``frame`` (a frame in the model's)."""
    into = compose(inverse(frame), link.pose)

    def shapes(found: Tuple[Shape, ...]) -> Tuple[Shape, ...]:
        return tuple(shape._replace(pose=compose(into, shape.pose)) for shape in found)
    inertial = MASSLESS if static else link.inertial._replace(
        pose=compose(into, link.inertial.pose))
    return BodyLink(link.name, frame, inertial, shapes(link.collisions), shapes(link.visuals))


def _static_body(name: str, links: List[Link]) -> BodyPlan:
    """Return one massless link holding every shape of ``links``, at the model's frame."""
    collisions: List[Shape] = []
    visuals: List[Shape] = []
    for link in links:
        moved = _moved(link, IDENTITY, True)
        collisions += moved.collisions
        visuals += moved.visuals
    return BodyPlan(name, IDENTITY, True, (BodyLink('base', IDENTITY, MASSLESS,
                                                    tuple(collisions), tuple(visuals)),), ())


class _Planner:
    """The moving part of one model, cut into bodies at the joints."""

    def __init__(self, model: Model, notes: Notes) -> None:
        self.model = model
        self.notes = notes
        self.links = {link.name: link for link in model.links}

    def fail(self, problem: str) -> RefusedError:
        return Place(self.model.source, (f'model {self.model.name[:100]}',)).fail(problem)

    def moving(self, name: str) -> bool:
        link = self.links.get(name)
        return link is not None and not link.static

    def pieces(self) -> List[List[str]]:
        """Return the moving links in pieces joined by joints, in the file's order."""
        group = {name: name for name in self.links if self.moving(name)}

        def root(name: str) -> str:
            while group[name] != name:
                name = group[name]
            return name
        for joint in self.model.joints:
            if self.moving(joint.parent) and self.moving(joint.child):
                group[root(joint.child)] = root(joint.parent)
        found: Dict[str, List[str]] = {}
        for name in group:
            found.setdefault(root(name), []).append(name)
        return list(found.values())

    def body(self, piece: List[str], name: str) -> BodyPlan:
        """Return one piece as a body: a tree from its root, loops and extra ties left out."""
        members = set(piece)
        joints = self.model.joints
        anchors = [j for j in joints if (j.child in members and not self.moving(j.parent)) or
                   (j.parent in members and not self.moving(j.child))]
        anchor = anchors[0] if anchors else None
        for _ in anchors[1:]:
            self.notes.note('joint closing a loop (left out)')
        if anchor is not None:
            root = anchor.child if anchor.child in members else anchor.parent
        else:
            root = self.model.canonical if self.model.canonical in members else next(
                (n for n in piece if not any(j.child == n and j.parent in members
                                             for j in joints)), piece[0])
        fixed_base = anchor is not None and anchor.kind == 'fixed'
        frames = {root: self.links[root].pose}
        edges = []  # (joint, turned round, URDF parent, URDF child), parents first
        if anchor is not None and not fixed_base:
            frames[ANCHOR] = frames[root] = anchor.pose
            edges.append((anchor, anchor.child not in members, ANCHOR, root))
        used = {id(anchor)}
        queue = [root]
        while queue:
            current = queue.pop(0)
            for joint in joints:
                other = joint.child if joint.parent == current else \
                    joint.parent if joint.child == current else None
                if other is None or other not in members or id(joint) in used:
                    continue
                used.add(id(joint))
                if other in frames:
                    self.notes.note('joint closing a loop (left out)')
                    continue
                frames[other] = joint.pose
                edges.append((joint, joint.parent != current, current, other))
                queue.append(other)
        if ANCHOR in frames:  # the root's link comes with the anchor's joint, below
            links = [BodyLink(ANCHOR, frames[ANCHOR], MASSLESS, (), ())]
        else:
            links = [_moved(self.links[root], frames[root], fixed_base)]
        urdf_joints: List[BodyJoint] = []
        for joint, turned, parent, child in edges:
            self._joint(joint, turned, parent, child, frames, links, urdf_joints)
        for link in links:
            if link.inertial.mass <= 0.0 and link.name != ANCHOR and not (
                    fixed_base and link.name == root):
                raise self.fail(f'link {link.name[:100]} moves, so it needs a mass above 0')
            if link.name != ANCHOR and not (fixed_base and link.name == root) and \
                    not valid_inertia(link.inertial.inertia):
                raise self.fail(f'link {link.name[:100]} moves, so its inertia must be '
                                'positive definite with moments that keep the triangle '
                                'inequality')
        return BodyPlan(name, links[0].frame, fixed_base and not urdf_joints, tuple(links),
                        tuple(urdf_joints))

    def _joint(self, joint: Joint, turned: bool, parent: str, child: str,
               frames: Dict[str, Transform], links: List[BodyLink],
               joints: List[BodyJoint]) -> None:
        """Add the URDF joint(s) from ``parent`` to ``child``, and ``child``'s link."""
        sign = -1.0 if turned else 1.0
        origin = compose(inverse(frames[parent]), frames[child])
        rotation = frames[child].rotation

        def axis_of(direction: Vector3) -> Vector3:
            x, y, z = rotate_inverse(rotation, direction)
            return (sign * x, sign * y, sign * z)

        def limits_of(limits: JointLimits) -> JointLimits:
            if not turned or limits.lower > limits.upper:
                return limits
            return limits._replace(lower=-limits.upper, upper=-limits.lower)
        if joint.kind in ('universal', 'revolute2'):
            axes = [(joint.axis, joint.limits), (joint.axis2, joint.limits2)]
            (first, first_limits), (second, second_limits) = axes[::-1] if turned else axes
            between = f'{joint.name}__between'
            links.append(BodyLink(between, frames[child], _BETWEEN, (), ()))
            joints.append(BodyJoint(f'{joint.name}__first', _turning(first_limits), parent,
                                    between, origin, axis_of(first), limits_of(first_limits)))
            parent, origin = between, IDENTITY
            kind, axis, limits = _turning(second_limits), second, second_limits
        else:
            kind = {'revolute': _turning(joint.limits), 'ball': 'spherical'}.get(
                joint.kind, joint.kind)
            axis, limits = joint.axis, joint.limits
        links.append(_moved(self.links[child], frames[child], False))
        joints.append(BodyJoint(joint.name, kind, parent, child, origin, axis_of(axis),
                                limits_of(limits)))


def _turning(limits: JointLimits) -> str:
    return 'revolute' if limits.lower <= limits.upper else 'continuous'


def plan_bodies(model: Model, notes: Notes) -> List[BodyPlan]:
    """
    Return the bodies of ``model``, the one holding its canonical link first.

    ``notes.note(what)`` hears of every joint left out. RESOURCE_PARSE_ERROR
    for a moving link of mass 0 (Bullet would take it for a fixed one) or with an
    inertia no body has (:func:`valid_inertia`).
    """
    name = entity_name(model.name)
    static = [link for link in model.links if link.static]
    if not model.links:
        return []
    if len(static) == len(model.links):
        return [_static_body(name, static)]
    planner = _Planner(model, notes)
    pieces = planner.pieces()
    pieces.sort(key=lambda piece: model.canonical not in piece)  # stable: the file's order
    bodies = []
    for number, piece in enumerate(pieces):
        body_name = name if number == 0 and (model.canonical in piece or not static) \
            else f'{name}__{entity_name(piece[0])}'
        bodies.append(planner.body(piece, body_name))
    if static:
        first = any(link.name == model.canonical for link in static)
        body = _static_body(name if first else f'{name}__static', static)
        bodies.insert(0 if first else len(bodies), body)
    return bodies
