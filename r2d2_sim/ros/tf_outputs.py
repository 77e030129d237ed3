"""
TF for one robot: ``/tf`` every state publication, ``/tf_static`` once (transient local).

With ``tf_layout`` namespaced, ``tf`` and ``tf_static`` in the robot's
namespace instead (:func:`tf_topics`), as Nav2's multi-robot launch remaps them.

Like the other outputs, these only translate a :class:`~r2d2_sim.sim.robots.robot.Frame`
into bytes: odom -> base_footprint from wheel odometry, optionally world ->
odom (the truth) and the URDF's moving joints; the static frames (footprint,
sensor mounts, fixed joints, the camera's optical frame) once at start-up.
tf2_msgs is in every ROS install but not on PyPI: without it TF is off.
"""

import threading
from typing import FrozenSet, List, NamedTuple, Optional, Sequence, Tuple

from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, QoSProfile

from r2d2_sim.sim.settings.table import ConfigError
from r2d2_sim.sim.settings.config import SimConfig
from r2d2_sim.sim.robots.robot import Frame, Robot
from r2d2_sim.sim.robots.sensors import (
    HEAD_CAMERA_FRAME_ID, IMU_FRAME_ID, LASER_FRAME_ID, LIDAR3D_FRAME_ID)
from r2d2_sim.ros.mirror import demand
from r2d2_sim.ros.notices import warn_once
from r2d2_sim.ros.serialization import MessageTemplate
from r2d2_sim.model.timing import stamp_of
from r2d2_sim.model.link_tree import LinkTransforms, parse_joints, root_link
from r2d2_sim.model.transforms import (
    compose, IDENTITY, inverse, normalised, Transform, yaw_to_quaternion)

__all__ = ['TF_QOS', 'TF_STATIC_QOS', 'TfOutput', 'start_tf', 'link_transforms',
           'static_transforms', 'publish_static_transforms', 'tf_topics', 'UrdfTree',
           'urdf_tree', 'check_urdf_frames']

# As tf2's TransformBroadcaster and StaticTransformBroadcaster set them.
TF_QOS = QoSProfile(depth=100)
TF_STATIC_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def tf_topics(config: SimConfig) -> Tuple[str, str]:
    """Return the robot's TF topics: ``/tf`` and ``/tf_static``, or relative (namespaced)."""
    return ('tf', 'tf_static') if config.tf_layout == 'namespaced' else ('/tf', '/tf_static')


class TfOutput:
    """
    ``/tf`` each state publication: odom -> base_footprint from wheel odometry.

    Optionally world -> odom, so that the chain world -> odom -> base_footprint
    -> base_link is the body frame's true pose (height and tilt too; world ->
    base_footprint for a robot without wheels, which has no odom), and
    the robot's moving joints (parent -> child link, as robot_state_publisher
    would publish them). All transforms carry the frame's stamp: the same as
    that step's odom message, so no sensor message is newer than its transform.
    """

    def __init__(self, node: Node, config: SimConfig, robot: Robot,
                 links: Optional[LinkTransforms]) -> None:
        from tf2_msgs.msg import TFMessage  # optional: the node checks it is importable
        self._publisher = node.create_publisher(TFMessage, tf_topics(config)[0], TF_QOS)
        frame = config.frame
        pairs = []
        self._odometry = robot.controller is not None
        if self._odometry:
            pairs.append((frame(config.odom_frame_id), frame(config.footprint_frame_id)))
        # The truth goes in world -> odom; a robot without wheels has no odom (and once got
        # no world at all, silently): its truth goes in world -> footprint.
        self._truth = config.publish_ground_truth_tf
        if self._truth:
            below_world = config.odom_frame_id if self._odometry else config.footprint_frame_id
            pairs.append((config.world_frame_id, frame(below_world)))
        # The static footprint -> base on /tf_static, undone to place the footprint.
        self._base_to_footprint = inverse(
            Transform((0.0, 0.0, robot.footprint_height_m), IDENTITY.rotation))
        self._links = links
        self._joint_slots = []
        if links is not None:
            index = {j.name: i for i, j in enumerate(robot.movable)}
            self._joint_slots = [index[name] for name in links.moving_joint_names]
            pairs += [(frame(j.parent_link), frame(j.child_link))
                      for j in links.moving([0.0] * len(self._joint_slots))]
        msg = TFMessage(transforms=[_transform_stamped(parent, child, IDENTITY)
                                    for parent, child in pairs])
        self._template = MessageTemplate(msg)
        self._stamps = [self._template.stamp(f'transforms[{i}].header.stamp')
                        for i in range(len(pairs))]
        self._transforms = [self._template.field(f'transforms[{i}].transform')
                            for i in range(len(pairs))]
        self.empty = not pairs
        self._demand = demand(self._publisher)
        # The latest frame, and its /tf serialized once someone asked (see latest).
        self._frame: Optional[Frame] = None
        self._latest: Optional[bytes] = None
        # A harness may read latest on its test's thread while an executor thread steps
        # (~/step): the template is patched by one of them at a time, from one frame.
        self._lock = threading.Lock()

    @property
    def latest(self) -> Optional[bytes]:
        """
        Return the latest /tf published (serialized), None before the first.

        For a listener in this process that starts later: a harness reads it
        here rather than listen to every publication. Built when asked if
        nobody subscribed to /tf when it was published.
        """
        with self._lock:
            if self._latest is None and self._frame is not None:
                self._latest = self._serialized(self._frame)
            return self._latest

    def publish(self, frame: Frame) -> None:
        """Publish the frame's transforms (to nobody: keep the frame for :attr:`latest`)."""
        with self._lock:
            self._frame = frame
            if not self._demand():
                self._latest = None
                return
            data = self._latest = self._serialized(frame)
        self._publisher.publish(data)

    def _serialized(self, frame: Frame) -> bytes:
        stamp = frame.stamp
        for slot in self._stamps:
            slot.set(*stamp)
        slots = iter(self._transforms)
        odom = None
        if self._odometry:
            odometry = frame.odometry
            assert odometry is not None, 'a robot with wheels measures odometry'
            odom = Transform((odometry.x_m, odometry.y_m, 0.0),
                             yaw_to_quaternion(odometry.yaw_rad))
            next(slots).set(odom.translation + odom.rotation)
        if self._truth:
            # The whole true pose, height and tilt too: the chain down to the body frame
            # (world -> odom -> footprint -> base) then ends where ground_truth says.
            # PyBullet's quaternion is off unit by up to ~1e-8, enough to move the footprint's
            # 0.47 m offset by 2e-8 m: tf2 normalises what it receives, so normalise first.
            base = frame.base
            footprint = compose(Transform(base.position, normalised(base.orientation)),
                                self._base_to_footprint)
            below = footprint if odom is None else compose(footprint, inverse(odom))
            next(slots).set(below.translation + below.rotation)
        if self._links is not None:
            positions = frame.joints.positions
            for joint in self._links.moving([positions[i] for i in self._joint_slots]):
                next(slots).set(joint.transform.translation + joint.transform.rotation)
        return self._template.to_bytes()


def start_tf(node: Node, config: SimConfig, robot: Robot, time_ns: int) -> Optional[TfOutput]:
    """
    Publish /tf_static once and return the /tf output (None if it has nothing to publish).

    A URDF link named like a frame of the node's own is a ConfigError (one
    line, :func:`check_urdf_frames`), tf2_msgs or not. tf2_msgs is in every
    ROS install but not on PyPI: without it, say so once and return None;
    everything else works.
    """
    check_urdf_frames(config, robot, urdf_tree(robot))
    try:
        import tf2_msgs.msg  # noqa: F401  (a pip-only venv: tools/build_tf2_msgs.sh)
    except ImportError:
        warn_once(node.get_logger(),
                  'tf2_msgs is not installed: /tf and /tf_static are off (a pip-only venv '
                  'gets it from tools/build_tf2_msgs.sh VENV); everything else works')
        return None
    links = link_transforms(config, robot) if config.publish_link_tf else None
    publish_static_transforms(node, static_transforms(config, robot, links), stamp_of(time_ns),
                              tf_topics(config)[1])
    tf = TfOutput(node, config, robot, links)
    return None if tf.empty else tf


def link_transforms(config: SimConfig, robot: Robot) -> LinkTransforms:
    """Return the robot's URDF link transforms, moving joints in the joint readout's order."""
    try:
        return LinkTransforms(robot.description, [j.name for j in robot.movable])
    except ValueError as exc:
        raise ConfigError(f'publish_link_tf: {exc}') from None


class UrdfTree(NamedTuple):
    """The frames a URDF gives TF: its root link, and every link a joint names."""

    root: Optional[str]  # None for a URDF without joints (robot_state_publisher: no frame)
    links: FrozenSet[str]


def urdf_tree(robot: Robot) -> UrdfTree:
    """Return the root link and the linked links of the robot's URDF (ConfigError if broken)."""
    try:
        joints = parse_joints(robot.description)
        root = root_link(joints) if joints else None
    except ValueError as exc:
        raise ConfigError(f'the robot description: {exc}') from None
    return UrdfTree(root, frozenset(link for joint in joints
                                    for link in (joint.parent_link, joint.child_link)))


def check_urdf_frames(config: SimConfig, robot: Robot, tree: UrdfTree) -> None:
    """
    Refuse (ConfigError, one line) a URDF link named like a frame the node publishes itself.

    robot_state_publisher (or ``publish_link_tf``) publishes every URDF link
    but the root as a joint's child; the node publishes odom, the footprint,
    the body frame (``base_frame_id``) and each sensor's frame on its own. A
    URDF with a link of one of those names (a TurtleBot3's ``base_footprint``
    root, its ``base_link``, ``base_scan``, ``imu_link``) would give that frame
    two parents, or close a loop, and tf2 answers with one or the other. The
    one frame both may name is the URDF's root as ``base_frame_id``, when
    the root is not turned from the body frame (``base_forward_axis`` x):
    the node then hangs the URDF there instead of below it.
    """
    root, links = tree
    base = config.base_frame_id
    if root == base and config.body_yaw_offset_rad:
        raise ConfigError(
            f'parameter base_frame_id names the URDF\'s root link {root!r}, which '
            f'base_forward_axis {config.base_forward_axis} turns from the body frame: TF would '
            f'have two frames {root!r}; give base_frame_id another name (the classic R2D2\'s '
            'urdf/classic_r2d2.yaml says base_body)')
    if not links:
        return
    ours = [(config.footprint_frame_id, 'parameter footprint_frame_id'),
            (base, 'parameter base_frame_id')]
    if robot.controller is not None:  # odometry: odom -> footprint, world -> odom
        ours.insert(0, (config.odom_frame_id, 'parameter odom_frame_id'))
    for sensor, frame_id, what in (
            (robot.laser, LASER_FRAME_ID, "the laser's frame: scan_rate > 0"),
            (robot.lidar, LIDAR3D_FRAME_ID, "the 3D lidar's frame: lidar3d_rate > 0"),
            (robot.imu, IMU_FRAME_ID, "the IMU's frame: imu_rate > 0"),
            (robot.camera, HEAD_CAMERA_FRAME_ID, "the camera's optical frame: camera_rate > 0")):
        if sensor is not None:
            ours.append((frame_id, what))
    clashes = [f'{frame_id!r} ({what})' for frame_id, what in ours
               if frame_id in links and not (frame_id == root == base)]
    world = config.world_frame_id
    if config.publish_ground_truth_tf:
        clashes += [f'{link!r} (parameter world_frame_id, with frame_prefix)'
                    for link in sorted(links) if config.frame(link) == world]
    if clashes:
        hint = (f'; base_frame_id may name the URDF\'s root link {root!r}'
                if root is not None and root != base else '')
        raise ConfigError(
            f'the URDF has links named like frames the node publishes itself, which would give '
            f'TF two parents or a loop: {", ".join(clashes)}; rename those links, or change '
            f'those parameters (a rate of 0 turns a sensor off){hint}')


def static_transforms(config: SimConfig, robot: Robot,
                      links: Optional[LinkTransforms]) -> List[Tuple[str, str, Transform]]:
    """
    Return the frames that never move, for ``/tf_static``: (parent, child, transform).

    base_footprint -> base_link (the body frame's height at rest; a frame of
    the node's own, not a URDF link, so the robot keeps the tutorial's 15
    joints and PyBullet gets no extra body), the sensor mounts, the URDF's
    fixed joints when link transforms are on, and the head camera's optical
    frame (z forward, x right, y down) on the head link. When the URDF's root
    link is not ``base_frame_id``, base_frame_id -> root (turned as
    ``base_forward_axis`` says), link transforms or not: robot_state_publisher
    hangs every other link from the root.
    """
    frame = config.frame
    base = frame(config.base_frame_id)
    result = [(frame(config.footprint_frame_id), base,
               Transform((0.0, 0.0, robot.footprint_height_m), IDENTITY.rotation))]
    if robot.laser is not None:
        result.append((base, frame(LASER_FRAME_ID), robot.laser.mount))
    if robot.lidar is not None:
        result.append((base, frame(LIDAR3D_FRAME_ID), robot.lidar.mount))
    if robot.imu is not None:
        result.append((base, frame(IMU_FRAME_ID), IDENTITY))
    # The URDF base, turned from the body; a URDF without joints names none.
    root = links.root_link if links is not None else urdf_tree(robot).root
    if root is not None and root != config.base_frame_id:
        result.append((base, frame(root), Transform(
            (0.0, 0.0, 0.0), yaw_to_quaternion(-config.body_yaw_offset_rad))))
    if links is not None:
        result += [(frame(j.parent_link), frame(j.child_link), j.transform) for j in links.fixed()]
    if robot.camera is not None:
        # Not a URDF link, so robot_state_publisher never publishes it: always ours.
        result.append((frame(robot.camera.link_name), frame(HEAD_CAMERA_FRAME_ID),
                       robot.camera.optical_mount))
    return result


def publish_static_transforms(node: Node, transforms: Sequence[Tuple[str, str, Transform]],
                              stamp: Tuple[int, int], topic: str = '/tf_static') -> Publisher:
    """Publish ``topic`` once, transient local for late subscribers; return its publisher."""
    # The publisher stays alive with the node (rclpy keeps it), so late joiners get it.
    from tf2_msgs.msg import TFMessage
    publisher = node.create_publisher(TFMessage, topic, TF_STATIC_QOS)
    msg = TFMessage(transforms=[_transform_stamped(p, c, t, stamp) for p, c, t in transforms])
    publisher.publish(msg)
    return publisher


def _transform_stamped(parent: str, child: str, transform: Transform,
                       stamp: Tuple[int, int] = (0, 0)) -> TransformStamped:
    msg = TransformStamped()
    msg.header.frame_id, msg.child_frame_id = parent, child
    msg.header.stamp.sec, msg.header.stamp.nanosec = stamp
    t, r = msg.transform.translation, msg.transform.rotation
    t.x, t.y, t.z = transform.translation
    r.x, r.y, r.z, r.w = transform.rotation
    return msg
