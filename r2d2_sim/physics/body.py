"""
One body in the PyBullet world: a loaded URDF, referred to through this object.

No ROS here. PyBullet reuses the unique id of a removed body for the next one
it loads (most recent first), so an id cached anywhere else could silently
read another body: only the :class:`Body` holds its id, and after
:meth:`Body.remove` every use raises. Each body saves its own initial state
and :meth:`Body.reset` puts it back in place (base pose and twist, joint
positions and velocities, a ball joint's rotation and spin too):
``restoreState`` of a whole world refuses to work once a body was added or
removed, and would reset every body at once.

A body also remembers how it was loaded and every lasting change made to it
since (its initial pose, friction, damping, ray groups), so a world emptied
by ``resetSimulation`` can load it again exactly (:meth:`Body.reload`): the
same object, a new id. Bullet keeps contact manifolds and the order of its
overlapping pairs from step to step, which a reset in place leaves behind;
a rebuilt world has none of them, as at start-up. :meth:`Body.reinsert`
drops them for one body without loading it again (a world restoring a saved
state does it for all).

A body is one concept, kept whole: its identity, state, motors and lasting
changes, and the read-only questions about its links (names and indices,
poses, boxes, collision shapes and mesh vertices, inertial frames) and what
it touches or comes near after a step, which the sensors' mounts, the
entities' bounds and a run's watch ask.
"""

import ctypes
from functools import partial
import math
import os
import xml.etree.ElementTree as ElementTree
from typing import (
    Any, Callable, ClassVar, Dict, List, NamedTuple, NoReturn, Optional, Sequence, Set, Tuple)

from r2d2_sim.errors import WorldError
from r2d2_sim.model.health import base_problem, joint_problem, joints_finite, twist_problem
from r2d2_sim.model.reach import FIXED, FREE, LinkReach, reach_radius, SLIDES, TURNS
from r2d2_sim.model.transforms import BaseState, in_body_frame, rotate_inverse
from r2d2_sim.physics import records
from r2d2_sim.physics.raycast import (
    BULLET_RAY_GROUP, exclude_from_rays, HIDDEN_MASK, RAY_EXCLUDED_GROUP, ray_mask, SHOWN_MASK)
from r2d2_sim.physics.records import (
    Aabb, ClosestPoints, CollisionShape, ContactPoint, Dynamics, JointRecord, JointStates,
    LinkState, Pose, Quat, Vec3)
from r2d2_sim.physics.stdio import silenced_output

with silenced_output():  # PyBullet prints its build time on import
    import pybullet
from pybullet_utils.bullet_client import BulletClient  # noqa: I100 (after the quiet import)

__all__ = ['Body', 'BodyRemoved', 'Loading', 'Motor', 'OwnFilters', 'WorldError', 'file_stamp']

ZERO: Vec3 = (0.0, 0.0, 0.0)
# Bullet's collision filters as PyBullet gives them at load (URDF2Bullet): the base link
# of a fixed base is static, every other link dynamic. (group, mask)
STATIC_FILTER = (2, -1 ^ 2)
DYNAMIC_FILTER = (1, -1)


class BodyRemoved(RuntimeError):
    """The body was removed from its world; its PyBullet id may now name another body."""


class Motor(NamedTuple):
    """The motor last set on a joint: a velocity motor, or a brake holding an angle."""

    velocity: float                # target, rad/s or m/s (0 for a brake)
    force: float                   # limit, N m or N
    held: Optional[float] = None   # the angle (rad) or position (m) a brake holds


# Joints of several degrees of freedom: a ball joint's position is a quaternion (x, y, z,
# w), its velocity an angular velocity; a planar joint's are 3 numbers each.
MULTI_DOF_JOINTS = (pybullet.JOINT_SPHERICAL, pybullet.JOINT_PLANAR)
# How each kind of joint moves its link, for a body's reach (model/reach.py): a ball turns.
_MOTIONS = {pybullet.JOINT_REVOLUTE: TURNS, pybullet.JOINT_SPHERICAL: TURNS,
            pybullet.JOINT_PRISMATIC: SLIDES, pybullet.JOINT_FIXED: FIXED}


class State(NamedTuple):
    """A body's state: its centre of mass's pose and twist (linear, angular), its joints'."""

    com: Pose
    twist: Tuple[Vec3, Vec3]
    joints: JointStates  # of the one-axis joints (Body.movable_indices)
    # Of the others that move (Body.multi_dof_indices): (position, velocity) each.
    multi_dof: Tuple[Tuple[Tuple[float, ...], Tuple[float, ...]], ...] = ()


# Its state and its joints' motors, as :meth:`Body.moment` returns them.
Moment = Tuple[State, Dict[int, Motor]]


class Loading(NamedTuple):
    """How a body was loaded (``loadURDF``'s arguments), to load it again the same way."""

    path: str
    position: Vec3
    orientation: Quat
    flags: int = 0
    file: Optional[Tuple[str, int, int]] = None  # the file read, its size and mtime_ns then


class OwnFilters(NamedTuple):
    """What a body's URDF says of its own collision filters, read when the body was loaded."""

    sets: Optional[bool]    # a <collision> sets a group or mask (None: the file was unreadable)
    unknown: str = ''       # why the file could not be read, when ``sets`` is None
    # Each link that sets them: its name, group and mask as PyBullet reads them (None: unset).
    links: Tuple[Tuple[str, Optional[int], Optional[int]], ...] = ()


def file_stamp(path: str) -> Optional[Tuple[str, int, int]]:
    """Return (path, size, mtime_ns) of a file, None if it is not there."""
    try:
        info = os.stat(path)
    except OSError:
        return None
    return path, info.st_size, info.st_mtime_ns


class Body:
    """
    A URDF loaded into a :class:`~r2d2_sim.physics.world.SimWorld`.

    ``name`` is unique in its world; ``source`` is the description it came
    from. ``body_yaw_offset_rad`` is the yaw from the URDF base frame to the
    body's REP-103 frame (x forward, y left): +pi/2 for a robot that drives
    along its base +y. Base states and poses are of that frame. ``loading``
    says how it was loaded (what :meth:`reload` does again); without it the
    body cannot be reloaded. ``own_filters``: what its file says of its own
    collision filters, read already (a twin's); else its file is read now.
    """

    # How often any body of this process was put somewhere, loaded or removed: a watch
    # that keeps the bodies around it (sim/oracles.py) makes its list again when it changed.
    any_moves: ClassVar[int] = 0

    def __init__(self, client: BulletClient, body_id: int, name: str, source: str, *,
                 body_yaw_offset_rad: float = 0.0, spawned: bool = False,
                 loading: Optional[Loading] = None,
                 own_filters: Optional[OwnFilters] = None) -> None:
        self.name = name
        self.source = source
        self.spawned = spawned
        self.body_yaw_offset_rad = body_yaw_offset_rad
        self._client = client
        self._id: Optional[int] = body_id
        self._loading = loading
        # Every lasting change since loading, in order: (method name, args, kwargs).
        self._changes: List[Tuple[str, tuple, Dict[str, Any]]] = []
        # The motor last set on each joint, for a rebuild in place: (target velocity, force,
        # the angle it holds, or None for a velocity motor).
        self._motors: Dict[int, Motor] = {}
        # The last velocity motors set, not yet in _motors (the drive sets the same wheels at
        # most steps while it ramps): joints, velocities, forces. See _motor_table.
        self._velocity_motors: Optional[Tuple[List[int], List[float], List[float]]] = None
        self._anchored: Set[int] = set()  # links whose contacts hold_joints anchored
        # What its URDF says of its collision filters: read when it is loaded, while its file
        # is there.
        self._own_filters = (own_filters if own_filters is not None
                             else _read_own_filters(loading))
        # How often the body was put somewhere, loaded or reloaded: a watch that keeps where
        # a body without joints stands (its bounds) looks again when this changed.
        self.moves = 0
        info = records.body_info(client, body_id)
        self.base_link_name = info.base_link_name
        self.urdf_name = info.name
        self.joints: Dict[str, JointRecord] = {j.name: j for j in records.joint_records(
            client, body_id)}
        self.movable_indices = [j.index for j in self.joints.values() if j.movable]
        self.multi_dof_indices = [j.index for j in self.joints.values()
                                  if j.type_code in MULTI_DOF_JOINTS]
        base = records.dynamics(client, body_id, -1)
        self.mass_kg = base.mass_kg + sum(records.dynamics(client, body_id, j.index).mass_kg
                                          for j in self.joints.values())
        self.fixed_base = base.mass_kg == 0.0
        # Static, and no joint moves a link: the body stays where it is put.
        self.rigid = self.static and not self.movable_indices and not self.multi_dof_indices
        self._base_inertial_inverse = client.invertTransform(base.inertial_position,
                                                             base.inertial_orientation)
        # Centre of mass -> body frame (the URDF base frame turned by the yaw
        # offset), composed once: one multiplyTransforms per base_state.
        self._com_to_body = client.multiplyTransforms(
            *self._base_inertial_inverse, ZERO,
            client.getQuaternionFromEuler((0.0, 0.0, body_yaw_offset_rad)))
        self._body_to_com = client.invertTransform(*self._com_to_body)
        self._bind_hot_path()
        self._initial = self._read_state()

    def _moved(self) -> None:
        """Count a placement, load or removal: in :attr:`moves` and :attr:`any_moves`."""
        self.moves += 1
        Body.any_moves += 1

    def _bind_hot_path(self) -> None:
        # BulletClient.__getattr__ builds a new functools.partial (after an
        # inspect.isbuiltin check) on every call: ~1 us each, 11 calls per
        # published step. Bind the per-step queries once instead.
        self._moved()  # a new id: loaded, reloaded or adopted
        cid = self._client._client
        body = self._id
        # Callables, not partials: once the body is removed they are _removed.
        self._get_joint_states: Callable[..., Any] = partial(
            pybullet.getJointStates, body, physicsClientId=cid)
        self._get_base_pose: Callable[..., Any] = partial(
            pybullet.getBasePositionAndOrientation, body, physicsClientId=cid)
        self._get_base_velocity: Callable[..., Any] = partial(
            pybullet.getBaseVelocity, body, physicsClientId=cid)
        self._multiply_transforms = partial(pybullet.multiplyTransforms, physicsClientId=cid)
        # The drive sets the wheels' motors at most steps while it ramps.
        self._set_motors: Callable[..., Any] = partial(
            pybullet.setJointMotorControlArray, body, physicsClientId=cid)
        # A run's watch asks these after every step (sim/oracles.py).
        self._get_contact_points: Callable[..., Any] = partial(
            pybullet.getContactPoints, body, physicsClientId=cid)
        self._get_closest_points: Callable[..., Any] = partial(
            pybullet.getClosestPoints, body, physicsClientId=cid)

    @property
    def id(self) -> int:
        """Return the PyBullet unique id, for advanced use; BodyRemoved once removed."""
        if self._id is None:
            raise BodyRemoved(f'body {self.name!r} was removed from the world')
        return self._id

    @property
    def alive(self) -> bool:
        """Return True until the body is removed."""
        return self._id is not None

    @property
    def static(self) -> bool:
        """Return True for a body that does not move (a fixed base, or no mass at all)."""
        return self.fixed_base or self.mass_kg == 0.0

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
        return in_body_frame(self.world_state())

    def world_pose(self) -> Tuple[Vec3, Quat]:
        """Return the body frame's pose in the world: :meth:`world_state` without the twist."""
        com_position, com_orientation = self._get_base_pose()
        return self._multiply_transforms(com_position, com_orientation, *self._com_to_body)

    def com_pose(self) -> Tuple[Vec3, Quat]:
        """Return the pose of the base's centre of mass (its inertial frame): one query."""
        return self._get_base_pose()

    def pose_of_com(self, com_position: Vec3, com_orientation: Quat) -> Tuple[Vec3, Quat]:
        """Return the body frame's pose given :meth:`com_pose` (:meth:`world_pose`'s bits)."""
        return self._multiply_transforms(com_position, com_orientation, *self._com_to_body)

    @property
    def com_to_body(self) -> Tuple[Vec3, Quat]:
        """Return the body frame in the base's centre of mass frame: position, orientation."""
        return self._com_to_body

    def world_state(self) -> BaseState:
        """Return the body frame's pose and its origin's twist, both in the world frame."""
        com_position, com_orientation = self._get_base_pose()
        position, orientation = self._multiply_transforms(
            com_position, com_orientation, *self._com_to_body)
        linear, angular = self._get_base_velocity()
        # Velocity of the frame's origin: v_com + w x (p_origin - p_com).
        rx, ry, rz = (position[0] - com_position[0], position[1] - com_position[1],
                      position[2] - com_position[2])
        wx, wy, wz = angular
        return BaseState(position, orientation,
                         (linear[0] + wy * rz - wz * ry, linear[1] + wz * rx - wx * rz,
                          linear[2] + wx * ry - wy * rx), angular)

    def state_problem(self, base: Optional[BaseState] = None) -> Optional[str]:
        """
        Return None if the base is finite and in bounds, else what is wrong.

        Checks ``base`` when given (no queries), else reads the centre of mass's
        pose and velocity directly (two queries, ~5 us: cheap enough for every step).
        """
        if base is None:
            return base_problem(*self._get_base_pose(), *self._get_base_velocity())
        return base_problem(*base)

    def twist_problem(self) -> Optional[str]:
        """Return None if the base's velocity is finite and in bounds (one query, ~2 us)."""
        return twist_problem(*self._get_base_velocity())

    def finite(self) -> bool:
        """
        Return True when the base's pose and twist and every joint's state are finite.

        A body whose physics blew up with a NaN passes it, in that step,
        through its contacts to the bodies it touches (see
        :meth:`SimWorld.repair <r2d2_sim.physics.world.SimWorld.repair>`).
        """
        position, orientation = self._get_base_pose()
        linear, angular = self._get_base_velocity()
        states = self.joint_states(self.movable_indices)
        values = [*position, *orientation, *linear, *angular, *states.positions,
                  *states.velocities]
        if self.multi_dof_indices:
            multi = self._client.getJointStatesMultiDof(self.id, self.multi_dof_indices)
            values += [value for q, dq, *_ in multi for value in (*q, *dq)]
        return all(map(math.isfinite, values))

    def joint_problem(self, indices: Sequence[int], states: JointStates) -> Optional[str]:
        """Return None if the joint readout ``states`` of ``indices`` is finite, else which."""
        if joints_finite(states.positions, states.velocities):
            return None  # every publication: no names looked up
        names = [j.name for j in self.joints.values()]  # stored in index order
        return joint_problem([names[i] for i in indices], states.positions, states.velocities)

    def set_joint_velocities(self, indices: Sequence[int], velocities: Sequence[float],
                             max_forces: Sequence[float]) -> None:
        """Drive joints with velocity motors (target rad/s or m/s, force limit N or N m)."""
        if self._anchored:
            self._anchor(indices, False)
        joints, targets, forces = list(indices), list(velocities), list(max_forces)
        self._set_motors(joints, pybullet.VELOCITY_CONTROL, targetVelocities=targets,
                         forces=forces)
        pending = self._velocity_motors
        if pending is not None and pending[0] != joints:
            self._motor_table()  # other joints' motors: into the table first
        self._velocity_motors = (joints, targets, forces)

    def _motor_table(self) -> Dict[int, Motor]:
        """Return the motor last set on each joint, the pending velocity motors put in."""
        pending = self._velocity_motors
        if pending is not None:
            self._velocity_motors = None
            joints, targets, forces = pending
            self._motors.update(zip(joints, map(Motor, targets, forces)))
        return self._motors

    def hold_joints(self, indices: Sequence[int], max_forces: Sequence[float],
                    positions: Optional[Sequence[float]] = None) -> None:
        """
        Brake joints: position motors hold their angles now (or ``positions``), within the forces.

        Bullet's velocity motor keeps a speed, never an angle: at target 0 it
        lets a joint turn by what its sequential solver leaves over each
        step, in the order of the links (R2D2's parked wheels rolled backwards
        at 0.2 mm/s, its first-listed front wheels' way, whatever the weight,
        friction, ERP or wheel geometry). A position motor takes that back.
        The held links' contacts are anchored too (Bullet's friction anchors),
        so they do not slip either: friction alone, a constraint on speeds,
        let the braked robot turn by 5e-6 rad/s. :meth:`set_joint_velocities`
        lets them go.
        """
        if positions is None:
            positions = self.joint_states(indices).positions
        self._client.setJointMotorControlArray(
            self.id, list(indices), pybullet.POSITION_CONTROL, targetPositions=list(positions),
            targetVelocities=[0.0] * len(indices), forces=list(max_forces))
        self._anchor(indices, True)
        self._motor_table().update(
            (index, Motor(0.0, force, position))
            for index, force, position in zip(indices, max_forces, positions))

    def _anchor(self, links: Sequence[int], anchored: bool) -> None:
        """Anchor the friction of the links' contacts (positional, as a brake's), or free it."""
        for link in links:
            if (link in self._anchored) != anchored:
                self._client.changeDynamics(self.id, link, frictionAnchor=int(anchored))
                (self._anchored.add if anchored else self._anchored.discard)(link)

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
        self._change('_change_dynamics', tuple(indices), anisotropicFriction=(1.0, 1.0, ratio))

    def drop_damping(self) -> None:
        """
        Let the body move without Bullet's default damping, as Gazebo and Isaac Sim do.

        Bullet slows every multibody by (0.04 + 0.04 |v|) v, linear and
        angular: a box thrown at 5 m/s is at 3.69 m/s after 1 s of free fall.
        """
        self._change('_change_dynamics', tuple(self.links()), linearDamping=0.0,
                     angularDamping=0.0)

    def free_joints(self) -> None:
        """
        Let the joints move as Gazebo's do: held only by their own friction, not by a motor.

        PyBullet gives every revolute and prismatic joint a velocity motor
        holding it still (a door on a hinge would not swing); this sets each
        motor's force to the joint's friction from the file (0 when none), so
        a joint turns freely against its Coulomb friction. A ball (spherical)
        joint has a motor too, holding its rotation: it gets the same.
        """
        joints = [j for j in self.joints.values() if j.movable]
        balls = [j for j in self.joints.values() if j.type_code == pybullet.JOINT_SPHERICAL]
        self._change('_free_joints', tuple(j.index for j in joints),
                     tuple(j.friction for j in joints), tuple(j.index for j in balls),
                     tuple(j.friction for j in balls))

    def _free_joints(self, indices: Sequence[int], frictions: Sequence[float],
                     balls: Sequence[int] = (), ball_frictions: Sequence[float] = ()) -> None:
        if indices:
            self.set_joint_velocities(indices, [0.0] * len(indices), frictions)
        for index, friction in zip(balls, ball_frictions):
            # A spherical joint's motor is a position motor: no stiffness and a velocity
            # gain alone make it a brake of at most the friction about each axis.
            self._client.setJointMotorControlMultiDof(
                self.id, index, pybullet.POSITION_CONTROL, targetPosition=[0.0, 0.0, 0.0, 1.0],
                targetVelocity=[0.0, 0.0, 0.0], positionGain=0.0, velocityGain=1.0,
                force=[friction] * 3)

    def _change_dynamics(self, links: Sequence[int], **dynamics: Any) -> None:
        for link in links:
            self._client.changeDynamics(self.id, link, **dynamics)

    def _change(self, method: str, *args: Any, **kwargs: Any) -> None:
        """Make a lasting change to the body by its method ``method``; remember it for reload."""
        getattr(self, method)(*args, **kwargs)
        self._changes.append((method, args, kwargs))

    def set_initial_pose(self, position: Vec3, orientation: Quat) -> None:
        """
        Place the centre of mass where the body starts, as part of loading it; save that state.

        Unlike a teleport, the placement is done again by :meth:`reload`:
        a robot set down on the ground after loading is set down the same way.
        """
        self._change('_place', tuple(position), tuple(orientation))
        self.save_initial_state()

    def _place(self, position: Vec3, orientation: Quat) -> None:
        self._moved()
        self._client.resetBasePositionAndOrientation(self.id, position, orientation)

    def set_base_state(self, position: Optional[Vec3] = None,
                       orientation: Optional[Quat] = None,
                       linear_velocity: Optional[Vec3] = None,
                       angular_velocity: Optional[Vec3] = None) -> None:
        """
        Teleport or fling the body: world-frame pose and twist of its centre of mass.

        Values left out keep their current ones. Nothing is validated, so tests
        can inject the absurd states that :meth:`state_problem` detects.
        """
        self._moved()
        current_position, current_orientation = self._get_base_pose()
        current_linear, current_angular = self._get_base_velocity()
        self._client.resetBasePositionAndOrientation(
            self.id, position if position is not None else current_position,
            orientation if orientation is not None else current_orientation)
        self._client.resetBaseVelocity(
            self.id, linear_velocity if linear_velocity is not None else current_linear,
            angular_velocity if angular_velocity is not None else current_angular)

    def set_world_state(self, position: Vec3, orientation: Quat,
                        linear_velocity: Vec3 = ZERO, angular_velocity: Vec3 = ZERO) -> None:
        """
        Place the body frame at a world pose, its origin moving with a world-frame twist.

        The inverse of :meth:`world_state`: PyBullet keeps the centre of mass,
        whose velocity is v_origin + w x (p_com - p_origin).
        """
        com_position, com_orientation = self._multiply_transforms(
            position, orientation, *self._body_to_com)
        rx, ry, rz = (com_position[0] - position[0], com_position[1] - position[1],
                      com_position[2] - position[2])
        wx, wy, wz = angular_velocity
        vx, vy, vz = linear_velocity
        self._moved()
        self._client.resetBasePositionAndOrientation(self.id, com_position, com_orientation)
        self._client.resetBaseVelocity(
            self.id, (vx + wy * rz - wz * ry, vy + wz * rx - wx * rz, vz + wx * ry - wy * rx),
            angular_velocity)

    def _read_state(self) -> State:
        com = Pose(*self._get_base_pose())
        velocity = self._get_base_velocity()
        multi_dof: Tuple[Tuple[Tuple[float, ...], Tuple[float, ...]], ...] = ()
        if self.multi_dof_indices:
            multi_dof = tuple((tuple(q), tuple(dq)) for q, dq, *_ in
                              self._client.getJointStatesMultiDof(self.id,
                                                                  self.multi_dof_indices))
        return State(com, (tuple(velocity[0]), tuple(velocity[1])),
                     self.joint_states(self.movable_indices), multi_dof)

    def save_initial_state(self) -> None:
        """Take the body's state now as the one :meth:`reset` returns to."""
        self._initial = self._read_state()

    def reset(self) -> None:
        """Put the body back in its initial state: base pose and twist, joints, at once."""
        self._put(self._initial)

    def moment(self) -> Moment:
        """Return the body's state now and its joints' motors, for :meth:`resume`."""
        return self._read_state(), dict(self._motor_table())

    def resume(self, moment: Moment) -> None:
        """
        After :meth:`reload`, put back the state and motors :meth:`moment` returned.

        Exactly: the same base pose and twist, joint positions and
        velocities (a ball joint's rotation and spin too), and motors, held
        joints at the angles they held (those set since the changes
        :meth:`reload` replays stay as they were last set).
        """
        state, motors = moment
        self._put(state)
        driven = [i for i, motor in motors.items() if motor.held is None]
        held = {i: angle for i, motor in motors.items() if (angle := motor.held) is not None}
        if driven:
            self.set_joint_velocities(driven, [motors[i].velocity for i in driven],
                                      [motors[i].force for i in driven])
        if held:
            self.hold_joints(list(held), [motors[i].force for i in held], list(held.values()))

    def _put(self, state: State) -> None:
        (position, orientation), (linear, angular), joints, multi_dof = state
        client, body = self._client, self.id
        self._moved()
        client.resetBasePositionAndOrientation(body, position, orientation)
        client.resetBaseVelocity(body, linear, angular)
        for index, q, dq in zip(self.movable_indices, joints.positions, joints.velocities):
            client.resetJointState(body, index, q, dq)
        if multi_dof:  # resetJointState takes one number: a ball joint would stay as it is
            client.resetJointStatesMultiDof(
                body, self.multi_dof_indices, targetValues=[q for q, _ in multi_dof],
                targetVelocities=[dq for _, dq in multi_dof])

    def exclude_from_rays(self, links: Optional[Sequence[int]] = None,
                          group: int = RAY_EXCLUDED_GROUP, hidden: bool = False) -> None:
        """
        Make links of the body (default: all) invisible to rays of ``group`` (see raycast).

        ``hidden``: to every ray, untested (raycast's Hidden links), until
        :meth:`show_to_rays`; the world decides when that is exact
        (``SimWorld.exclude_from_rays``).
        """
        self._change('_exclude_from_rays', None if links is None else tuple(links), group,
                     hidden)

    def _exclude_from_rays(self, links: Optional[Sequence[int]], group: int,
                           hidden: bool = False) -> None:
        exclude_from_rays(self._client, self.id, links, group, hidden)

    @property
    def hidden_ray_groups(self) -> int:
        """Return the ray groups (bits) of the links hidden from every ray; 0 when none."""
        mask = 0
        for method, args, _ in self._changes:
            if method == '_exclude_from_rays' and args[2]:
                mask |= args[1]
        return mask

    def show_to_rays(self) -> bool:
        """
        Let every ray test the links hidden from them again (their groups stay); False if none.

        Bullet re-inserts them into its broadphase (contacts found later may
        come in another order). A reload or a twin loads them shown, as if
        never hidden.
        """
        shown = False
        for i, (method, args, kwargs) in enumerate(self._changes):
            if method == '_exclude_from_rays' and args[2]:
                links, group, _ = args
                self._changes[i] = (method, (links, group, False), kwargs)
                if self._id is not None:
                    exclude_from_rays(self._client, self._id, links, group)
                shown = True
        return shown

    @property
    def sets_own_collision_filters(self) -> bool:
        """
        Return True when the URDF the body was loaded from sets collision groups or masks.

        Read from its file when the body was loaded; True too when that file
        could not be read then (unknown: treated as set, so nothing is put
        back wrongly).
        """
        return self._own_filters.sets is not False

    def rays_miss(self, group: int) -> List[str]:
        """
        Return how the URDF's own collision filters hide links from rays of ``group``.

        A robot's rays (``ray_mask(group)``, cast in Bullet's group 1) pass through a
        link whose group has no other bit than ``group``, and skip one whose mask
        lacks group 1; what hides each such link, as a phrase (after "its URDF").
        Empty: none.
        """
        missed = []
        for link, own_group, own_mask in self._own_filters.links:
            if own_group == 0:
                missed.append(f'puts link {link} in collision group 0, which no ray sees')
            elif own_group is not None and not own_group & ray_mask(group):
                missed.append(f'puts link {link} in collision group {own_group}, the one '
                              'those rays pass through (a group with another bit, such as 1, '
                              'is seen)')
            elif own_mask is not None and not own_mask & BULLET_RAY_GROUP:
                missed.append(f'gives link {link} the collision mask {own_mask}, without group '
                              f'{BULLET_RAY_GROUP}, which rays are cast in')
        return missed

    def collision_filters(self) -> Dict[int, Tuple[int, int]]:
        """
        Return each link's collision filter (group, mask) now, by link index (-1: the base).

        PyBullet's at load (the base link of a fixed base static, every other
        link dynamic), then the rays' exclusions since. WorldError for a URDF
        that sets its own (``<collision group=... mask=...>``): those are not
        followed here.
        """
        if self._own_filters.sets is None:
            raise WorldError(f'{self.name}: {self._own_filters.unknown}, so whether its URDF '
                             'sets its own collision groups (which cannot be put back) is unknown')
        if self._own_filters.sets:
            raise WorldError(f'{self.name} sets its own collision groups in its URDF, which '
                             'cannot be put back')
        filters = {link: DYNAMIC_FILTER for link in self.links()}
        if self.fixed_base:
            filters[-1] = STATIC_FILTER
        for method, args, _ in self._changes:
            if method == '_exclude_from_rays':
                links, group, hidden = args
                for link in self.links() if links is None else links:
                    filters[link] = (group, HIDDEN_MASK if hidden else SHOWN_MASK)
        return filters

    def reinsert(self) -> None:
        """
        Put every link into Bullet's broadphase again, with its filter: its pairs are dropped.

        With them go their contact points, and the order in which Bullet
        found them: the body is then as it was loaded, for the next step's
        pairs (see :meth:`collision_filters` for what raises).
        """
        client, body = self._client, self.id
        self._moved()  # after a restore (SimWorld.restore_state), its pose came back too
        for link, (group, mask) in self.collision_filters().items():
            client.setCollisionFilterGroupMask(body, link, group, mask)

    def remove(self) -> None:
        """Take the body out of the world; its id is forgotten (PyBullet will reuse it)."""
        if self._id is not None:
            self._client.removeBody(self._id)
            self._forget_id()

    def unloaded(self) -> None:
        """Forget the id: the world was emptied under the body (``resetSimulation``)."""
        self._forget_id()

    def _forget_id(self) -> None:
        self._id = None
        Body.any_moves += 1  # gone: a watch's list of the bodies around it is out of date
        # The bound queries hold the old id: from now on they raise instead.
        self._get_joint_states = self._get_base_pose = self._get_base_velocity = self._removed
        self._set_motors = self._removed
        # A later body may take the old id: these would read that one's contacts.
        self._get_contact_points = self._get_closest_points = self._removed

    def reload(self) -> None:
        """
        Load the body again as it was loaded, with every lasting change made to it since.

        For a world emptied by ``resetSimulation``: the body comes back in
        its initial state, as the same object with a new id (or a removed
        body comes back). WorldError (one line) when it is loaded already,
        was never loaded from a file, or its file cannot be loaded as it was.
        """
        if self._id is not None:
            raise WorldError(f'body {self.name!r} is in the world already')
        self._id = self._load_into(self._client)
        self._bind_hot_path()
        self._motors = {}  # a fresh load has no motors but those its changes set again
        self._velocity_motors = None
        self._anchored = set()
        for method, args, kwargs in self._changes:
            getattr(self, method)(*args, **kwargs)

    def loaded_into(self, client: BulletClient) -> 'Body':
        """
        Load the body as :meth:`reload` would, into another client; return that body.

        For a world built beside the live one (``SimWorld.build``): the new
        body has this one's name, file and lasting changes, in its initial
        state, while this one goes on in the live world until it takes the
        new body's place with :meth:`adopt`. WorldError as for :meth:`reload`.
        """
        body_id = self._load_into(client)
        twin = Body(client, body_id, self.name, self.source,
                    body_yaw_offset_rad=self.body_yaw_offset_rad, spawned=self.spawned,
                    loading=self._loading, own_filters=self._own_filters)
        for method, args, kwargs in self._changes:
            twin._change(method, *args, **kwargs)
        return twin

    def adopt(self, twin: 'Body') -> None:
        """
        Take ``twin``'s place in its client (from :meth:`loaded_into`): this object goes on there.

        A lasting change made to this body after the twin was loaded is made
        to the twin first. The twin is not to be used afterwards.
        """
        for method, args, kwargs in self._changes[len(twin._changes):]:
            twin._change(method, *args, **kwargs)
        if twin.hidden_ray_groups and not self.hidden_ray_groups:
            twin.show_to_rays()  # shown here after the twin was loaded hidden
        self._client, self._id = twin._client, twin._id
        self._motors, self._anchored = twin._motor_table(), twin._anchored
        self._velocity_motors = None
        self._bind_hot_path()

    def _load_into(self, client: BulletClient) -> int:
        """Load the body's file into ``client`` as it was loaded; return the new id."""
        loading = self._loading
        if loading is None:
            raise WorldError(f'body {self.name!r} was not loaded from a file: it cannot be '
                             'loaded again')
        # Its own client hands back the copy it read first (measured: an edited file
        # reloads as it was); another reads the file anew, and a changed file would
        # no longer fit the body's joints, mass and centre of mass.
        if client is not self._client and loading.file is not None and file_stamp(
                loading.file[0]) not in (None, loading.file):
            raise WorldError(f'{self.source} changed since {self.name} was loaded from it')
        try:
            # Cached graphics shapes: half the time of a load of R2D2 (8 -> 4 ms), and
            # the same physics and camera images as without (compared bit for bit).
            body_id = client.loadURDF(
                loading.path, basePosition=loading.position, baseOrientation=loading.orientation,
                flags=loading.flags | pybullet.URDF_ENABLE_CACHED_GRAPHICS_SHAPES)
        except client.error as exc:
            raise WorldError(f'PyBullet cannot load {self.source} again: {exc}') from None
        if client.getNumJoints(body_id) != len(self.joints):
            client.removeBody(body_id)
            raise WorldError(f'{self.source} changed since {self.name} was loaded from it')
        return body_id

    def reloadable(self) -> bool:
        """Return True when :meth:`reload` can load the body as it was: its file unchanged."""
        loading = self._loading
        return (loading is not None and loading.file is not None
                and file_stamp(loading.file[0]) == loading.file)

    def _removed(self, *args: Any, **kwargs: Any) -> NoReturn:
        raise BodyRemoved(f'body {self.name!r} was removed from the world')

    # -- its links: names, poses, boxes, shapes; contacts and near points ---------------

    def link_index(self, link_name: str) -> int:
        """Return the index of the link named ``link_name`` (-1 for the base)."""
        if link_name == self.base_link_name:
            return -1
        for joint in self.joints.values():
            if joint.link_name == link_name:
                return joint.index
        names = [self.base_link_name] + [j.link_name for j in self.joints.values()]
        raise WorldError(f'no link named {link_name!r}; the robot has: {", ".join(names)}')

    def link_name(self, link: int) -> str:
        """Return the name of link ``link`` (-1: the base link)."""
        if link == -1:
            return self.base_link_name
        for joint in self.joints.values():
            if joint.index == link:
                return joint.link_name
        raise WorldError(f'{self.name} has no link {link}')

    def link_state(self, link: int) -> LinkState:
        """Return a link's world centre of mass and frame (forward kinematics now)."""
        return records.link_state(self._client, self.id, link)

    def link_pose(self, link: int) -> Tuple[Vec3, Quat]:
        """Return the world position and orientation of a link frame (-1: base link)."""
        if link < 0:
            com_position, com_orientation = self._get_base_pose()
            return self._multiply_transforms(com_position, com_orientation,
                                             *self._base_inertial_inverse)
        state = self.link_state(link)
        return state.frame_position, state.frame_orientation

    def aabb(self, link: int) -> Aabb:
        """Return the world bounding box of a link (-1: the base)."""
        return records.aabb(self._client, self.id, link)

    def links(self) -> range:
        """Return every link index of the body, the base (-1) first."""
        return range(-1, len(self.joints))

    def dynamics(self, link: int) -> Dynamics:
        """Return a link's mass, lateral friction and inertial frame (-1: the base)."""
        return records.dynamics(self._client, self.id, link)

    def bounding_box(self) -> Aabb:
        """Return the world bounding box around all of the body's links (``low[2]``: its floor)."""
        lows, highs = zip(*(self.aabb(link) for link in self.links()))
        return Aabb(tuple(map(min, zip(*lows))), tuple(map(max, zip(*highs))))

    def links_spanning_height(self, height_m: float) -> List[int]:
        """Return the links whose bounding box spans ``height_m`` now (a sensor plane)."""
        boxes = ((link, self.aabb(link)) for link in self.links())
        return [link for link, box in boxes if box.low[2] <= height_m <= box.high[2]]

    def link_positions_in_base(self, links: Sequence[int]) -> List[Vec3]:
        """Return the link frames' origins expressed in the body frame."""
        base = self.world_state()
        result = []
        for link in links:
            origin = self.link_state(link).frame_position
            offset = tuple(origin[i] - base.position[i] for i in range(3))
            result.append(rotate_inverse(base.orientation, offset))
        return result

    def collision_shapes(self, link: int) -> List[CollisionShape]:
        """Return a link's collision shapes (-1: the base), each in the link's inertial frame."""
        return records.collision_shapes(self._client, self.id, link)

    def contacts(self, ignoring: Sequence['Body'] = ()) -> List[ContactPoint]:
        """Return where this body touches others after the last step (it is ``body_a``)."""
        return records.contact_records(self._get_contact_points(),
                                       [body.id for body in ignoring if body.alive])

    def contacts_with(self, *others: 'Body') -> List[ContactPoint]:
        """Return where this body touches ``others`` after the last step (a query a pair)."""
        get = self._get_contact_points
        points = [point for other in others for point in get(other.id)]
        return records.contact_records(points) if points else []

    def closest_points(self, other: 'Body', range_m: float) -> Optional[ClosestPoints]:
        """Return this body's nearest points to ``other`` within ``range_m`` (None: farther)."""
        return records.nearest_points(self._get_closest_points(other.id, range_m))

    def inertial_pose(self, link: int) -> Tuple[Vec3, Quat]:
        """Return the world pose of a link's inertial frame (-1: the base): its shapes' frame."""
        if link < 0:
            position, orientation = self._get_base_pose()
            return tuple(position), tuple(orientation)
        state = self.link_state(link)
        return state.com_position, state.com_orientation

    def bounds(self) -> Aabb:
        """Return the world box around every link's collision box now."""
        boxes = [records.aabb(self._client, self.id, link) for link in self.links()]
        lows, highs = zip(*(box.low for box in boxes)), zip(*(box.high for box in boxes))
        (x0, y0, z0), (x1, y1, z1) = map(min, lows), map(max, highs)
        return Aabb((x0, y0, z0), (x1, y1, z1))

    def reach_m(self) -> Optional[float]:
        """
        Return a radius about the base's centre of mass that holds the body in any joint state.

        From the links as they stand now, their joints' kinds and limits (see
        :func:`~r2d2_sim.model.reach.reach_radius`); None when a joint can take a
        link anywhere (planar, or a prismatic joint without limits).
        """
        client, body = self._client, self.id
        links = []
        for joint in self.joints.values():
            motion = _MOTIONS.get(joint.type_code, FREE)
            state = client.getLinkState(body, joint.index)
            origin = tuple(state[4])
            ends: List[Vec3] = []
            if motion == SLIDES and joint.lower_limit <= joint.upper_limit:
                position = client.getJointState(body, joint.index)[0]
                # PyBullet gives the axis in the child link's inertial frame (URDF2Bullet
                # turns it by the inertial origin), not in its URDF frame.
                axis = client.rotateVector(state[1], joint.axis)
                ends = [tuple(o + a * (limit - position) for o, a in zip(origin, axis))
                        for limit in (joint.lower_limit, joint.upper_limit)]
            box = records.aabb(client, body, joint.index)
            links.append(LinkReach(joint.parent_index, motion, origin, ends, box.low, box.high))
        base = records.aabb(client, body, -1)
        return reach_radius(tuple(self._get_base_pose()[0]), base.low, base.high, links)

    def mesh_vertices(self, link: int, shape_index: int) -> List[Vec3]:
        """Return a collision mesh's vertices in its link's inertial frame (empty if none)."""
        return records.mesh_vertices(self._client, self.id, link, shape_index)

    def __repr__(self) -> str:
        return f'Body({self.name!r}, id={self._id}, source={self.source!r})'


def _read_own_filters(loading: Optional[Loading]) -> OwnFilters:
    """Read what the URDF a body was loaded from says of its own collision filters."""
    if loading is None or loading.file is None:
        return OwnFilters(False)
    path = loading.file[0]
    try:
        root = ElementTree.parse(path).getroot()
    except FileNotFoundError:
        return OwnFilters(None, f'its file {path} is gone')
    except OSError as exc:
        return OwnFilters(None, f'its file {path} cannot be read ({exc.strerror or exc})')
    except ElementTree.ParseError as exc:
        return OwnFilters(None, f'its file {path} is not XML as Python reads it ({exc})')
    sets = any(c.get('group') is not None or c.get('mask') is not None
               for c in root.iter('collision'))
    links = []
    for link in root.findall('link') if sets else ():
        # Per link, the last <collision> that sets one wins (URDF2Bullet).
        group = mask = None
        for collision in link.findall('collision'):
            if (text := collision.get('group')) is not None:
                group = _urdf_int(text)
            if (text := collision.get('mask')) is not None:
                mask = _urdf_int(text)
        if group is not None or mask is not None:
            links.append((link.get('name', ''), group, mask))
    return OwnFilters(sets, '', tuple(links))


_atof = ctypes.CDLL(None).atof
_atof.restype, _atof.argtypes = ctypes.c_double, [ctypes.c_char_p]
INT_MIN = -2 ** 31


def _urdf_int(text: str) -> int:
    """Return the int PyBullet reads ``text`` as: C's atof, turned to an int (x86's way)."""
    value = _atof(text.encode('utf-8', 'replace'))
    if not (math.isfinite(value) and INT_MIN <= value < -INT_MIN):
        return INT_MIN  # what x86 gives for a double out of an int's range
    return int(value)  # towards zero, as C does
