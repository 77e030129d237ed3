"""
A tf2-style transform buffer in plain Python, for tests on machines without tf2_ros.

tf2_ros is not on PyPI, so a pip-only user has no ``Buffer`` to ask where a
laser point lies in ``odom``. :class:`TransformBuffer` keeps what ``/tf`` and
``/tf_static`` carry and answers ``lookup_transform(target, source, time)`` as
tf2's ``BufferCore`` does: through the frames' common ancestor, interpolating
each moving edge between the two samples around the requested time (linear in
translation, slerp in rotation), static edges at any time, time 0 meaning the
latest time every edge on the path has data for, a bounded history per edge
(10 s by default, as tf2's cache), and tf2's errors: unknown frames,
unconnected trees, extrapolation into the past or the future.

No ROS here: messages are read duck-typed (:func:`from_tf_message`), times are
integer nanoseconds, the math is :mod:`r2d2_sim.model.transforms`. Thread-safe, so a
subscription can feed it while the test thread looks up.
"""

import bisect
import math
import threading
from typing import Any, Dict, List, NamedTuple, Optional, Sequence, Set

from r2d2_sim.model.transforms import (
    apply, compose, IDENTITY, inverse, Quaternion, Transform, Vector3)

__all__ = [
    'DEFAULT_CACHE_TIME_NS',
    'TransformException',
    'LookupException',
    'ConnectivityException',
    'ExtrapolationException',
    'InvalidArgumentException',
    'StampedTransform',
    'TransformBuffer',
    'from_tf_message',
    'slerp',
    'interpolate',
]

# tf2's default cache time: a moving edge keeps this much history behind its newest sample.
DEFAULT_CACHE_TIME_NS = 10 * 10**9
# tf2 refuses a rotation whose squared norm is further than this from 1.
QUATERNION_TOLERANCE = 1e-5
# Below this angle between two rotations, slerp's sin(theta) loses precision: interpolate
# linearly and normalise (the error is far below a nanoradian).
_SLERP_LINEAR_BELOW_COS = 0.9999995


class TransformException(Exception):
    """Base of the buffer's errors, as tf2's ``TransformException``."""


class LookupException(TransformException, LookupError):
    """A frame the buffer has never heard of."""


class ConnectivityException(TransformException):
    """Both frames are known, but in two trees with no frame in common."""


class ExtrapolationException(TransformException):
    """An edge on the path has no data around the requested time."""


class InvalidArgumentException(TransformException, ValueError):
    """A frame id, time or transform that tf2 would refuse."""


class StampedTransform(NamedTuple):
    """
    The pose of ``child_frame_id`` in ``frame_id`` at ``stamp_ns``: what a lookup returns.

    Plain Python values, not a geometry_msgs ``TransformStamped`` (this layer
    imports no ROS): ``frame_id`` the parent (a lookup's target frame),
    ``child_frame_id`` the child (its source frame), ``stamp_ns`` integer
    nanoseconds, ``transform`` a :class:`~r2d2_sim.model.transforms.Transform`
    of ``translation`` (x, y, z, m: the child's origin in the parent) and
    ``rotation`` (a unit quaternion x, y, z, w), both tuples, which map points
    of the child frame into the parent frame; ``translation`` and ``rotation``
    are shortcuts to them. So tf2's ``t.transform.translation.x`` is
    ``t.translation[0]`` here, and ``t.header.stamp`` is ``stamp_ns``.
    """

    frame_id: str
    child_frame_id: str
    stamp_ns: int
    transform: Transform

    @property
    def translation(self) -> Vector3:
        """Return the child origin in parent coordinates (m)."""
        return self.transform.translation

    @property
    def rotation(self) -> Quaternion:
        """Return the child's orientation in the parent, (x, y, z, w)."""
        return self.transform.rotation


def _seconds(time_ns: int) -> str:
    return f'{time_ns // 10**9}.{time_ns % 10**9:09d}'


def slerp(a: Quaternion, b: Quaternion, ratio: float) -> Quaternion:
    """
    Return the rotation ``ratio`` of the way from ``a`` to ``b`` along the shorter arc.

    q and -q are the same rotation; like tf2's ``slerp``, the shorter of the two
    arcs is taken, so interpolating from yaw 170 to -170 degrees passes 180.
    """
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    dot = ax * bx + ay * by + az * bz + aw * bw
    if dot < 0.0:
        bx, by, bz, bw, dot = -bx, -by, -bz, -bw, -dot
    if dot > _SLERP_LINEAR_BELOW_COS:
        wa, wb = 1.0 - ratio, ratio
    else:
        theta = math.acos(dot)
        sin_theta = math.sin(theta)
        wa = math.sin((1.0 - ratio) * theta) / sin_theta
        wb = math.sin(ratio * theta) / sin_theta
    q = (wa * ax + wb * bx, wa * ay + wb * by, wa * az + wb * bz, wa * aw + wb * bw)
    norm = math.sqrt(sum(c * c for c in q))
    return (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm)


def interpolate(a: Transform, b: Transform, ratio: float) -> Transform:
    """Return the transform ``ratio`` of the way from ``a`` to ``b``: lerp and slerp, as tf2."""
    (ax, ay, az), (bx, by, bz) = a.translation, b.translation
    return Transform((ax + (bx - ax) * ratio, ay + (by - ay) * ratio, az + (bz - az) * ratio),
                     slerp(a.rotation, b.rotation, ratio))


class _Edge:
    """The history of one child frame in its parent: one value when static, else samples."""

    def __init__(self, parent: str, static: bool) -> None:
        self.parent = parent
        self.static = static
        self.stamps: List[int] = []          # ascending, nanoseconds
        self.transforms: List[Transform] = []

    def insert(self, stamp_ns: int, transform: Transform, cache_time_ns: int) -> bool:
        if self.static:
            self.stamps, self.transforms = [stamp_ns], [transform]
            return True
        if self.stamps and stamp_ns < self.stamps[-1] - cache_time_ns:
            return False  # older than the history kept: tf2 ignores it too (TF_OLD_DATA)
        i = bisect.bisect_left(self.stamps, stamp_ns)
        if i < len(self.stamps) and self.stamps[i] == stamp_ns:
            return False  # tf2 keeps the first of two samples at one time (TF_REPEATED_DATA)
        self.stamps.insert(i, stamp_ns)
        self.transforms.insert(i, transform)
        oldest = bisect.bisect_left(self.stamps, self.stamps[-1] - cache_time_ns)
        del self.stamps[:oldest], self.transforms[:oldest]
        return True

    def latest_ns(self) -> int:
        """Return the newest stamp; 0 for a static edge, which holds at any time."""
        return 0 if self.static else self.stamps[-1]

    def at(self, time_ns: int, child: str) -> Transform:
        if self.static:
            return self.transforms[0]
        stamps = self.stamps
        where = f'when looking up transform from frame [{child}] to frame [{self.parent}]'
        if len(stamps) == 1:
            if time_ns == stamps[0]:
                return self.transforms[0]
            raise ExtrapolationException(
                f'Lookup would require extrapolation at time {_seconds(time_ns)}, but only '
                f'time {_seconds(stamps[0])} is in the buffer, {where}')
        if time_ns < stamps[0]:
            raise ExtrapolationException(
                f'Lookup would require extrapolation into the past. Requested time '
                f'{_seconds(time_ns)} but the earliest data is at time {_seconds(stamps[0])}, '
                f'{where}')
        if time_ns > stamps[-1]:
            raise ExtrapolationException(
                f'Lookup would require extrapolation into the future. Requested time '
                f'{_seconds(time_ns)} but the latest data is at time {_seconds(stamps[-1])}, '
                f'{where}')
        i = bisect.bisect_left(stamps, time_ns)
        if stamps[i] == time_ns:
            return self.transforms[i]
        before, after = stamps[i - 1], stamps[i]
        return interpolate(self.transforms[i - 1], self.transforms[i],
                           (time_ns - before) / (after - before))


def _check_frame_id(frame: Any, what: str) -> str:
    if not isinstance(frame, str) or not frame:
        raise InvalidArgumentException(f'{what} must be a non-empty frame id, got {frame!r}')
    if frame.startswith('/'):
        raise InvalidArgumentException(
            f'{what} {frame!r}: in tf2 frame ids cannot start with a \'/\'')
    return frame


def _check_time(time_ns: Any, what: str) -> int:
    if isinstance(time_ns, bool) or not isinstance(time_ns, int) or time_ns < 0:
        raise InvalidArgumentException(f'{what} must be an integer >= 0 (ns), got {time_ns!r}')
    return time_ns


def _check_transform(translation: Sequence[float], rotation_xyzw: Sequence[float],
                     what: str) -> Transform:
    try:
        t = tuple(float(v) for v in translation)
        q = tuple(float(v) for v in rotation_xyzw)
    except (TypeError, ValueError):
        raise InvalidArgumentException(f'{what}: translation and rotation must be numbers') \
            from None
    if len(t) != 3 or len(q) != 4:
        raise InvalidArgumentException(
            f'{what}: translation needs 3 numbers and rotation 4 (x, y, z, w), got {t}, {q}')
    if not all(math.isfinite(v) for v in t + q):
        raise InvalidArgumentException(f'{what}: NaN or infinity in {t}, {q}')
    norm2 = sum(v * v for v in q)
    if abs(norm2 - 1.0) > QUATERNION_TOLERANCE:
        raise InvalidArgumentException(
            f'{what}: rotation {q} is not a unit quaternion (squared norm {norm2:.9g})')
    norm = math.sqrt(norm2)
    return Transform(t, (q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm))


class TransformBuffer:
    """
    Transforms between frames over time, looked up as tf2's ``Buffer.lookup_transform``.

    Feed it with :meth:`add` (or :meth:`add_tf_message` from a ``/tf`` or
    ``/tf_static`` subscription); ask :meth:`lookup_transform`,
    :meth:`can_transform` or :meth:`transform_point`. Each child frame has
    one parent: adding it under another parent, or switching it between
    static and moving, starts its history anew (tf2 keeps both, which matters
    only for frames that change parents).
    """

    def __init__(self, cache_time_ns: int = DEFAULT_CACHE_TIME_NS) -> None:
        self.cache_time_ns = _check_time(cache_time_ns, 'cache_time_ns')
        self._edges: Dict[str, _Edge] = {}   # by child frame
        self._known: Set[str] = set()         # every frame ever added, as tf2 keeps them
        self._lock = threading.Lock()

    def add(self, parent: str, child: str, stamp_ns: int, translation: Sequence[float],
            rotation_xyzw: Sequence[float], static: bool = False) -> bool:
        """
        Store the pose of ``child`` in ``parent`` at ``stamp_ns``; return whether it was kept.

        As tf2 does, a sample older than the kept history or at a time already
        held is ignored (False). Refused with InvalidArgumentException: empty or
        '/'-prefixed frame ids, a frame its own parent, a transform that would
        close a loop, NaN, a rotation that is not a unit quaternion.
        """
        _check_frame_id(parent, 'parent frame')
        _check_frame_id(child, 'child frame')
        _check_time(stamp_ns, 'stamp_ns')
        what = f'transform {parent} -> {child}'
        if parent == child:
            raise InvalidArgumentException(f'{what}: a frame cannot be its own parent')
        transform = _check_transform(translation, rotation_xyzw, what)
        with self._lock:
            frame: Optional[str] = parent
            while frame is not None:
                if frame == child:
                    raise InvalidArgumentException(
                        f'{what} would make a loop: {parent} is below {child} in the tree')
                edge = self._edges.get(frame)
                frame = edge.parent if edge is not None else None
            edge = self._edges.get(child)
            if edge is None or edge.parent != parent or edge.static != bool(static):
                edge = self._edges[child] = _Edge(parent, bool(static))
            self._known.update((parent, child))
            return edge.insert(stamp_ns, transform, self.cache_time_ns)

    def add_tf_message(self, msg: Any, static: bool = False) -> int:
        """Add every transform of a ``tf2_msgs/msg/TFMessage``; return how many were kept."""
        kept = 0
        for t in from_tf_message(msg):
            kept += self.add(t.frame_id, t.child_frame_id, t.stamp_ns, t.transform.translation,
                             t.transform.rotation, static)
        return kept

    def clear(self) -> None:
        """Forget every transform, as tf2's ``Buffer.clear``."""
        with self._lock:
            self._edges.clear()
            self._known.clear()

    @property
    def frames(self) -> Set[str]:
        """Return every frame the buffer has been given, as a parent or as a child."""
        with self._lock:
            return set(self._known)

    def parent_of(self, frame: str) -> Optional[str]:
        """Return the parent of ``frame``; None for a root or an unknown frame."""
        with self._lock:
            edge = self._edges.get(frame)
            return None if edge is None else edge.parent

    def lookup_transform(self, target_frame: str, source_frame: str,
                         time_ns: int = 0) -> StampedTransform:
        """
        Return the pose of ``source_frame`` in ``target_frame`` at ``time_ns``.

        The result maps points of the source frame into the target frame
        (``frame_id`` target, ``child_frame_id`` source, as tf2). ``time_ns`` 0
        means the latest time for which every moving edge on the path has data;
        the result's ``stamp_ns`` says which time was used (0 when every edge
        on the path is static). Raises LookupException, ConnectivityException,
        ExtrapolationException or InvalidArgumentException, all TransformException.
        """
        _check_frame_id(target_frame, 'target_frame')
        _check_frame_id(source_frame, 'source_frame')
        _check_time(time_ns, 'time_ns')
        with self._lock:
            for frame, argument in ((target_frame, 'target_frame'),
                                    (source_frame, 'source_frame')):
                if frame not in self._known:
                    listed = ', '.join(sorted(self._known)) or 'none yet'
                    raise LookupException(
                        f'"{frame}" passed to lookup_transform argument {argument} does not '
                        f'exist (known frames: {listed})')
            source_path = self._path_to_root(source_frame)
            target_path = self._path_to_root(target_frame)
            ancestor = next((f for f in target_path if f in source_path), None)
            if ancestor is None:
                raise ConnectivityException(
                    f"Could not find a connection between '{target_frame}' and "
                    f"'{source_frame}' because they are not part of the same tree: TF has two "
                    f"or more unconnected trees (roots '{target_path[-1]}' and "
                    f"'{source_path[-1]}')")
            source_up = source_path[:source_path.index(ancestor)]
            target_up = target_path[:target_path.index(ancestor)]
            if time_ns == 0:
                time_ns = self._latest_common_ns(source_up + target_up, source_frame)
            ancestor_from_source = self._chain(source_up, time_ns)
            ancestor_from_target = self._chain(target_up, time_ns)
        return StampedTransform(target_frame, source_frame, time_ns,
                                compose(inverse(ancestor_from_target), ancestor_from_source))

    def can_transform(self, target_frame: str, source_frame: str, time_ns: int = 0) -> bool:
        """Return whether :meth:`lookup_transform` would succeed, as tf2's ``can_transform``."""
        try:
            self.lookup_transform(target_frame, source_frame, time_ns)
        except TransformException:
            return False
        return True

    def transform_point(self, target_frame: str, source_frame: str, point: Sequence[float],
                        time_ns: int = 0) -> Vector3:
        """Return ``point`` (x, y, z in ``source_frame``, m) in ``target_frame`` at ``time_ns``."""
        return apply(self.lookup_transform(target_frame, source_frame, time_ns).transform,
                     point)

    # -- internals, called with the lock held -----------------------------------

    def _path_to_root(self, frame: str) -> List[str]:
        """Return ``frame`` and its ancestors, root last (add() keeps the tree loop-free)."""
        path = [frame]
        edge = self._edges.get(frame)
        while edge is not None:
            path.append(edge.parent)
            edge = self._edges.get(edge.parent)
        return path

    def _latest_common_ns(self, children: Sequence[str], frame: str) -> int:
        """Return the newest time all moving edges of ``children`` have data for (0: none)."""
        latest = [self._edges[c].latest_ns() for c in children if not self._edges[c].static]
        if latest:
            return min(latest)
        edge = self._edges.get(frame)  # same frame both ways: its own newest time, as tf2
        return edge.latest_ns() if edge is not None and not children else 0

    def _chain(self, children: Sequence[str], time_ns: int) -> Transform:
        """Return the pose of ``children[0]`` in the parent of ``children[-1]`` at ``time_ns``."""
        result = IDENTITY
        for child in children:
            result = compose(self._edges[child].at(time_ns, child), result)
        return result


def from_tf_message(msg: Any) -> List[StampedTransform]:
    """
    Return the transforms of a ``tf2_msgs/msg/TFMessage`` (or anything shaped like one).

    Reads ``msg.transforms[i].header.frame_id``, ``.header.stamp.sec`` and
    ``.nanosec``, ``.child_frame_id``, ``.transform.translation.x/y/z`` and
    ``.transform.rotation.x/y/z/w``; no ROS import, so a fake message works too.
    """
    result = []
    for t in msg.transforms:
        stamp = t.header.stamp
        translation, rotation = t.transform.translation, t.transform.rotation
        result.append(StampedTransform(
            t.header.frame_id, t.child_frame_id, int(stamp.sec) * 10**9 + int(stamp.nanosec),
            Transform((translation.x, translation.y, translation.z),
                      (rotation.x, rotation.y, rotation.z, rotation.w))))
    return result
