"""
The PyBullet world: one robot (and any extra bodies) on a plane, at a fixed time step.

No ROS here. The world owns its own physics client (never the module-global
``pybullet`` state), so several worlds can live in one process and tests can
build and tear down their own. Joints are looked up by name into
:class:`JointRecord` entries; nothing indexes PyBullet's tuples elsewhere.
"""

from dataclasses import dataclass
from functools import partial
import math
from typing import Dict, List, NamedTuple, Optional, Sequence, Tuple

import numpy

from r2d2_sim.stdio import silenced_output

with silenced_output():  # PyBullet prints its build time on import
    import pybullet
import pybullet_data  # noqa: I100 (imported after pybullet on purpose)
from pybullet_utils.bullet_client import BulletClient

from r2d2_sim.description import (
    check_urdf_xml, default_urdf_path, DescriptionError, DescriptionFile, read_description,
    resolve_description_path)
from r2d2_sim.errors import SetupError

Vec3 = Tuple[float, float, float]
Quat = Tuple[float, float, float, float]

JOINT_TYPE_NAMES = {
    pybullet.JOINT_REVOLUTE: 'revolute',
    pybullet.JOINT_PRISMATIC: 'prismatic',
    pybullet.JOINT_SPHERICAL: 'spherical',
    pybullet.JOINT_PLANAR: 'planar',
    pybullet.JOINT_FIXED: 'fixed',
    pybullet.JOINT_POINT2POINT: 'point2point',
    pybullet.JOINT_GEAR: 'gear',
}

# Gap left between the lowest point of the robot and the ground at spawn, so
# that it starts just above the plane instead of interpenetrating it.
SPAWN_CLEARANCE_M = 0.001
# Beyond these the state is absurd rather than physical: the robot was flung
# off the world or the solver diverged. R2D2 drives at 1.75 m/s at most, and
# Bullet caps body speeds at 100 (m/s or rad/s), so an explosion saturates there.
MAX_DISTANCE_M = 1.0e4
MAX_LINEAR_SPEED_M_S = 50.0
MAX_ANGULAR_SPEED_RAD_S = 50.0


class WorldError(SetupError, RuntimeError):
    """A robot description or world setting that cannot be simulated."""


@dataclass(frozen=True)
class ExtraModel:
    """Another body in the world: a description reference and its spawn position."""

    description: str
    position: Vec3


@dataclass(frozen=True)
class JointRecord:
    """The 17 attributes PyBullet's ``getJointInfo`` reports for a joint."""

    index: int
    name: str
    type_code: int
    q_index: int
    u_index: int
    flags: int
    damping: float
    friction: float
    lower_limit: float
    upper_limit: float
    max_force: float
    max_velocity: float
    link_name: str
    axis: Vec3
    parent_frame_position: Vec3
    parent_frame_orientation: Quat
    parent_index: int

    @classmethod
    def from_info(cls, info: Sequence) -> 'JointRecord':
        """Build a record from the tuple ``getJointInfo`` returns."""
        (index, name, type_code, q_index, u_index, flags, damping, friction,
         lower, upper, max_force, max_velocity, link_name, axis, parent_pos,
         parent_orn, parent_index) = info
        return cls(
            index=index, name=name.decode('utf-8'), type_code=type_code,
            q_index=q_index, u_index=u_index, flags=flags, damping=damping,
            friction=friction, lower_limit=lower, upper_limit=upper,
            max_force=max_force, max_velocity=max_velocity,
            link_name=link_name.decode('utf-8'), axis=tuple(axis),
            parent_frame_position=tuple(parent_pos),
            parent_frame_orientation=tuple(parent_orn),
            parent_index=parent_index)

    @property
    def type_name(self) -> str:
        """Return the joint type as a word (``revolute``, ``fixed``, ...)."""
        return JOINT_TYPE_NAMES.get(self.type_code, 'unknown')

    @property
    def movable(self) -> bool:
        """Return True for joints with one degree of freedom (not fixed)."""
        return self.type_code in (pybullet.JOINT_REVOLUTE, pybullet.JOINT_PRISMATIC)


class BaseState(NamedTuple):
    """Pose of the base link frame in the world and its twist in that frame."""

    position: Vec3
    orientation: Quat
    linear_velocity: Vec3
    angular_velocity: Vec3


class JointStates(NamedTuple):
    """Positions, velocities and applied efforts of a list of joints (read every step)."""

    positions: Sequence[float]
    velocities: Sequence[float]
    efforts: Sequence[float]


def _format(values: Sequence[float]) -> str:
    return '(' + ', '.join(f'{v:.4g}' for v in values) + ')'


def _rotate_transposed(matrix: Sequence[float], v: Sequence[float]) -> Vec3:
    """Multiply the transpose of a row-major 3x3 matrix by a vector."""
    return (matrix[0] * v[0] + matrix[3] * v[1] + matrix[6] * v[2],
            matrix[1] * v[0] + matrix[4] * v[1] + matrix[7] * v[2],
            matrix[2] * v[0] + matrix[5] * v[1] + matrix[8] * v[2])


class SimWorld:
    """
    A PyBullet world holding one robot, stepped at a fixed time step.

    The robot is spawned at ``initial_pose`` (x, y, yaw) with its lowest point
    just above the ground, and that state is saved so :meth:`reset` can restore
    it exactly (positions, velocities and contact caches).

    ``body_yaw_offset_rad`` is the yaw from the URDF base frame to the robot's
    REP-103 body frame (x forward, y left): +pi/2 for a robot that drives
    along its base +y. Base states and ``initial_pose`` use the body frame.
    """

    def __init__(self, urdf_path: Optional[str] = None, *, gui: bool = False,
                 time_step_s: float = 1.0 / 240.0,
                 gravity_m_s2: Vec3 = (0.0, 0.0, -9.8),
                 ground_plane: bool = True,
                 initial_pose: Tuple[float, float, float] = (0.0, 0.0, 0.0),
                 robot_description: str = '',
                 body_yaw_offset_rad: float = 0.0,
                 extra_models: Sequence[ExtraModel] = ()) -> None:
        if not (math.isfinite(time_step_s) and time_step_s > 0.0):
            raise WorldError(f'time step must be a positive number of seconds, got {time_step_s}')
        self.time_step_s = time_step_s
        self.gui = gui
        self.body_yaw_offset_rad = body_yaw_offset_rad
        self._description_file: Optional[DescriptionFile] = None
        self._client = None
        try:
            if robot_description:
                self._description_file = DescriptionFile(robot_description)
                self.urdf_path = self._description_file.path
                self.robot_description = robot_description
            else:
                self.urdf_path = (resolve_description_path(urdf_path) if urdf_path
                                  else default_urdf_path())
                self.robot_description = read_description(self.urdf_path)
                check_urdf_xml(self.robot_description, self.urdf_path)
            extra_paths = [resolve_description_path(m.description) for m in extra_models]
        except DescriptionError as exc:
            self.close()
            raise WorldError(str(exc)) from None
        # 'argv[0]=' on every connect, on stdout; why a GUI cannot open goes to stderr.
        with silenced_output(stderr=False):
            self._client = BulletClient(
                connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        try:
            self._setup(gravity_m_s2, ground_plane, initial_pose)
            self.extra_model_ids = [self._load(path, m.position)
                                    for path, m in zip(extra_paths, extra_models)]
            self._initial_state = self._client.saveState()
        except Exception:
            self.close()
            raise

    def _load(self, path: str, position: Vec3, orientation: Quat = (0.0, 0.0, 0.0, 1.0),
              flags: int = 0) -> int:
        try:
            return self._client.loadURDF(path, basePosition=position,
                                         baseOrientation=orientation, flags=flags)
        except self._client.error as exc:
            raise WorldError(f'PyBullet cannot load {path}: {exc}') from None

    def _setup(self, gravity: Vec3, ground_plane: bool,
               initial_pose: Tuple[float, float, float]) -> None:
        client = self._client
        client.resetSimulation()
        client.setAdditionalSearchPath(pybullet_data.getDataPath())
        client.setTimeStep(self.time_step_s)
        client.setGravity(*gravity)
        # Bullet's cone friction makes skid-steered wheels creep into a turn over
        # seconds (measured: 0.04 -> 0.11 rad/s for a 0.5 rad/s command); the
        # classic pyramid model reaches a steady yaw rate within 0.1 s.
        client.setPhysicsEngineParameter(enableConeFriction=0)
        if self.gui:
            client.configureDebugVisualizer(client.COV_ENABLE_GUI, 0)
        self.plane_id = client.loadURDF('plane.urdf') if ground_plane else None
        x, y, yaw = initial_pose
        orientation = client.getQuaternionFromEuler(
            (0.0, 0.0, yaw - self.body_yaw_offset_rad))
        # True cylinders roll smoothly; the default turns them into faceted
        # convex hulls that make wheels bump along.
        self.robot_id = self._load(
            self.urdf_path, (x, y, 0.0), orientation,
            flags=client.URDF_USE_INERTIA_FROM_FILE | client.URDF_USE_IMPLICIT_CYLINDER)
        lowest_z = min(self._client.getAABB(self.robot_id, link)[0][2]
                       for link in range(-1, client.getNumJoints(self.robot_id)))
        position, _ = client.getBasePositionAndOrientation(self.robot_id)
        client.resetBasePositionAndOrientation(
            self.robot_id, (position[0], position[1],
                            position[2] - lowest_z + SPAWN_CLEARANCE_M), orientation)
        self.joints: Dict[str, JointRecord] = {}
        for index in range(client.getNumJoints(self.robot_id)):
            record = JointRecord.from_info(client.getJointInfo(self.robot_id, index))
            self.joints[record.name] = record
        dynamics = client.getDynamicsInfo(self.robot_id, -1)
        self._base_inertial_inverse = client.invertTransform(dynamics[3], dynamics[4])
        # Centre of mass -> body frame (the URDF base frame turned by the yaw
        # offset), composed once: one multiplyTransforms per base_state.
        self._com_to_body = client.multiplyTransforms(
            *self._base_inertial_inverse, (0.0, 0.0, 0.0),
            client.getQuaternionFromEuler((0.0, 0.0, self.body_yaw_offset_rad)))
        self.base_link_name = client.getBodyInfo(self.robot_id)[0].decode('utf-8')
        self.step_count = 0
        self._bind_hot_path()

    def _bind_hot_path(self) -> None:
        # BulletClient.__getattr__ builds a new functools.partial (after an
        # inspect.isbuiltin check) on every call: ~1 us each, 11 calls per
        # published step. Bind the per-step queries once instead.
        cid = self._client._client
        robot = self.robot_id
        self._step_simulation = partial(pybullet.stepSimulation, physicsClientId=cid)
        self._get_joint_states = partial(pybullet.getJointStates, robot, physicsClientId=cid)
        self._get_base_pose = partial(pybullet.getBasePositionAndOrientation, robot,
                                      physicsClientId=cid)
        self._get_base_velocity = partial(pybullet.getBaseVelocity, robot, physicsClientId=cid)
        self._multiply_transforms = partial(pybullet.multiplyTransforms, physicsClientId=cid)
        self._matrix_from_quaternion = partial(pybullet.getMatrixFromQuaternion,
                                               physicsClientId=cid)

    @property
    def client(self) -> BulletClient:
        """Return the PyBullet client of this world (for advanced use)."""
        return self._client

    @property
    def sim_time_s(self) -> float:
        """Return the simulated time since start, in seconds."""
        return self.step_count * self.time_step_s

    def joint(self, name: str) -> JointRecord:
        """Return the joint named ``name`` or raise WorldError listing the known ones."""
        try:
            return self.joints[name]
        except KeyError:
            raise WorldError(
                f'no joint named {name!r}; the robot has: {", ".join(self.joints)}') from None

    def movable_joints(self) -> List[JointRecord]:
        """Return the joints with a degree of freedom, in index order."""
        return [j for j in self.joints.values() if j.movable]

    def step(self, steps: int = 1) -> None:
        """Advance the physics by ``steps`` fixed time steps."""
        step_simulation = self._step_simulation
        for _ in range(steps):
            step_simulation()
        self.step_count += steps

    def set_joint_velocities(self, indices: Sequence[int], velocities: Sequence[float],
                             max_forces: Sequence[float]) -> None:
        """Drive joints with velocity motors (target rad/s or m/s, force limit N or N m)."""
        self._client.setJointMotorControlArray(
            self.robot_id, list(indices), pybullet.VELOCITY_CONTROL,
            targetVelocities=list(velocities), forces=list(max_forces))

    def set_wheel_lateral_friction(self, indices: Sequence[int], ratio: float) -> None:
        """
        Give wheels less grip along their axle than along their rolling direction.

        ``ratio`` scales friction along the wheel cylinder's axis (its shape z).
        Four fixed wheels can only turn by skidding sideways; with equal grip in
        all directions R2D2 stick-slips through turns at 52-82 % of the ideal
        yaw rate; at 0.35 it turns steadily at 90-95 % for any wheel speed
        while still resisting sideslip in arcs (lower ratios skid outwards).
        """
        if not (math.isfinite(ratio) and 0.0 < ratio <= 1.0):
            raise WorldError(f'wheel lateral friction ratio must be in (0, 1], got {ratio}')
        for index in indices:
            self._client.changeDynamics(self.robot_id, index,
                                        anisotropicFriction=(1.0, 1.0, ratio))

    def joint_states(self, indices: Sequence[int]) -> JointStates:
        """Read the joints' positions, velocities and applied motor efforts in one query."""
        if not indices:
            return JointStates(positions=[], velocities=[], efforts=[])
        positions, velocities, _, efforts = zip(*self._get_joint_states(indices))
        return JointStates(positions, velocities, efforts)

    def base_state(self) -> BaseState:
        """
        Return the true pose of the body frame and its twist in that frame.

        PyBullet reports the base's centre of mass; this converts to the URDF
        base link frame turned by ``body_yaw_offset_rad`` (the REP-103 body
        frame) and expresses both velocities in it, as ROS odometry does.
        """
        com_position, com_orientation = self._get_base_pose()
        position, orientation = self._multiply_transforms(
            com_position, com_orientation, *self._com_to_body)
        linear, angular = self._get_base_velocity()
        # Velocity of the link origin: v_com + w x (p_origin - p_com).
        rx, ry, rz = (position[0] - com_position[0], position[1] - com_position[1],
                      position[2] - com_position[2])
        wx, wy, wz = angular
        linear = (linear[0] + wy * rz - wz * ry,
                  linear[1] + wz * rx - wx * rz,
                  linear[2] + wx * ry - wy * rx)
        rotation = self._matrix_from_quaternion(orientation)
        return BaseState(position, orientation, _rotate_transposed(rotation, linear),
                         _rotate_transposed(rotation, angular))

    def link_positions_in_base(self, link_indices: Sequence[int]) -> List[Vec3]:
        """Return the link frames' origins expressed in the body frame."""
        client = self._client
        base = self.base_state()
        rotation = client.getMatrixFromQuaternion(base.orientation)
        result = []
        for link in link_indices:
            world = client.getLinkState(self.robot_id, link)[4]
            offset = tuple(world[i] - base.position[i] for i in range(3))
            result.append(_rotate_transposed(rotation, offset))
        return result

    def link_index(self, link_name: str) -> int:
        """Return the index of the link named ``link_name`` (-1 for the base)."""
        if link_name == self.base_link_name:
            return -1
        for joint in self.joints.values():
            if joint.link_name == link_name:
                return joint.index
        names = [self.base_link_name] + [j.link_name for j in self.joints.values()]
        raise WorldError(f'no link named {link_name!r}; the robot has: {", ".join(names)}')

    def link_pose(self, link_index: int) -> Tuple[Vec3, Quat]:
        """Return the world position and orientation of a link frame (-1: base link)."""
        if link_index < 0:
            com_position, com_orientation = self._client.getBasePositionAndOrientation(
                self.robot_id)
            return self._client.multiplyTransforms(
                com_position, com_orientation, *self._base_inertial_inverse)
        state = self._client.getLinkState(self.robot_id, link_index,
                                          computeForwardKinematics=True)
        return tuple(state[4]), tuple(state[5])

    def link_half_extent_m(self, link_index: int) -> float:
        """Return half the largest horizontal size of a link's bounding box."""
        low, high = self._client.getAABB(self.robot_id, link_index)
        return max(high[0] - low[0], high[1] - low[1]) / 2.0

    def render(self, width_px: int, height_px: int, view: Sequence[float],
               projection: Sequence[float]) -> Tuple[bytes, numpy.ndarray]:
        """
        Render with the CPU renderer: rgb8 rows (top row first) and the raw depth buffer.

        ER_TINY_RENDERER works without a display (DIRECT mode) and gives the
        same pixels in GUI mode, so tests and headless runs see what users see.
        The depth buffer is OpenGL's non-linear d in [0, 1], shaped (height, width).
        """
        _, _, rgba, depth, _ = self._client.getCameraImage(
            width_px, height_px, viewMatrix=list(view), projectionMatrix=list(projection),
            renderer=pybullet.ER_TINY_RENDERER, flags=pybullet.ER_NO_SEGMENTATION_MASK)
        rgb = numpy.asarray(rgba, dtype=numpy.uint8).reshape(height_px, width_px, 4)[:, :, :3]
        return rgb.tobytes(), numpy.asarray(depth, dtype=float).reshape(height_px, width_px)

    def wheel_radius_m(self, joint_index: int) -> float:
        """Return the radius of a wheel from its collision shape (cylinder or sphere)."""
        for shape in self._client.getCollisionShapeData(self.robot_id, joint_index):
            geometry, dimensions = shape[2], shape[3]
            if geometry == pybullet.GEOM_CYLINDER:
                return float(dimensions[1])
            if geometry == pybullet.GEOM_SPHERE:
                return float(dimensions[0])
        raise WorldError(
            f'cannot derive a wheel radius: link {joint_index} has no cylinder or sphere '
            'collision shape (set wheel_radius)')

    def joint_info(self) -> List[dict]:
        """
        Describe every joint (its 17 attributes) and its child link.

        Link entries follow the tutorial's link analysis: mass and lateral
        friction from ``getDynamicsInfo`` and the link frame's world pose.
        """
        client = self._client
        result = []
        for joint in self.joints.values():
            dynamics = client.getDynamicsInfo(self.robot_id, joint.index)
            link_state = client.getLinkState(self.robot_id, joint.index,
                                             computeForwardKinematics=True)
            result.append({
                'index': joint.index,
                'name': joint.name,
                'type': joint.type_name,
                'type_code': joint.type_code,
                'q_index': joint.q_index,
                'u_index': joint.u_index,
                'flags': joint.flags,
                'damping': joint.damping,
                'friction': joint.friction,
                'lower_limit': joint.lower_limit,
                'upper_limit': joint.upper_limit,
                'max_force': joint.max_force,
                'max_velocity': joint.max_velocity,
                'link_name': joint.link_name,
                'axis': list(joint.axis),
                'parent_frame_position': list(joint.parent_frame_position),
                'parent_frame_orientation': list(joint.parent_frame_orientation),
                'parent_index': joint.parent_index,
                'link': {
                    'name': joint.link_name,
                    'mass': dynamics[0],
                    'lateral_friction': dynamics[1],
                    'world_position': list(link_state[4]),
                    'world_orientation': list(link_state[5]),
                },
            })
        return result

    def state_problem(self, base: Optional[BaseState] = None) -> Optional[str]:
        """
        Return None if the robot's base is finite and in bounds, else what is wrong.

        Checks ``base`` when given (no queries), else reads the centre of mass's
        pose and velocity directly (two queries, ~5 us: cheap enough for every
        step). Speeds are frame-independent, so both readings use one test.
        """
        if base is None:
            position, orientation = self._get_base_pose()
            linear, angular = self._get_base_velocity()
        else:
            position, orientation = base.position, base.orientation
            linear, angular = base.linear_velocity, base.angular_velocity
        # The usual case in one expression (NaN and inf fail every comparison);
        # a norm under a limit implies every axis under it. Else find out what.
        (x, y, z), (vx, vy, vz), (wx, wy, wz) = position, linear, angular
        if (x * x + y * y + z * z < MAX_DISTANCE_M ** 2
                and vx * vx + vy * vy + vz * vz < MAX_LINEAR_SPEED_M_S ** 2
                and wx * wx + wy * wy + wz * wz < MAX_ANGULAR_SPEED_RAD_S ** 2
                and math.isfinite(sum(orientation))):
            return None
        for label, values in (('position', position), ('orientation', orientation),
                              ('linear velocity', linear), ('angular velocity', angular)):
            if not all(map(math.isfinite, values)):
                return f'base {label} is not finite: {_format(values)}'
        if max(map(abs, position)) > MAX_DISTANCE_M:
            return f'base left the world: position {_format(position)} m'
        # Spin first: a body spun about a far axis also moves its centre fast.
        spin = math.sqrt(angular[0] ** 2 + angular[1] ** 2 + angular[2] ** 2)
        if spin > MAX_ANGULAR_SPEED_RAD_S:
            return f'base spinning at {spin:.3g} rad/s'
        speed = math.sqrt(linear[0] ** 2 + linear[1] ** 2 + linear[2] ** 2)
        if speed > MAX_LINEAR_SPEED_M_S:
            return f'base flung at {speed:.3g} m/s'
        return None

    def joint_problem(self, indices: Sequence[int], states: JointStates) -> Optional[str]:
        """Return None if the joint readout ``states`` of ``indices`` is finite, else which."""
        if math.isfinite(sum(states.positions) + sum(states.velocities)):
            return None  # a sum of finite values that overflowed is looked at below
        for values in (states.positions, states.velocities):
            if not all(map(math.isfinite, values)):
                by_index = list(self.joints)  # joints are stored in index order
                names = [by_index[i] for i, v in zip(indices, values) if not math.isfinite(v)]
                return f'joint state not finite: {", ".join(names)}'
        return None

    def set_base_state(self, position: Optional[Vec3] = None,
                       orientation: Optional[Quat] = None,
                       linear_velocity: Optional[Vec3] = None,
                       angular_velocity: Optional[Vec3] = None) -> None:
        """
        Teleport or fling the robot: world-frame pose and twist of its centre of mass.

        Values left out keep their current ones. Nothing is validated, so tests
        can inject the absurd states that :meth:`state_problem` detects.
        """
        client = self._client
        current_position, current_orientation = self._get_base_pose()
        current_linear, current_angular = self._get_base_velocity()
        client.resetBasePositionAndOrientation(
            self.robot_id, position if position is not None else current_position,
            orientation if orientation is not None else current_orientation)
        client.resetBaseVelocity(
            self.robot_id, linear_velocity if linear_velocity is not None else current_linear,
            angular_velocity if angular_velocity is not None else current_angular)

    def reset(self) -> None:
        """
        Restore the state saved at spawn: initial pose, zero velocities.

        The step counter keeps counting: simulated time never goes backwards.
        """
        self._client.restoreState(self._initial_state)

    def follow_camera(self, distance_m: float = 2.0) -> None:
        """Point the GUI camera at the robot (no-op without a window)."""
        if not self.gui:
            return
        base = self.base_state()
        yaw = math.degrees(self._client.getEulerFromQuaternion(base.orientation)[2])
        self._client.resetDebugVisualizerCamera(distance_m, yaw - 90.0, -30.0, base.position)

    def close(self) -> None:
        """Disconnect the physics client and delete temporary files; safe to call twice."""
        client = getattr(self, '_client', None)
        if client is not None:
            try:
                client.disconnect()
            except pybullet.error:
                pass
            self._client = None
        description_file = getattr(self, '_description_file', None)
        if description_file is not None:
            description_file.close()

    @property
    def connected(self) -> bool:
        """Return True while the physics client is connected."""
        return self._client is not None and self._client.isConnected()

    def __enter__(self) -> 'SimWorld':
        return self

    def __exit__(self, *exc) -> None:
        self.close()
