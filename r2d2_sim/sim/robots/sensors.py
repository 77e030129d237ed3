"""
The robot's sensors and where they sit on it: head camera, planar laser, 3D lidar, IMU.

No ROS here. Each sensor measures the :class:`~r2d2_sim.physics.body.Body` it is
mounted on, in the world it is in, when the simulation says it is due; the
readings are plain data (bytes, arrays, tuples) that outputs only translate.
The sensors' models (ray geometry, REP-117 ranges, IMU, depth, Gazebo's noise)
are pure math in :mod:`r2d2_sim.model.sensors`, :mod:`r2d2_sim.model.camera`
and :mod:`r2d2_sim.model.noise`. Each sensor draws its noise from a stream of
its own (:func:`~r2d2_sim.model.noise.noise_generator`: the robot's
``noise_seed``, its name, the sensor), which :meth:`restart_noise` starts
again as at start-up.
"""

import math
from typing import List, NamedTuple, Optional, Sequence, TYPE_CHECKING

import numpy

from r2d2_sim.model import camera
from r2d2_sim.physics.body import Body, WorldError
# The sensors' frame ids are the parameter table's, which checks them against the others.
from r2d2_sim.sim.settings.table import (
    ConfigError, HEAD_CAMERA_FRAME_ID, HEAD_CAMERA_LINK, IMU_FRAME_ID, LASER_FRAME_ID,
    LIDAR3D_FRAME_ID)
from r2d2_sim.sim.settings.config import SimConfig
from r2d2_sim.sim.bounds import link_box
from r2d2_sim.physics.raycast import ray_mask, RayRequest
from r2d2_sim.model.noise import noise_generator, NoiseModel
from r2d2_sim.model.sensors import (
    ImuModel, ImuReading, lidar_directions, lidar_ranges, LidarGeometry, linearize_depth,
    noisy_depth, ranges_from_hits, ray_endpoints, ScanGeometry, SensorConfigError)
from r2d2_sim.model.transforms import (
    apply, BaseState, IDENTITY, quaternion_from_rpy, quaternion_multiply, rotation_matrix,
    Transform)

if TYPE_CHECKING:  # typing only
    from r2d2_sim.physics.world import SimWorld

__all__ = ['HEAD_CAMERA_LINK', 'HEAD_CAMERA_FRAME_ID', 'LASER_FRAME_ID', 'LASER_HEIGHT_M',
           'LIDAR3D_FRAME_ID', 'IMU_FRAME_ID', 'CameraImage', 'HeadCamera', 'LaserScanner',
           'Lidar3d', 'ImuSensor']

# The head camera's clipping planes, and the gap between its link's bounding
# box and the lens (so the head itself is not in view).
HEAD_CAMERA_NEAR_M = 0.01
HEAD_CAMERA_FAR_M = 100.0
HEAD_CAMERA_CLEARANCE_M = 0.01
# The laser (frame base_scan) sits on the body's axis this high above the
# ground: R2D2's body frame is 0.47 m up, and at 0.25 m the scan sees the
# room's 0.4 m boxes and walls. The IMU (imu_link) is at the body frame.
LASER_HEIGHT_M = 0.25
# The 3D lidar sits this far above the robot's highest point unless its height is set.
LIDAR3D_CLEARANCE_M = 0.05


class CameraImage(NamedTuple):
    """One render of the head camera: rgb8 rows (top row first), and depth in metres if asked."""

    rgb: bytes
    depth: Optional[numpy.ndarray]  # float32 metres along the optical axis (REP-118)


class HeadCamera:
    """A pinhole camera on the head link looking forward (turning with head_swivel)."""

    def __init__(self, world: 'SimWorld', body: Body, config: SimConfig) -> None:
        try:
            self._link = body.link_index(HEAD_CAMERA_LINK)
        except WorldError as exc:
            raise ConfigError(f'camera_rate > 0 needs a link named {HEAD_CAMERA_LINK!r}: '
                              f'{exc}') from None
        self._world = world
        self._body = body
        self.link_name = HEAD_CAMERA_LINK
        # Half the head's largest horizontal size, in its own frame (the same at any spawn yaw).
        low, high = link_box(body, self._link)
        self._lens_offset_m = (max(high[0] - low[0], high[1] - low[1]) / 2.0
                               + HEAD_CAMERA_CLEARANCE_M)
        # The optical frame (z forward, x right, y down) on the head link: the
        # lens sits ahead of the head along the robot's forward axis.
        yaw = body.body_yaw_offset_rad
        self.optical_mount = Transform(
            (self._lens_offset_m * math.cos(yaw), self._lens_offset_m * math.sin(yaw), 0.0),
            quaternion_multiply(quaternion_from_rpy(0.0, 0.0, yaw),
                                quaternion_from_rpy(-math.pi / 2, 0.0, -math.pi / 2)))
        width, height, fov = (config.camera_width_px, config.camera_height_px,
                              config.camera_fov_deg)
        # As CameraInfo publishes them: where the renderer samples each pixel.
        self.intrinsics = camera.image_intrinsics(width, height, fov)
        self._projection = camera.projection_matrix(
            width, height, fov, HEAD_CAMERA_NEAR_M, HEAD_CAMERA_FAR_M)
        self._config = config
        self._depth_noise = self._new_depth_noise()

    def _new_depth_noise(self) -> NoiseModel:
        config = self._config
        return NoiseModel(config.noise('depth'),
                          noise_generator(config.noise_seed, self._body.name, 'depth'),
                          period_s=1.0 / config.camera_rate_hz)

    def restart_noise(self, config: Optional[SimConfig] = None) -> None:
        """Start the depth noise again from its seed (``config``'s from now on, if given)."""
        if config is not None:
            self._config = config
        self._depth_noise = self._new_depth_noise()

    def render(self, depth: bool = False) -> CameraImage:
        """
        Render the camera's view now: rgb8 rows (top row first), and depth if asked.

        Depth is float32 metres along the optical axis (REP-118: +inf where
        nothing is within the far plane), from the same render as the image,
        with ``depth_noise_*`` added; with ``camera_self_filter``, NaN where
        the robot sees itself (noise is drawn for those pixels all the same).
        """
        position, orientation = self._body.link_pose(self._link)
        forward, up = camera.link_camera_axes(orientation, self._body.body_yaw_offset_rad)
        offset = self._lens_offset_m
        eye = [position[i] + offset * forward[i] for i in range(3)]
        k = self.intrinsics
        view = camera.view_matrix(eye, forward, up)
        if not depth:
            rgb, _ = self._world.render(k.width_px, k.height_px, view, self._projection)
            return CameraImage(rgb, None)
        itself = None
        if self._config.camera_self_filter:
            rgb, depth_buffer, itself = self._world.render_seeing(
                self._body, k.width_px, k.height_px, view, self._projection)
        else:
            rgb, depth_buffer = self._world.render(k.width_px, k.height_px, view,
                                                   self._projection)
        depth_m = noisy_depth(linearize_depth(depth_buffer, HEAD_CAMERA_NEAR_M, HEAD_CAMERA_FAR_M),
                              self._depth_noise, HEAD_CAMERA_NEAR_M, HEAD_CAMERA_FAR_M)
        if itself is not None:
            depth_m[itself] = numpy.nan
        return CameraImage(rgb, depth_m)


class _RaySensor:
    """
    What a ray-casting sensor on a body shares: its beams cast from its mount, its noise stream.

    A subclass sets ``_world``, ``_body``, ``_config``, ``mount`` (in the
    body frame), ``_rays_in_sensor`` (each beam's full-length end in the
    sensor frame), ``_group`` and ``_mask`` (its robot's ray group), and
    names its noise stream (``NOISE``) and rate (``RATE``, a config field).
    """

    NOISE = ''
    RATE = ''
    _world: 'SimWorld'
    _body: Body
    _config: SimConfig
    mount: Transform
    _rays_in_sensor: numpy.ndarray
    _group: int
    _mask: int
    _noise: NoiseModel

    def rays(self) -> RayRequest:
        """Return the beams from where the sensor is now, to cast with other sensors' rays."""
        base = self._body.world_state()
        pose = Transform(base.position, base.orientation)
        origin = numpy.array(apply(pose, self.mount.translation))
        ends = origin + self._rays_in_sensor @ numpy.array(rotation_matrix(base.orientation)).T
        starts = numpy.broadcast_to(origin, ends.shape)
        return RayRequest(starts, ends, self._group)

    def _cast(self) -> numpy.ndarray:
        """Cast every beam from where the sensor is now; return the hit fractions."""
        rays = self.rays()
        return self._world.cast_rays(rays.starts, rays.ends, self._mask)

    def _new_noise(self) -> NoiseModel:
        config = self._config
        return NoiseModel(config.noise(self.NOISE),
                          noise_generator(config.noise_seed, self._body.name, self.NOISE),
                          period_s=1.0 / getattr(config, self.RATE))

    def restart_noise(self, config: Optional[SimConfig] = None) -> None:
        """Start the noise stream again from its seed (``config``'s from now on, if given)."""
        if config is not None:
            self._config = config
        self._noise = self._new_noise()


class LaserScanner(_RaySensor):
    """
    A planar laser scanner on the body's axis, ``LASER_HEIGHT_M`` above the ground.

    Rays start at the laser origin (REP-117 ranges are from there) and pass
    through the robot's own links that cross the scan plane (R2D2's body and
    legs), which go into a ray group of this robot's own; links below or
    above it (wheels, head) keep their broadphase entries. Re-inserting the
    crossing links reorders the contacts Bullet finds for them: the physics
    is the same with the scanner on or off only while they touch nothing;
    once the body touches a wall or a box, the two runs part (each still
    repeats itself bit for bit). Every other robot's links stay
    visible. The group (``ray_group``, a bit of the world's) is the robot's:
    it gives it back when it leaves.
    """

    NOISE, RATE = 'scan', 'scan_rate_hz'

    def __init__(self, world: 'SimWorld', body: Body, config: SimConfig,
                 footprint_height_m: float, ray_group: int) -> None:
        try:
            self.geometry = ScanGeometry(config.scan_angle_min_rad, config.scan_angle_max_rad,
                                         config.scan_samples, config.scan_range_min_m,
                                         config.scan_range_max_m)
        except SensorConfigError as exc:
            raise ConfigError(f'laser scanner: {exc}') from None
        self._world = world
        self._body = body
        self.mount = Transform((0.0, 0.0, LASER_HEIGHT_M - footprint_height_m), IDENTITY.rotation)
        # Each beam's full-length ray in the sensor frame, computed once (69 us a scan).
        _, ends = ray_endpoints(self.geometry, (0.0, 0.0, 0.0))
        self._rays_in_sensor = ends
        self._config = config
        self._noise = self._new_noise()
        # The scan plane in the world now: the robot stands on the ground, or
        # (spawned in the air) is about to fall onto it.
        ground_z = body.world_state().position[2] - footprint_height_m
        self._group = ray_group
        self._mask = ray_mask(ray_group)
        self.excluded_links = body.links_spanning_height(ground_z + LASER_HEIGHT_M)
        world.exclude_from_rays(body, self.excluded_links, ray_group)

    def scan(self) -> numpy.ndarray:
        """Cast the beams from where the laser is now; return REP-117 ranges (float32)."""
        return self.ranges(self._cast())

    def ranges(self, fractions: numpy.ndarray) -> numpy.ndarray:
        """Return the beams' REP-117 ranges, float32 with the noise added, from hit fractions."""
        return ranges_from_hits(fractions, self.geometry, noise=self._noise)


class Lidar3d(_RaySensor):
    """
    A multi-ring lidar on the body's axis: a point per beam, in its own frame ``lidar_3d``.

    It stands ``lidar3d_height`` above the ground (by default 5 cm above the
    robot's highest point). Its beams start at its origin and pass through
    the robot's own links they could meet (those reaching into the band of
    heights the rings sweep within the robot's horizontal extent, R2D2's head
    from on top), put into the robot's ray group as the planar laser's are;
    every other robot stays visible. Rays are cast in batches of at most
    PyBullet's 16,384 per call (a 16 x 1800 lidar: two calls).
    """

    NOISE, RATE = 'lidar3d', 'lidar3d_rate_hz'

    def __init__(self, world: 'SimWorld', body: Body, config: SimConfig,
                 footprint_height_m: float, ray_group: int) -> None:
        try:
            self.geometry = LidarGeometry(config.lidar3d_rings, config.lidar3d_angle_min_rad,
                                          config.lidar3d_angle_max_rad, config.lidar3d_samples,
                                          config.lidar3d_range_min_m, config.lidar3d_range_max_m)
        except SensorConfigError as exc:
            raise ConfigError(f'3D lidar: {exc}') from None
        self._world = world
        self._body = body
        self._config = config
        base = body.world_state()
        ground_z = base.position[2] - footprint_height_m
        box = body.bounding_box()
        self.height_m = config.lidar3d_height_m or (box.high[2] - ground_z + LIDAR3D_CLEARANCE_M)
        self.mount = Transform((0.0, 0.0, self.height_m - footprint_height_m), IDENTITY.rotation)
        self.directions = lidar_directions(self.geometry)  # (rings, samples, 3), unit
        self._rays_in_sensor = self.directions.reshape(-1, 3) * self.geometry.range_max_m
        self._group = ray_group
        self._mask = ray_mask(ray_group)
        self.excluded_links = self._own_links_in_view(body, base.position, ground_z)
        world.exclude_from_rays(body, self.excluded_links, ray_group)
        self._noise = self._new_noise()

    def _own_links_in_view(self, body: Body, axis: Sequence[float], ground_z: float
                           ) -> List[int]:
        """Return the links the beams could meet within the robot's horizontal extent."""
        radius = 0.0
        for link in body.links():
            low, high = body.aabb(link)
            for x in (low[0], high[0]):
                for y in (low[1], high[1]):
                    radius = max(radius, math.hypot(x - axis[0], y - axis[1]))
        origin_z = ground_z + self.height_m
        lowest = origin_z + radius * math.tan(min(self.geometry.angle_min_rad, 0.0))
        highest = origin_z + radius * math.tan(max(self.geometry.angle_max_rad, 0.0))
        return [link for link in body.links()
                if body.aabb(link).low[2] <= highest and body.aabb(link).high[2] >= lowest]

    def scan(self) -> numpy.ndarray:
        """
        Cast every beam from where the lidar is now; return its points, (rings, samples, 3).

        float32 metres in the lidar's frame; NaN for a beam without a return
        within range or with one nearer than range_min.
        """
        return self.points(self._cast())

    def points(self, fractions: numpy.ndarray) -> numpy.ndarray:
        """Return the points of the beams' hit fractions: float32, NaN where none returned."""
        ranges = lidar_ranges(fractions, self.geometry, self._noise)
        return (self.directions * ranges[:, :, None]).astype(numpy.float32)


class ImuSensor:
    """An IMU at the body frame's origin, axes along the body's (REP-145 ``imu_link``)."""

    def __init__(self, body: Body, config: SimConfig) -> None:
        self._body = body
        self._config = config
        self.model = self._new_model()

    def _new_model(self) -> ImuModel:
        config = self._config
        return ImuModel(
            gravity_m_s2=config.gravity_m_s2,
            orientation_noise=config.noise('imu_orientation'),
            angular_velocity_noise=config.noise('imu_angular_velocity'),
            linear_acceleration_noise=config.noise('imu_linear_acceleration'),
            rng=noise_generator(config.noise_seed, self._body.name, 'imu'),
            period_s=1.0 / config.imu_rate_hz)

    def restart_noise(self, config: Optional[SimConfig] = None) -> None:
        """
        Start the noise afresh as at start-up: its stream from its seed (``config``'s, if given).

        The motion goes on: the new model keeps the last sample, so the next
        reading's acceleration is the velocity's change since it (a fresh
        model read none, as if the robot had been put back).
        """
        if config is not None:
            self._config = config
        model = self._new_model()
        model.carry_on(self.model)
        self.model = model

    def read(self, time_s: float, world: Optional[BaseState] = None) -> ImuReading:
        """
        Return the reading for the body's true motion now (acceleration since the last).

        ``world``: the body's :meth:`~r2d2_sim.physics.body.Body.world_state`
        this step, when the robot already read it (one query pair fewer).
        """
        base = world if world is not None else self._body.world_state()
        return self.model.update(time_s, base.orientation, base.linear_velocity,
                                 base.angular_velocity)

    def reset(self) -> None:
        """Forget the last sample: a reset teleports the robot, which is no acceleration."""
        self.model.reset()
