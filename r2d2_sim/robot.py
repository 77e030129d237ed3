"""
What the simulator needs to know about the robot in the world: its drive train and its head camera.

No ROS here. The drive train is found by joint name in the URDF: which
joints are the left and right wheels, their radius, the track between them
and their limits, each from a parameter or else derived from the URDF (and
held to the parameter's bounds either way). Problems are one-line
:class:`~r2d2_sim.parameters.ConfigError` messages naming what to set.
"""

from dataclasses import dataclass
import math
from typing import Callable, Optional, Tuple

import numpy

from r2d2_sim import camera
from r2d2_sim.kinematics import DiffDriveGeometry, TwistLimits
from r2d2_sim.parameters import (
    Bounds, ConfigError, SimConfig, WHEEL_FORCE, WHEEL_RADIUS, WHEEL_SEPARATION,
    WHEEL_VELOCITY)
from r2d2_sim.raycast import cast_rays, exclude_from_rays
from r2d2_sim.sensors import (
    ImuModel, ImuReading, linearize_depth, ranges_from_hits, ray_endpoints,
    ScanGeometry, SensorConfigError)
from r2d2_sim.transforms import (
    apply, IDENTITY, quaternion_from_rpy, quaternion_multiply, rotate, rotation_matrix,
    Transform)
from r2d2_sim.world import SimWorld, WorldError

# The head camera: its link, image frame, clipping planes, and the gap between
# the link's bounding box and the lens (so the head itself is not in view).
HEAD_CAMERA_LINK = 'head'
HEAD_CAMERA_FRAME_ID = 'head_camera_optical'
HEAD_CAMERA_NEAR_M = 0.01
HEAD_CAMERA_FAR_M = 100.0
HEAD_CAMERA_CLEARANCE_M = 0.01
# The laser (frame base_scan) sits on the body's axis this high above the
# ground: R2D2's body frame is 0.47 m up, and at 0.25 m the scan sees the
# room's 0.4 m boxes and walls. The IMU (imu_link) is at the body frame.
LASER_FRAME_ID = 'base_scan'
LASER_HEIGHT_M = 0.25
IMU_FRAME_ID = 'imu_link'


@dataclass(frozen=True)
class DriveTrain:
    """The wheel joints (left, then right) and the differential drive they make."""

    left_indices: Tuple[int, ...]
    right_indices: Tuple[int, ...]
    geometry: DiffDriveGeometry
    limits: TwistLimits
    max_force_n_m: float

    @property
    def wheel_indices(self) -> Tuple[int, ...]:
        """Return every wheel joint index, left wheels first."""
        return self.left_indices + self.right_indices


def _from_urdf(name: str, value: float, bounds: Bounds) -> float:
    """Hold a value derived from the URDF to the bounds of the parameter that overrides it."""
    try:
        return bounds.check(name, value)
    except ConfigError:
        raise ConfigError(f'the URDF gives {name.replace("_", " ")} {value:g} {bounds.unit}, '
                          f'outside [{bounds.low:g}, {bounds.high:g}]: set {name}') from None


def find_drive_train(world: SimWorld, config: SimConfig, source: str,
                     warn: Callable[[str], None]) -> Optional[DriveTrain]:
    """
    Find the wheels named in ``config`` and derive what the parameters leave at 0.

    Returns None for a robot without wheels: when it has none of the default
    wheel joints (with a warning that cmd_vel is ignored), or when both wheel
    lists are empty on a robot that has no joint named like a wheel.
    """
    names = config.left_wheel_names + config.right_wheel_names
    missing = [n for n in names if n not in world.joints]
    if names and len(missing) == len(names) and config.wheel_names_are_default:
        warn(f'{source} has none of the default wheel joints: cmd_vel is ignored')
        return None
    if missing:
        raise ConfigError(
            f'wheel joint(s) {", ".join(missing)} not in the URDF; it has: '
            f'{", ".join(world.joints)}')
    if not names:
        wheels = [j.name for j in world.joints.values()
                  if j.type_name == 'revolute' and 'wheel' in j.name.lower()]
        if wheels:
            raise ConfigError(
                'left_wheel_names and right_wheel_names are empty, but the robot drives '
                f'on wheel joints {", ".join(wheels)}: list them as left and right wheels')
        return None
    wheels = [world.joint(n) for n in names]
    for wheel in wheels:
        if wheel.type_name != 'revolute':
            raise ConfigError(f'wheel joint {wheel.name} is {wheel.type_name}, '
                              'not a revolute/continuous joint')
    left = tuple(world.joint(n).index for n in config.left_wheel_names)
    right = tuple(world.joint(n).index for n in config.right_wheel_names)
    radius = config.wheel_radius_m or _from_urdf(
        'wheel_radius', world.wheel_radius_m(left[0]), WHEEL_RADIUS)
    separation = config.wheel_separation_m or _from_urdf(
        'wheel_separation', _track_m(world, left, right), WHEEL_SEPARATION)
    urdf_velocity = min(w.max_velocity for w in wheels)
    urdf_force = min(w.max_force for w in wheels)
    if not urdf_velocity > 0.0 and not config.max_wheel_velocity_rad_s:
        raise ConfigError('the URDF gives the wheels no velocity limit: set max_wheel_velocity')
    if not urdf_force > 0.0 and not config.max_wheel_force_n_m:
        raise ConfigError('the URDF gives the wheels no effort limit: set max_wheel_force')
    geometry = DiffDriveGeometry(
        wheel_radius_m=radius,
        wheel_separation_m=separation * config.wheel_separation_multiplier,
        max_wheel_velocity_rad_s=config.max_wheel_velocity_rad_s or _from_urdf(
            'max_wheel_velocity', urdf_velocity, WHEEL_VELOCITY))
    limits = TwistLimits(
        max_linear_m_s=config.max_linear_velocity_m_s,
        max_angular_rad_s=config.max_angular_velocity_rad_s,
        max_linear_acceleration_m_s2=config.max_linear_acceleration_m_s2,
        max_angular_acceleration_rad_s2=config.max_angular_acceleration_rad_s2)
    return DriveTrain(left, right, geometry, limits, config.max_wheel_force_n_m or _from_urdf(
        'max_wheel_force', urdf_force, WHEEL_FORCE))


def _track_m(world: SimWorld, left: Tuple[int, ...], right: Tuple[int, ...]) -> float:
    """Track width: distance along the body y axis between left and right wheel centres."""
    positions = world.link_positions_in_base(left + right)
    left_y = [p[1] for p in positions[:len(left)]]
    right_y = [p[1] for p in positions[len(left):]]
    separation = sum(left_y) / len(left_y) - sum(right_y) / len(right_y)
    if separation <= 0.0:
        raise ConfigError(
            f'left wheels are not to the left of the right wheels (track {separation:.3f} m '
            'along base y): check left_wheel_names/right_wheel_names')
    return separation


class HeadCamera:
    """A pinhole camera on the head link looking forward (turning with head_swivel)."""

    def __init__(self, world: SimWorld, config: SimConfig) -> None:
        try:
            self._link = world.link_index(HEAD_CAMERA_LINK)
        except WorldError as exc:
            raise ConfigError(f'camera_rate > 0 needs a link named {HEAD_CAMERA_LINK!r}: '
                              f'{exc}') from None
        self._world = world
        self.link_name = HEAD_CAMERA_LINK
        self._lens_offset_m = world.link_half_extent_m(self._link) + HEAD_CAMERA_CLEARANCE_M
        # The optical frame (z forward, x right, y down) on the head link: the
        # lens sits ahead of the head along the robot's forward axis.
        yaw = world.body_yaw_offset_rad
        self.optical_mount = Transform(
            (self._lens_offset_m * math.cos(yaw), self._lens_offset_m * math.sin(yaw), 0.0),
            quaternion_multiply(quaternion_from_rpy(0.0, 0.0, yaw),
                                quaternion_from_rpy(-math.pi / 2, 0.0, -math.pi / 2)))
        width, height, fov = (config.camera_width_px, config.camera_height_px,
                              config.camera_fov_deg)
        self.intrinsics = camera.intrinsics(width, height, fov)
        self._projection = camera.projection_matrix(
            width, height, fov, HEAD_CAMERA_NEAR_M, HEAD_CAMERA_FAR_M)

    def render(self, depth: bool = False) -> Tuple[bytes, Optional[numpy.ndarray]]:
        """
        Render the camera's view now: rgb8 rows (top row first), and depth if asked.

        Depth is float32 metres along the optical axis (REP-118: +inf where
        nothing is within the far plane), from the same render as the image.
        """
        world = self._world
        position, orientation = world.link_pose(self._link)
        forward, up = camera.link_camera_axes(orientation, world.body_yaw_offset_rad)
        offset = self._lens_offset_m
        eye = [position[i] + offset * forward[i] for i in range(3)]
        k = self.intrinsics
        rgb, depth_buffer = world.render(k.width_px, k.height_px,
                                         camera.view_matrix(eye, forward, up), self._projection)
        if not depth:
            return rgb, None
        return rgb, linearize_depth(depth_buffer, HEAD_CAMERA_NEAR_M, HEAD_CAMERA_FAR_M)

    def render_rgb(self) -> bytes:
        """Render the camera's view now: rgb8 rows, top row first."""
        return self.render()[0]


class LaserScanner:
    """
    A planar laser scanner on the body's axis, ``LASER_HEIGHT_M`` above the ground.

    Rays start at the laser origin (REP-117 ranges are from there) and pass
    through the robot's own links that cross the scan plane (R2D2's body and
    legs), which are excluded from rays; links below or above it (wheels,
    head) keep their broadphase entries, so the physics is the same with the
    scanner on or off.
    """

    def __init__(self, world: SimWorld, config: SimConfig, footprint_height_m: float) -> None:
        try:
            self.geometry = ScanGeometry(config.scan_angle_min_rad, config.scan_angle_max_rad,
                                         config.scan_samples, config.scan_range_min_m,
                                         config.scan_range_max_m)
        except SensorConfigError as exc:
            raise ConfigError(f'laser scanner: {exc}') from None
        self._world = world
        self.mount = Transform((0.0, 0.0, LASER_HEIGHT_M - footprint_height_m), IDENTITY.rotation)
        # Each beam's full-length ray in the sensor frame, computed once (69 us a scan).
        _, ends = ray_endpoints(self.geometry, (0.0, 0.0, 0.0))
        self._rays_in_sensor = ends
        self._noise_std_m = config.scan_noise_std_m
        self._rng = numpy.random.default_rng(config.noise_seed)
        height_m = LASER_HEIGHT_M
        client, robot = world.client, world.robot_id
        crossing = [link for link in range(-1, client.getNumJoints(robot))
                    if client.getAABB(robot, link)[0][2] <= height_m
                    <= client.getAABB(robot, link)[1][2]]
        exclude_from_rays(client, robot, crossing)

    def scan(self) -> numpy.ndarray:
        """Cast the beams from where the laser is now; return REP-117 ranges (float32)."""
        world = self._world
        base = world.base_state()
        pose = Transform(base.position, base.orientation)
        origin = numpy.array(apply(pose, self.mount.translation))
        ends = origin + self._rays_in_sensor @ numpy.array(rotation_matrix(base.orientation)).T
        starts = numpy.broadcast_to(origin, ends.shape)
        return ranges_from_hits(cast_rays(world.client, starts, ends), self.geometry,
                                self._noise_std_m, self._rng)


class ImuSensor:
    """An IMU at the body frame's origin, axes along the body's (REP-145 ``imu_link``)."""

    def __init__(self, world: SimWorld, config: SimConfig) -> None:
        self._world = world
        # Its own stream of noise, so turning the scanner on does not change it.
        self.model = ImuModel(
            gravity_m_s2=config.gravity_m_s2,
            orientation_std_rad=config.imu_orientation_noise_std_rad,
            angular_velocity_std_rad_s=config.imu_angular_velocity_noise_std_rad_s,
            linear_acceleration_std_m_s2=config.imu_linear_acceleration_noise_std_m_s2,
            rng=numpy.random.default_rng([config.noise_seed, 1]))

    def read(self, time_s: float) -> ImuReading:
        """Return the reading for the body's true motion now (acceleration since the last)."""
        base = self._world.base_state()
        q = base.orientation
        return self.model.update(time_s, q, rotate(q, base.linear_velocity),
                                 rotate(q, base.angular_velocity))

    def reset(self) -> None:
        """Forget the last sample: a reset teleports the robot, which is no acceleration."""
        self.model.reset()
