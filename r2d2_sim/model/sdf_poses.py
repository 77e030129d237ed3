"""
SDF's poses: six (or seven) numbers to a transform, and frames resolved through ``relative_to``.

Pure math, free of ROS and PyBullet. SDF (1.4 to 1.11) writes a pose as
``x y z roll pitch yaw`` (radians, or degrees with ``degrees="true"``), or
``x y z qx qy qz qw`` with ``rotation_format="quat_xyzw"`` (1.9+); the
rotation is URDF's (roll about fixed x, then pitch about y, then yaw about z).
Since SDF 1.7 a pose may say which frame it is relative to: a
:class:`PoseGraph` holds one scope's frames (a model's links, joints, nested
models and ``<frame>`` elements, or a world's models and frames), each at a
pose relative to another, and resolves them to the scope's own frame,
following scoped names (``nested::link``) into nested scopes and refusing a
frame that names no frame or a chain that comes back on itself
(:class:`FrameError`). :func:`rpy_from_quaternion` turns rotations back into
the ``rpy`` a URDF writes.
"""

import math
from typing import Dict, List, Optional, Sequence, Tuple

from r2d2_sim.model.transforms import (
    compose, IDENTITY, quaternion_from_rpy, Quaternion, Transform, Vector3)

__all__ = ['FrameError', 'PoseGraph', 'pose_from_values', 'rpy_from_quaternion',
           'SCOPE_SEPARATOR']

SCOPE_SEPARATOR = '::'
# A quaternion written in a file, give or take its digits.
QUATERNION_NORM_TOLERANCE = 1e-3


class FrameError(ValueError):
    """A pose that names no frame, refers in a circle, or does not make a rotation."""


def pose_from_values(values: Sequence[float], quaternion: bool = False,
                     degrees: bool = False) -> Transform:
    """
    Return the transform of an SDF pose's numbers.

    Six numbers ``x y z roll pitch yaw`` (``degrees``: the angles are in
    degrees), or seven ``x y z qx qy qz qw`` when ``quaternion`` (normalised;
    FrameError for one that is not unit within 1e-3, nor finite).
    """
    count = 7 if quaternion else 6
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise FrameError(f'a pose is {count} finite numbers')
    translation = (float(values[0]), float(values[1]), float(values[2]))
    if quaternion:
        qx, qy, qz, qw = (float(v) for v in values[3:])
        norm = math.sqrt(sum(c * c for c in (qx, qy, qz, qw)))
        if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
            raise FrameError(f'the quaternion of a pose is not a unit one (norm {norm:.6g})')
        return Transform(translation, (qx / norm, qy / norm, qz / norm, qw / norm))
    angles = [math.radians(v) if degrees else float(v) for v in values[3:]]
    return Transform(translation, quaternion_from_rpy(*angles))


def rpy_from_quaternion(q: Quaternion) -> Vector3:
    """
    Return (roll, pitch, yaw) in radians with ``quaternion_from_rpy(*rpy)`` the rotation ``q``.

    At pitch +-90 degrees (gimbal lock) roll is taken as 0 and the yaw
    carries the rest, so the rotation still comes back exactly.
    """
    x, y, z, w = q
    sin_pitch = 2.0 * (w * y - z * x)
    if abs(sin_pitch) >= 1.0 - 1e-12:
        yaw = math.atan2(-2.0 * (x * y - z * w), 1.0 - 2.0 * (x * x + z * z))
        return (0.0, math.copysign(math.pi / 2.0, sin_pitch), yaw)
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(sin_pitch)
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return (roll, pitch, yaw)


class PoseGraph:
    """
    One scope's frames, each at a pose relative to another; resolved to the scope's frame.

    ``root`` is the scope's own frame (``__model__`` for a model, ``world``
    for a world), at the identity. :meth:`add` puts a frame at a pose
    relative to another (``''``: the scope's frame); a frame that is a
    nested scope (a nested model) brings that scope's graph, so that
    ``nested::link`` resolves through it. Frames are resolved on demand,
    once each; FrameError names the frame whose pose cannot be resolved.
    """

    def __init__(self, root: str) -> None:
        self.root = root
        self._edges: Dict[str, Tuple[str, Transform]] = {}
        self._scopes: Dict[str, 'PoseGraph'] = {}
        self._resolved: Dict[str, Transform] = {root: IDENTITY}
        self._resolving: List[str] = []  # frames being resolved now, through nested scopes

    def __contains__(self, name: str) -> bool:
        return self.find(name)

    def names(self) -> List[str]:
        """Return the frames of this scope (not of nested ones), in the order they were added."""
        return list(self._edges)

    def add(self, name: str, relative_to: str, pose: Transform,
            scope: Optional['PoseGraph'] = None) -> None:
        """
        Put frame ``name`` at ``pose`` relative to ``relative_to`` ('' for the scope's frame).

        ``scope``: the graph of the nested scope this frame is the frame of.
        FrameError when the scope has a frame of that name already.
        """
        if name in self._edges or name == self.root:
            raise FrameError(f'two frames are named {name!r} in one scope')
        self._edges[name] = (relative_to or self.root, pose)
        if scope is not None:
            self._scopes[name] = scope

    def find(self, name: str) -> bool:
        """Return True if ``name`` (scoped names too) names a frame of this scope."""
        if name == self.root or name in self._edges:
            return True
        head, _, rest = name.partition(SCOPE_SEPARATOR)
        scope = self._scopes.get(head)
        return bool(rest) and scope is not None and (rest == scope.root or scope.find(rest))

    def pose(self, name: str) -> Transform:
        """Return the pose of frame ``name`` in the scope's frame; FrameError if it has none."""
        if name in self._resolved:
            return self._resolved[name]
        if name not in self._edges:
            head, _, rest = name.partition(SCOPE_SEPARATOR)
            scope = self._scopes.get(head)
            if not rest or scope is None:
                raise FrameError(f'no frame named {name[:100]!r}')
            inner = IDENTITY if rest == scope.root else scope.pose(rest)
            return compose(self.pose(head), inner)
        return self._resolve(name)

    def _resolve(self, name: str) -> Transform:
        """Follow ``relative_to`` from ``name`` to a resolved frame, then compose back."""
        if name in self._resolving:
            raise FrameError(f'the poses of {", ".join(self._resolving)} are relative to each '
                             'other in a circle')
        self._resolving.append(name)
        try:
            return self._follow(name)
        finally:
            self._resolving.remove(name)

    def _follow(self, name: str) -> Transform:
        chain = [name]
        while True:
            parent = self._edges[chain[-1]][0]
            if parent in self._resolved or parent not in self._edges:
                break
            if parent in chain:
                raise FrameError(f'the poses of {", ".join(chain[chain.index(parent):])} are '
                                 'relative to each other in a circle')
            chain.append(parent)
        parent = self._edges[chain[-1]][0]
        if not self.find(parent):
            raise FrameError(f'the pose of {chain[-1]!r} is relative to {parent[:100]!r}, which '
                             'names no frame')
        pose = self.pose(parent)
        for frame in reversed(chain):
            pose = compose(pose, self._edges[frame][1])
            self._resolved[frame] = pose
        return pose
