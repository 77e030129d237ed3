"""
What an SDF world or model describes, as plain data: models, links, shapes, joints, frames.

No ROS, no PyBullet, no XML: :mod:`.reader` fills these from SDF files and
:mod:`.bodies` turns them into the bodies PyBullet loads. Nested models are
flattened into their top-level model (links and joints keep scoped names,
``nested::link``); every pose is resolved, so nothing here refers to another
frame by name. Transforms are (translation, quaternion) as in
:mod:`r2d2_sim.model.transforms`; lengths in metres, masses in kg.
"""

from typing import NamedTuple, Optional, Tuple

from r2d2_sim.model.transforms import IDENTITY, Transform, Vector3

__all__ = ['Geometry', 'Shape', 'Inertial', 'Link', 'JointLimits', 'Joint', 'Model',
           'NamedFrame', 'Scene', 'JOINT_TYPES', 'DEFAULT_INERTIAL']

Rgba = Tuple[float, float, float, float]

# SDF's joint types that PyBullet can represent, and what becomes of each; the others
# (screw, gearbox) are held fixed and said so.
JOINT_TYPES = ('fixed', 'revolute', 'continuous', 'prismatic', 'ball', 'universal',
               'revolute2')


class Geometry(NamedTuple):
    """
    One shape's geometry, as SDF gives it.

    ``kind`` is box (``size`` x y z), sphere (radius), cylinder (radius,
    length), capsule (radius, length of the cylinder between the caps), plane
    (normal x y z, size x y) or mesh: ``mesh`` the file's path, ``uri`` as
    the SDF wrote it (for messages), ``scale`` per axis.
    """

    kind: str
    size: Tuple[float, ...] = ()
    mesh: Optional[str] = None
    scale: Vector3 = (1.0, 1.0, 1.0)
    uri: str = ''


class Shape(NamedTuple):
    """A collision or a visual: its pose in its link's frame, geometry, surface or colour."""

    name: str
    pose: Transform
    geometry: Geometry
    friction: Optional[float] = None     # <surface><friction> mu, where given
    restitution: Optional[float] = None  # <surface><bounce> restitution_coefficient
    colour: Optional[Rgba] = None        # a visual's <material>, where given


class Inertial(NamedTuple):
    """Mass (kg), the centre of mass's frame in the link's, and the inertia there (kg m^2)."""

    mass: float
    pose: Transform
    inertia: Tuple[float, float, float, float, float, float]  # ixx ixy ixz iyy iyz izz


# SDF's default: a link without <inertial> has 1 kg and a unit inertia.
DEFAULT_INERTIAL = Inertial(1.0, IDENTITY, (1.0, 0.0, 0.0, 1.0, 0.0, 1.0))


class Link(NamedTuple):
    """One link: its scoped name, pose in its top-level model's frame, and what it is made of."""

    name: str
    pose: Transform
    static: bool
    inertial: Inertial
    collisions: Tuple[Shape, ...]
    visuals: Tuple[Shape, ...]


class JointLimits(NamedTuple):
    """An axis's limits: position (rad or m; lower > upper: none), effort and velocity."""

    lower: float
    upper: float
    effort: float
    velocity: float
    damping: float = 0.0
    friction: float = 0.0


class Joint(NamedTuple):
    """
    One joint: type, parent and child links (scoped names, or ``world``), its frame and axes.

    ``pose`` is the joint frame in the top-level model's frame; ``axis`` and
    ``axis2`` are unit vectors in that frame too (whatever frame the file
    expressed them in).
    """

    name: str
    kind: str
    parent: str
    child: str
    pose: Transform
    axis: Vector3 = (0.0, 0.0, 1.0)
    limits: JointLimits = JointLimits(1.0, -1.0, 0.0, 0.0)
    axis2: Vector3 = (0.0, 0.0, 1.0)
    limits2: JointLimits = JointLimits(1.0, -1.0, 0.0, 0.0)


class Model(NamedTuple):
    """
    A top-level model, nested ones flattened into it.

    ``pose`` is its frame in the world (for a model read on its own: the
    identity); ``canonical`` its canonical link's scoped name; ``source``
    the file it came from, as shown in messages.
    """

    name: str
    pose: Transform
    static: bool
    links: Tuple[Link, ...]
    joints: Tuple[Joint, ...]
    canonical: str
    source: str


class NamedFrame(NamedTuple):
    """A world-level ``<frame>``: its name and pose in the world (a named pose)."""

    name: str
    pose: Transform


class Scene(NamedTuple):
    """
    What one SDF file describes: its models, frames, and what is not simulated.

    ``world`` is the ``<world>``'s name ('' for a file of models);
    ``not_simulated`` counts what is left out by what it is (``plugin``,
    ``light``...); ``left_out`` says which missing or unsupported assets were
    left out (``ignore_missing_or_unsupported_assets``).
    """

    world: str
    models: Tuple[Model, ...]
    frames: Tuple[NamedFrame, ...]
    not_simulated: Tuple[Tuple[str, int], ...]
    left_out: Tuple[str, ...]
