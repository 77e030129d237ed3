"""
A planned body as URDF text PyBullet loads: links, shapes, colours, friction, joints.

No ROS, no PyBullet. Shapes map one to one (box, sphere, cylinder, capsule,
plane), meshes through :class:`~r2d2_sim.sim.sdf.mesh_cache.MeshCache`: on a
static body a mesh collision is PyBullet's concave triangle mesh
(``concave="yes"``: walls stay walls, the laser and the camera see their
faces), on a moving one the convex hulls of its connected pieces; a visual
mesh is drawn in the SDF's colour, else one piece per colour of the file.
A plane, which PyBullet draws nothing for, gets a thin box as its visual.
Friction and restitution are per link in Bullet: a link takes its first
collision's. Numbers are written with ``repr``, so a pose survives exactly;
one element a line, as PyBullet reads a URDF line by line into 8 kB buffers
(``BulletUrdfImporter.cpp``: a longer line breaks inside an attribute).
"""

import math
from typing import Callable, Dict, Iterable, List, Optional, Sequence, Set, Tuple
from xml.sax.saxutils import quoteattr

from r2d2_sim.model.sdf_poses import rpy_from_quaternion
from r2d2_sim.model.transforms import compose, Transform
from r2d2_sim.sim.sdf.bodies import BodyJoint, BodyLink, BodyPlan, entity_name
from r2d2_sim.sim.sdf.description import Geometry, Shape
from r2d2_sim.sim.sdf.elements import Notes
from r2d2_sim.sim.sdf.mesh_cache import Converted

__all__ = ['urdf_text', 'DEFAULT_COLOUR', 'PLANE_THICKNESS_M']

# Gazebo draws a visual without a material light grey.
DEFAULT_COLOUR = (0.7, 0.7, 0.7, 1.0)
PLANE_THICKNESS_M = 0.002

# A mesh geometry -> its converted files (None: left out, as the load allows).
Meshes = Callable[[Geometry], Optional[Converted]]
Hulls = Callable[[Converted], str]    # a converted mesh -> its convex pieces' OBJ


def _numbers(values: Iterable[float]) -> str:
    return ' '.join(repr(float(v)) for v in values)


def _origin(pose: Transform) -> str:
    return (f'<origin xyz="{_numbers(pose.translation)}" '
            f'rpy="{_numbers(rpy_from_quaternion(pose.rotation))}"/>')


def _plane_box(shape: Shape) -> Tuple[Transform, str]:
    """Return a plane's visual: a thin box along its normal, its top face on the plane."""
    nx, ny, nz, sx, sy = shape.geometry.size
    # The rotation taking +z onto the normal (about z x n).
    w = 1.0 + nz
    if w < 1e-9:
        turn = (1.0, 0.0, 0.0, 0.0)
    else:
        norm = math.sqrt(ny * ny + nx * nx + w * w)
        turn = (-ny / norm, nx / norm, 0.0, w / norm)
    pose = compose(shape.pose, Transform((0.0, 0.0, 0.0), turn))
    pose = compose(pose, Transform((0.0, 0.0, -PLANE_THICKNESS_M / 2.0), (0.0, 0.0, 0.0, 1.0)))
    return pose, f'<box size="{_numbers((sx, sy, PLANE_THICKNESS_M))}"/>'


def _primitive(geometry: Geometry) -> str:
    kind, size = geometry.kind, geometry.size
    if kind == 'box':
        return f'<box size="{_numbers(size)}"/>'
    if kind == 'sphere':
        return f'<sphere radius="{size[0]!r}"/>'
    if kind in ('cylinder', 'capsule'):
        return f'<{kind} radius="{size[0]!r}" length="{size[1]!r}"/>'
    return f'<plane normal="{_numbers(size[:3])}"/>'


class _Writer:
    """One body's URDF, with the converted meshes it uses and their triangles counted."""

    def __init__(self, meshes: Meshes, hulls: Hulls, notes: Notes) -> None:
        self.meshes = meshes
        self.hulls = hulls
        self.notes = notes
        self.triangles = 0
        self.materials = 0

    def _mesh(self, filename: str, geometry: Geometry) -> str:
        return f'<mesh filename={quoteattr(filename)} scale="{_numbers(geometry.scale)}"/>'

    def collision(self, shape: Shape, static: bool) -> List[str]:
        geometry = shape.geometry
        if geometry.kind == 'plane' and not static:
            self.notes.note('plane on a moving link (left out)')
            return []
        if geometry.kind != 'mesh':
            return [f'<collision>{_origin(shape.pose)}<geometry>{_primitive(geometry)}'
                    '</geometry></collision>']
        converted = self.meshes(geometry)
        if converted is None:
            return []
        self.triangles += converted.triangles
        if static:
            return [f'<collision concave="yes">{_origin(shape.pose)}<geometry>'
                    f'{self._mesh(converted.mesh, geometry)}</geometry></collision>']
        return [f'<collision>{_origin(shape.pose)}<geometry>'
                f'{self._mesh(self.hulls(converted), geometry)}</geometry></collision>']

    def _visual(self, pose: Transform, geometry_text: str,
                colour: Optional[Sequence[float]]) -> str:
        self.materials += 1
        rgba = _numbers(colour or DEFAULT_COLOUR)
        return (f'<visual>{_origin(pose)}<geometry>{geometry_text}</geometry><material '
                f'name="colour_{self.materials}"><color rgba="{rgba}"/></material></visual>')

    def visual(self, shape: Shape) -> List[str]:
        geometry = shape.geometry
        if geometry.kind == 'plane':
            return [self._visual(*_plane_box(shape), shape.colour)]
        if geometry.kind != 'mesh':
            return [self._visual(shape.pose, _primitive(geometry), shape.colour)]
        converted = self.meshes(geometry)
        if converted is None:
            return []
        self.triangles += converted.triangles
        if shape.colour is not None or not converted.parts:
            return [self._visual(shape.pose, self._mesh(converted.mesh, geometry),
                                 shape.colour)]
        return [self._visual(shape.pose, self._mesh(path, geometry), colour)
                for path, colour in converted.parts]

    def link(self, link: BodyLink, name: str, static: bool) -> str:
        parts = [f'<link name={quoteattr(name)}>']
        inertial = link.inertial
        ixx, ixy, ixz, iyy, iyz, izz = inertial.inertia
        parts.append(f'<inertial>{_origin(inertial.pose)}<mass value="{inertial.mass!r}"/>'
                     f'<inertia ixx="{ixx!r}" ixy="{ixy!r}" ixz="{ixz!r}" iyy="{iyy!r}" '
                     f'iyz="{iyz!r}" izz="{izz!r}"/></inertial>')
        for shape in link.collisions:
            parts += self.collision(shape, static)
        for shape in link.visuals:
            parts += self.visual(shape)
        friction = next((s.friction for s in link.collisions if s.friction is not None), None)
        bounce = next((s.restitution for s in link.collisions if s.restitution is not None),
                      None)
        if friction is not None or bounce is not None:
            parts.append('<contact>' + ('' if friction is None else
                                        f'<lateral_friction value="{friction!r}"/>') +
                         ('' if bounce is None else f'<restitution value="{bounce!r}"/>') +
                         '</contact>')
        parts.append('</link>')
        return '\n'.join(parts)  # PyBullet reads a URDF in lines of at most 8 kB


def _joint(joint: BodyJoint, name: str, names: Dict[str, str]) -> str:
    text = [f'<joint name={quoteattr(name)} type="{joint.kind}">'
            f'<parent link={quoteattr(names[joint.parent])}/>'
            f'<child link={quoteattr(names[joint.child])}/>{_origin(joint.origin)}']
    if joint.kind != 'fixed':
        text.append(f'<axis xyz="{_numbers(joint.axis)}"/>')
    limits = joint.limits
    if joint.kind in ('revolute', 'prismatic'):
        text.append(f'<limit lower="{limits.lower!r}" upper="{limits.upper!r}" '
                    f'effort="{limits.effort!r}" velocity="{limits.velocity!r}"/>')
    if joint.kind != 'fixed':
        text.append(f'<dynamics damping="{limits.damping!r}" friction="{limits.friction!r}"/>')
    text.append('</joint>')
    return ''.join(text)


def _unique_names(names: Iterable[str]) -> List[str]:
    """
    Return each name as a URDF may have it, made unique among them (a repeat gets ``_1``...).

    Names that differ in SDF can meet once cleaned (``j k`` and ``j_k``, ``a::j``
    and ``a__j``); PyBullet refuses two links of one name and crashes the whole
    process (SIGSEGV) on two joints of one name.
    """
    taken: Set[str] = set()
    unique = []
    for name in names:
        wanted = entity_name(name)
        made, number = wanted, 1
        while made in taken:
            made, number = f'{wanted}_{number}', number + 1
        taken.add(made)
        unique.append(made)
    return unique


def urdf_text(body: BodyPlan, meshes: Meshes, hulls: Hulls, notes: Notes) -> Tuple[str, int]:
    """Return a body's URDF text and how many mesh triangles it uses."""
    writer = _Writer(meshes, hulls, notes)
    names = dict(zip((link.name for link in body.links),
                     _unique_names(link.name for link in body.links)))
    text = [f'<robot name={quoteattr(body.name)}>']
    for index, link in enumerate(body.links):
        text.append(writer.link(link, names[link.name], static=body.static or (
            index == 0 and link.inertial.mass == 0.0)))
    joint_names = _unique_names(joint.name for joint in body.joints)
    text += [_joint(joint, joint_name, names)
             for joint, joint_name in zip(body.joints, joint_names)]
    text.append('</robot>')
    return '\n'.join(text), writer.triangles
