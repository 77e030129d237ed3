"""
The node's parameters in one table: name, ROS type, default, unit, bounds, description.

No ROS here. Everything else is derived from :data:`PARAMETERS`: the
:class:`~r2d2_sim.sim.settings.config.SimConfig` fields (generated, and checked
against the table) and the validation in
:func:`~r2d2_sim.sim.settings.config.parse_config` (one readable
:class:`ConfigError` line per bad value, so a bad parameter is a clear start-up
error rather than a traceback; frame ids that would break the TF tree
included), the node's typed ROS declarations, and ``sim_node --help`` and
``docs/parameters.md`` (:mod:`r2d2_sim.sim.settings.reference`). Several robots'
settings come from it in :mod:`r2d2_sim.sim.settings.robots`.
"""

import math
from typing import Any, Callable, Dict, List, NamedTuple, Optional

from r2d2_sim.sim.settings import readers as read
# ConfigError and Bounds are defined with the readers; the table's users import them here.
from r2d2_sim.sim.settings.readers import Bounds, ConfigError  # noqa: F401


# Measured on the package's own R2D2 (four wheels skid-steering, lateral
# friction ratio 0.35): it turns at 90-95 % of an ideal differential drive's
# yaw rate for wheel speeds of 1 to 10 rad/s; an effective track of 1.1 x the
# geometric 0.44 m makes a 0.5 rad/s command turn at 0.5 rad/s.
DEFAULT_WHEEL_SEPARATION_MULTIPLIER = 1.1

# Measured on the package's R2D2 (tall, 0.44 m track): a step to full speed
# (1.75 m/s, the wheels' 50 rad/s) tips it over at 3 m/s^2 and above, but not at
# 2; spinning in place it stays upright up to about 3 rad/s (7 degrees of
# wobble) and falls over at 5. The defaults keep any command on its wheels.
DEFAULT_MAX_LINEAR_ACCELERATION_M_S2 = 1.0
DEFAULT_MAX_ANGULAR_ACCELERATION_RAD_S2 = 2.0
DEFAULT_MAX_ANGULAR_VELOCITY_RAD_S = 3.0

# Yaw from the URDF base frame to the REP-103 body frame for each forward axis.
FORWARD_AXIS_YAW_RAD = {'x': 0.0, 'y': math.pi / 2, '-x': math.pi, '-y': -math.pi / 2}


# The frames of the node's own sensors (with frame_prefix in front), and the
# URDF link the head camera's frame hangs from; r2d2_sim.sim.robots.sensors mounts them.
LASER_FRAME_ID = 'base_scan'
LIDAR3D_FRAME_ID = 'lidar_3d'
IMU_FRAME_ID = 'imu_link'
HEAD_CAMERA_FRAME_ID = 'head_camera_optical'
HEAD_CAMERA_LINK = 'head'


# Below 1e-6 (a step every 70 min of wall time at 240 Hz) a step's wait passed what the
# platform can sleep (1e-13: OverflowError): such a factor is no use, so it is refused.
REAL_TIME_FACTOR = Bounds(1.0e-6, 1000.0, '', 'as fast as possible')

# Physical quantities of a robot that drives on wheels; beyond these a value is
# a typo (wheel_radius 1e308 once made odom report x = -5e284).
WHEEL_RADIUS = Bounds(0.001, 10.0, 'm', 'derive it from the URDF')
WHEEL_SEPARATION = Bounds(0.001, 100.0, 'm', 'derive it from the URDF')
WHEEL_VELOCITY = Bounds(0.001, 10000.0, 'rad/s', 'take the URDF velocity limit')
WHEEL_FORCE = Bounds(0.001, 100000.0, 'N m', 'take the URDF effort limit')


# What one robot's sensors may cost, by what their rays and pixels cost here (CPU of
# our 2-core machine, idle: a ray 1.5-2 us, a pixel of the head camera 0.15 us; under
# load, up to 3 times as much). PyBullet holds the interpreter while it casts or
# renders, so one scan or image is as long as the node answers nothing, SIGINT
# included (a 256 x 10,000 lidar: 12 s a scan; a 4096^2 camera ran at 1 % of real
# time); the per-second bounds keep a robot above about a fifth of real time.
MAX_LIDAR3D_RAYS_PER_SCAN = 64 * 2048           # about 0.25 s a scan
MAX_RAYS_PER_SECOND = 1_500_000  # a 64 x 2048 lidar at 10 Hz and a laser: about 2.5 s of CPU
MAX_CAMERA_PIXELS = 1920 * 1080                 # about 0.3 s an image
MAX_CAMERA_PIXELS_PER_SECOND = 1920 * 1080 * 15  # about 5 s of CPU a simulated second


# -- readers: raw parameter value -> validated value (one ConfigError line) ---

# -- the table -----------------------------------------------------------------

class Parameter(NamedTuple):
    """
    One ROS parameter and the :class:`SimConfig` field it becomes.

    ``ros_type`` is the declared ROS type (double, integer, bool, string,
    double_array, string_array); ``read`` validates and converts a raw value;
    ``bounds`` then holds numbers (or each element of a number list) to a range.
    ``per_robot``: a robot's own setting (its description, drive, frames,
    sensors), which each robot listed in ``robots`` may override; the others
    are the world's (physics, time, the ground, the live view). ``python_type``
    is the field's type when ``read`` gives more than the ROS type says.
    """

    name: str
    ros_type: str
    default: Any
    description: str
    field: str
    read: Callable[[str, Any], Any]
    bounds: Optional[Bounds] = None
    per_robot: bool = False  # each robot of several may set its own (robot_a.<name>)
    python_type: str = ''    # the SimConfig field's type, when not the ROS type's


class NoiseFamily(NamedTuple):
    """
    The seven parameters of one sensor's Gazebo noise (see :mod:`r2d2_sim.model.noise`).

    ``prefix`` names them (``scan`` -> ``scan_noise_mean``...); values are in
    ``unit`` and within +-``magnitude``, the rounding step in
    ``precision_unit`` up to ``precision_max``. ``std`` is the family's
    standard deviation parameter when it existed before the rest (it keeps
    its name, field and description).
    """

    prefix: str
    what: str
    unit: str
    magnitude: float
    precision_unit: str
    precision_max: float
    std: Optional[Parameter] = None

    def name(self, part: str) -> str:
        """Return the parameter name of one part (mean, std, bias_mean...)."""
        return f'{self.prefix}_noise_{part}'

    def field(self, part: str) -> str:
        """Return the SimConfig field of one part."""
        if part == 'std' and self.std is not None:
            return self.std.field
        return self.name(part)

    def parameters(self) -> List[Parameter]:
        """Return the family's seven table entries, in the order of a Gazebo <noise>."""
        unit, what, magnitude = self.unit, self.what, self.magnitude
        shown = unit or 'fraction'
        spread = Bounds(0.0, magnitude, unit)
        std = self.std or Parameter(
            self.name('std'), 'double', 0.0,
            f'{what}: white noise standard deviation ({shown}); 0 = none.',
            self.name('std'), read.non_negative, spread, per_robot=True)
        return [
            Parameter(self.name('mean'), 'double', 0.0,
                      f'{what}: mean of the white noise ({shown}), added to every reading.',
                      self.name('mean'), read.number, Bounds(-magnitude, magnitude, unit),
                      per_robot=True),
            std,
            Parameter(self.name('bias_mean'), 'double', 0.0,
                      f'{what}: mean of the constant bias ({shown}), drawn once per robot '
                      'and sensor (per axis) from the seed, its sign flipped with '
                      'probability 0.5 (Gazebo\'s bias_mean).',
                      self.name('bias_mean'), read.number, Bounds(-magnitude, magnitude, unit),
                      per_robot=True),
            Parameter(self.name('bias_std'), 'double', 0.0,
                      f'{what}: standard deviation of the constant bias ({shown}).',
                      self.name('bias_std'), read.non_negative, spread, per_robot=True),
            Parameter(self.name('dynamic_bias_std'), 'double', 0.0,
                      f'{what}: the drifting bias\'s random walk ({shown} per sqrt(s)): a '
                      'Gauss-Markov process from 0 that settles at this times '
                      'sqrt(correlation time / 2); 0 = none.',
                      self.name('dynamic_bias_std'), read.non_negative,
                      Bounds(0.0, magnitude, f'{unit}/sqrt(s)' if unit else '1/sqrt(s)'),
                      per_robot=True),
            Parameter(self.name('dynamic_bias_correlation_time'), 'double', 0.0,
                      f'{what}: the drifting bias\'s correlation time in s (Gazebo suggests '
                      'hours: 3600).',
                      self.name('dynamic_bias_correlation_time'), read.non_negative,
                      Bounds(0.001, 1.0e7, 's', 'no drifting bias'), per_robot=True),
            Parameter(self.name('precision'), 'double', 0.0,
                      f'{what}: readings are rounded to a multiple of this '
                      f'({self.precision_unit}); 0 = no rounding.',
                      self.name('precision'), read.non_negative,
                      Bounds(0.0, self.precision_max, self.precision_unit), per_robot=True),
        ]


NOISE_PARTS = ('mean', 'std', 'bias_mean', 'bias_std', 'dynamic_bias_std',
               'dynamic_bias_correlation_time', 'precision')

NOISE_FAMILIES: Dict[str, NoiseFamily] = {family.prefix: family for family in (
    NoiseFamily('scan', 'Laser range noise', 'm', 10.0, 'm', 10.0, Parameter(
        'scan_noise_std', 'double', 0.0,
        'Gaussian range noise standard deviation in m, clipped into the range so that '
        'noise never fakes a miss; 0 = exact.',
        'scan_noise_std_m', read.non_negative, Bounds(0.0, 10.0, 'm'), per_robot=True)),
    NoiseFamily('imu_orientation', 'IMU orientation noise, a rotation about each world axis',
                'rad', 1.0, 'rad', 1.0, Parameter(
                    'imu_orientation_noise_std', 'double', 0.0,
                    'IMU orientation noise standard deviation in rad (its covariance is the '
                    'mean square error of all its noise parameters); 0 = exact.',
                    'imu_orientation_noise_std_rad', read.non_negative, Bounds(0.0, 1.0, 'rad'),
                    per_robot=True)),
    NoiseFamily('imu_angular_velocity', 'IMU angular velocity noise, each axis', 'rad/s', 10.0,
                'rad/s', 10.0, Parameter(
                    'imu_angular_velocity_noise_std', 'double', 0.0,
                    'IMU angular velocity noise standard deviation in rad/s (its covariance is '
                    'the mean square error of all its noise parameters); 0 = exact.',
                    'imu_angular_velocity_noise_std_rad_s', read.non_negative,
                    Bounds(0.0, 10.0, 'rad/s'), per_robot=True)),
    NoiseFamily('imu_linear_acceleration', 'IMU acceleration noise, each axis', 'm/s^2', 100.0,
                'm/s^2', 100.0, Parameter(
                    'imu_linear_acceleration_noise_std', 'double', 0.0,
                    'IMU acceleration noise standard deviation in m/s^2 (its covariance is the '
                    'mean square error of all its noise parameters); 0 = exact.',
                    'imu_linear_acceleration_noise_std_m_s2', read.non_negative,
                    Bounds(0.0, 100.0, 'm/s^2'), per_robot=True)),
    NoiseFamily('encoder', 'Wheel encoder noise, relative to each side\'s rotation since the '
                'last reading (0.01 = 1 %; a bias is a wheel radius off by that fraction)',
                '', 1.0, 'rad: the encoder tick, 2 pi / ticks per turn', 2.0 * math.pi),
    NoiseFamily('depth', 'Depth image noise, each pixel', 'm', 10.0, 'm', 10.0),
    NoiseFamily('lidar3d', '3D lidar range noise, each beam', 'm', 10.0, 'm', 10.0),
)}


def _noise_parameters(prefix: str) -> List[Parameter]:
    return NOISE_FAMILIES[prefix].parameters()


PARAMETERS: List[Parameter] = [
    Parameter('urdf', 'string', '',
              'Robot description: a file path, a package://pkg/path URI or a name in '
              'pybullet_data (r2d2.urdf); empty means the package\'s own urdf/r2d2.urdf.',
              'urdf', read.string, per_robot=True),
    Parameter('robot_description', 'string', '',
              'URDF XML text (as robot_state_publisher takes it); overrides urdf.',
              'robot_description', read.string, per_robot=True),
    Parameter('base_forward_axis', 'string', 'x',
              'Axis of the URDF base frame the robot drives along: x, y, -x or -y (quote it '
              'in YAML files, which read a bare y as true).',
              'base_forward_axis', read.choice(list(FORWARD_AXIS_YAW_RAD)), per_robot=True),
    Parameter('wheel_velocity_sign', 'integer', 1,
              '1, or -1 when a negative wheel velocity drives the robot forward.',
              'wheel_velocity_sign', read.choice([1, -1]), per_robot=True),
    Parameter('gravity', 'double_array', [0.0, 0.0, -9.8], 'Gravity [x, y, z] in m/s^2.',
              'gravity_m_s2', read.numbers(3), Bounds(-1000.0, 1000.0, 'm/s^2 on each axis'),
              python_type='Tuple[float, float, float]'),
    Parameter('ground_plane', 'bool', True, 'Load pybullet_data\'s plane.urdf as the ground.',
              'ground_plane', read.boolean),
    Parameter('extra_models', 'string_array', [],
              'Other bodies, each "description x y z" (description resolved like urdf), '
              'e.g. the tutorial\'s cube: ["cube.urdf 0 0 1"]. They collide with the robot.',
              'extra_models', read.extra_models,
              python_type='Tuple[Tuple[str, Tuple[float, float, float]], ...]'),
    Parameter('gui', 'bool', False,
              'Open the PyBullet window (needs a display); same paced rate, the camera '
              'follows the robot.',
              'gui', read.boolean),
    Parameter('physics_rate', 'double', 240.0,
              'Physics steps per simulated second (Hz). No sensor or publication runs faster '
              'than the physics: below 100 Hz, also set imu_rate (100 Hz by default) to '
              'physics_rate or less, or to 0 (IMU off).',
              'physics_rate_hz', read.positive, Bounds(10.0, 10000.0, 'Hz')),
    Parameter('real_time_factor', 'double', 1.0,
              'Simulated seconds per wall-clock second; 0 runs as fast as possible.',
              'real_time_factor', read.non_negative, REAL_TIME_FACTOR),
    Parameter('publish_rate', 'double', 0.0,
              'State publishing rate in simulated Hz; 0 publishes after every physics step. '
              'A rate that does not divide physics_rate (50 Hz at 240 Hz) publishes at the '
              'first step after each period.',
              'publish_rate_hz', read.non_negative, Bounds(0.001, 10000.0, 'Hz', 'every step')),
    Parameter('ray_threads', 'integer', 0,
              'Threads a call of 128 rays or more (a scan) is cast on, the ranges the same bit '
              'for bit; 0 = auto: 2 in a node (sim_node, SimHarness) that may use two cores, 1 '
              'in the ROS-free core. Farms and learning environments set 1: one per core.',
              'ray_threads', read.integer, Bounds(1, 64, '', 'auto')),
    Parameter('outputs_process', 'bool', False,
              'Publish every output from a second process (r2d2_sim_outputs), fed a step\'s '
              'bytes through a pipe: the physics thread builds the messages but never waits in '
              'DDS. The same bytes, order and stamps; the live view and the recording live '
              'there too (the same file). Lockstep calls return once published (slower there: '
              'for many robots at real time with their topics taken).',
              'outputs_process', read.boolean),
    Parameter('cmd_vel_timeout', 'double', 0.5,
              'Simulated seconds without cmd_vel before the wheels are braked; 0 disables.',
              'cmd_vel_timeout_s', read.non_negative, per_robot=True),
    Parameter('start_paused', 'bool', False,
              'Start with physics stopped, waiting for ~/pause false or ~/step.',
              'start_paused', read.boolean),
    Parameter('wheel_radius', 'double', 0.0,
              'Wheel radius in metres; 0 derives it from the wheels\' collision cylinders '
              '(0.035 m on R2D2).',
              'wheel_radius_m', read.non_negative, WHEEL_RADIUS, per_robot=True),
    Parameter('wheel_separation', 'double', 0.0,
              'Distance between left and right wheels in metres; 0 derives it from the URDF '
              '(0.44 m between R2D2\'s left and right wheel centres).',
              'wheel_separation_m', read.non_negative, WHEEL_SEPARATION, per_robot=True),
    Parameter('wheel_separation_multiplier', 'double', DEFAULT_WHEEL_SEPARATION_MULTIPLIER,
              'Effective/nominal track ratio used by commands and odometry (skid steering; '
              'the default is calibrated on R2D2).',
              'wheel_separation_multiplier', read.positive, Bounds(0.1, 10.0), per_robot=True),
    Parameter('wheel_lateral_friction_ratio', 'double', 0.35,
              'Wheel grip along the axle relative to rolling grip, in (0, 1].',
              'wheel_lateral_friction_ratio', read.ratio, per_robot=True),
    Parameter('left_wheel_names', 'string_array',
              ['left_front_wheel_joint', 'left_back_wheel_joint'],
              'Joints driven as the left side.', 'left_wheel_names', read.joint_names,
              per_robot=True),
    Parameter('right_wheel_names', 'string_array',
              ['right_front_wheel_joint', 'right_back_wheel_joint'],
              'Joints driven as the right side.', 'right_wheel_names', read.joint_names,
              per_robot=True),
    Parameter('max_wheel_velocity', 'double', 0.0,
              'Wheel speed limit in rad/s; 0 takes the URDF joint velocity limit (50 rad/s on '
              'R2D2). Commands beyond it are scaled down keeping their curvature.',
              'max_wheel_velocity_rad_s', read.non_negative, WHEEL_VELOCITY, per_robot=True),
    Parameter('max_wheel_force', 'double', 0.0,
              'Wheel motor torque limit in N m; 0 takes the URDF joint effort limit (20 N m '
              'on R2D2). Values taken from the URDF are held to the same range.',
              'max_wheel_force_n_m', read.non_negative, WHEEL_FORCE, per_robot=True),
    Parameter('max_linear_velocity', 'double', 0.0,
              'Forward speed limit in m/s; 0 leaves only the wheel speed limit.',
              'max_linear_velocity_m_s', read.limit, Bounds(0.001, 50.0, 'm/s', 'no limit'),
              per_robot=True),
    Parameter('max_angular_velocity', 'double', DEFAULT_MAX_ANGULAR_VELOCITY_RAD_S,
              'Turn rate limit in rad/s; 0 leaves only the wheel speed limit. Spinning faster '
              'than about 4 rad/s throws R2D2 over.',
              'max_angular_velocity_rad_s', read.limit, Bounds(0.001, 50.0, 'rad/s', 'no limit'),
              per_robot=True),
    Parameter('max_linear_acceleration', 'double', DEFAULT_MAX_LINEAR_ACCELERATION_M_S2,
              'Forward acceleration and braking limit in m/s^2; 0 means none. A step to full '
              'speed at 3 m/s^2 or more tips R2D2 over.',
              'max_linear_acceleration_m_s2', read.limit,
              Bounds(0.001, 1000.0, 'm/s^2', 'no limit'), per_robot=True),
    Parameter('max_angular_acceleration', 'double', DEFAULT_MAX_ANGULAR_ACCELERATION_RAD_S2,
              'Turn rate acceleration limit in rad/s^2; 0 means none.',
              'max_angular_acceleration_rad_s2', read.limit,
              Bounds(0.001, 1000.0, 'rad/s^2', 'no limit'), per_robot=True),
    Parameter('odom_frame_id', 'string', 'odom', 'Frame of the wheel odometry.',
              'odom_frame_id', read.frame, per_robot=True),
    Parameter('base_frame_id', 'string', 'base_link',
              'Child frame of both odometry topics: the body frame (x forward), parent of the '
              'URDF\'s root link in TF unless it names that link, which it may only when '
              'base_forward_axis is x.',
              'base_frame_id', read.frame, per_robot=True),
    Parameter('world_frame_id', 'string', 'world', 'Frame of the ground_truth odometry.',
              'world_frame_id', read.frame),
    Parameter('initial_pose', 'double_array', [0.0, 0.0, 0.0],
              'Spawn pose [x (m), y (m), yaw (rad)] in the world frame, or relative to the '
              'world\'s start_pose when its manifest names one.',
              'initial_pose', read.numbers(3), per_robot=True,
              python_type='Tuple[float, float, float]'),
    Parameter('tags', 'string_array', [],
              'Tags of the robot as an entity of the simulation standard (GetEntityInfo, the '
              'tags filters), e.g. [astromech, test_subject]; at most 64.',
              'tags', read.tags, per_robot=True),
    Parameter('pose_covariance_diagonal', 'double_array',
              [0.001, 0.001, 1.0e6, 1.0e6, 1.0e6, 0.01],
              'Diagonal of the odom pose covariance (x, y, z, roll, pitch, yaw).',
              'pose_covariance_diagonal', read.variances, per_robot=True),
    Parameter('twist_covariance_diagonal', 'double_array',
              [0.001, 1.0e6, 1.0e6, 1.0e6, 1.0e6, 0.01],
              'Diagonal of the odom twist covariance (vx, vy, vz, wx, wy, wz).',
              'twist_covariance_diagonal', read.variances, per_robot=True),
    Parameter('camera_rate', 'double', 0.0,
              'Head camera images per simulated second (Hz); 0 turns the camera off.',
              'camera_rate_hz', read.non_negative, Bounds(0.001, 10000.0, 'Hz', 'off'),
              per_robot=True),
    Parameter('camera_width', 'integer', 320, 'Head camera image width in pixels.',
              'camera_width_px', read.integer, Bounds(1, 4096, 'px'), per_robot=True),
    Parameter('camera_height', 'integer', 240, 'Head camera image height in pixels.',
              'camera_height_px', read.integer, Bounds(1, 4096, 'px'), per_robot=True),
    Parameter('camera_fov', 'double', 60.0,
              'Head camera vertical field of view in degrees, below 180.',
              'camera_fov_deg', read.field_of_view, per_robot=True),
    Parameter('camera_depth', 'bool', False,
              'With the camera on, also publish a 32FC1 depth image in metres (REP-118).',
              'camera_depth', read.boolean, per_robot=True),
    Parameter('camera_point_cloud', 'bool', False,
              'With the camera on, also publish camera/depth/points: the depth as an organised '
              'sensor_msgs/PointCloud2 (x y z float32 in the optical frame, NaN where the '
              'depth is not finite), at camera_rate.',
              'camera_point_cloud', read.boolean, per_robot=True),
    Parameter('camera_self_filter', 'bool', False,
              'With depth on (camera_depth or camera_point_cloud), the pixels that see the robot '
              'itself (R2D2\'s gripper: 4.7 % of the default view) read NaN in the depth image '
              'and the cloud, as robot_self_filter leaves them; the colour image still shows '
              'them.',
              'camera_self_filter', read.boolean, per_robot=True),
    *_noise_parameters('depth'),
    Parameter('world', 'string', '',
              'The world to load around the robots: a URDF, an SDF world (Gazebo\'s *.sdf, '
              '*.world) or an r2d2_sim world manifest (*.world.yaml), as a path, a file:// or '
              'package:// URI, or a name looked for in the package\'s urdf/, world_paths and '
              'pybullet_data (package://r2d2_sim/urdf/room.world.yaml, room.urdf); empty for '
              'the empty world (empty.world.yaml). LoadWorld replaces it.', 'world',
              read.string),
    Parameter('world_paths', 'string_array', [],
              'Directories of worlds (paths, file:// or package:// URIs): GetAvailableWorlds '
              'lists their *.world.yaml files and SDF worlds (*.sdf, *.world), and a LoadWorld '
              'request may load from them, as from the package\'s urdf/, pybullet_data and '
              'ROS packages. One that is no directory stops the start.',
              'world_paths', read.directories),
    Parameter('model_paths', 'string_array', [],
              'Directories (paths, file:// or package:// URIs) searched for the model:// URIs '
              'of SDF worlds and models, before GZ_SIM_RESOURCE_PATH, IGN_GAZEBO_RESOURCE_PATH, '
              'GAZEBO_MODEL_PATH and SDF_PATH; a LoadWorld or SpawnEntity request may use '
              'their files. One that is no directory stops the start.',
              'model_paths', read.directories),
    Parameter('strict_worlds', 'bool', False,
              'Refuse a world (and an SDF spawn) with elements r2d2_sim does not simulate '
              '(plugins, lights, sensors, physics settings...) instead of naming them in one '
              'summary line; LoadWorld\'s fail_on_unsupported_element does so per request.',
              'strict_worlds', read.boolean),
    Parameter('publish_tf', 'bool', True,
              'Publish odom -> base_footprint on /tf and the static frames on /tf_static '
              '(needs tf2_msgs).', 'publish_tf', read.boolean, per_robot=True),
    Parameter('publish_link_tf', 'bool', False,
              'Also publish the robot\'s link transforms (what robot_state_publisher would).',
              'publish_link_tf', read.boolean, per_robot=True),
    Parameter('publish_ground_truth_tf', 'bool', False,
              'Also publish world -> odom so that world -> base is the true pose (height and '
              'tilt too; world -> base_footprint for a robot without wheels).',
              'publish_ground_truth_tf', read.boolean, per_robot=True),
    Parameter('publish_contacts', 'bool', False,
              'Publish what the robot touches (its own links and the ground aside) on contacts '
              'as visualization_msgs/MarkerArray: a sphere at each touched body\'s strongest '
              'contact point, in world_frame_id, at the state rate while any last and once '
              'when they end.', 'publish_contacts', read.boolean, per_robot=True),
    Parameter('footprint_frame_id', 'string', 'base_footprint',
              'The base\'s projection on the ground, parent of base_frame_id in TF.',
              'footprint_frame_id', read.frame, per_robot=True),
    Parameter('frame_prefix', 'string', '',
              'Prefix for every frame the robot publishes (not world_frame_id), e.g. robot1/.',
              'frame_prefix', read.frame_prefix, per_robot=True),
    Parameter('scan_rate', 'double', 10.0,
              'Laser scans per simulated second (Hz) on scan; 0 turns the scanner off.',
              'scan_rate_hz', read.non_negative, Bounds(0.001, 10000.0, 'Hz', 'off'),
              per_robot=True),
    Parameter('scan_samples', 'integer', 360, 'Beams per scan.', 'scan_samples', read.integer,
              Bounds(2, 10000), per_robot=True),
    Parameter('scan_angle_min', 'double', -math.pi, 'First beam angle in rad (0 = forward).',
              'scan_angle_min_rad', read.number, Bounds(-math.pi, math.pi, 'rad'), per_robot=True),
    Parameter('scan_angle_max', 'double', math.pi,
              'Last beam angle in rad; a full circle has no duplicate last beam.',
              'scan_angle_max_rad', read.number, Bounds(-math.pi, math.pi, 'rad'), per_robot=True),
    Parameter('scan_range_min', 'double', 0.12, 'Closest range in m; nearer reads -inf.',
              'scan_range_min_m', read.non_negative, Bounds(0.0, 100.0, 'm'), per_robot=True),
    Parameter('scan_range_max', 'double', 12.0, 'Farthest range in m; no return reads +inf.',
              'scan_range_max_m', read.positive, Bounds(0.01, 1000.0, 'm'), per_robot=True),
    *_noise_parameters('scan'),
    Parameter('imu_rate', 'double', 100.0,
              'IMU messages per simulated second (Hz) on imu; 0 turns the IMU off.',
              'imu_rate_hz', read.non_negative, Bounds(0.001, 10000.0, 'Hz', 'off'),
              per_robot=True),
    Parameter('lidar3d_rate', 'double', 0.0,
              'Multi-ring 3D lidar scans per simulated second (Hz) on points '
              '(sensor_msgs/PointCloud2 as Velodyne drivers publish it); 0 turns it off.',
              'lidar3d_rate_hz', read.non_negative, Bounds(0.001, 10000.0, 'Hz', 'off'),
              per_robot=True),
    Parameter('lidar3d_rings', 'integer', 16, 'Rings (beams stacked vertically) of the 3D lidar.',
              'lidar3d_rings', read.integer, Bounds(1, 256), per_robot=True),
    Parameter('lidar3d_samples', 'integer', 1800,
              'Beams per ring around a full turn (1800: 0.2 degrees apart).',
              'lidar3d_samples', read.integer, Bounds(1, 10000), per_robot=True),
    Parameter('lidar3d_angle_min', 'double', -math.radians(15.0),
              'Elevation of the lowest ring in rad (negative: below the horizon).',
              'lidar3d_angle_min_rad', read.number, Bounds(-math.pi / 2, math.pi / 2, 'rad'),
              per_robot=True),
    Parameter('lidar3d_angle_max', 'double', math.radians(15.0),
              'Elevation of the highest ring in rad.',
              'lidar3d_angle_max_rad', read.number, Bounds(-math.pi / 2, math.pi / 2, 'rad'),
              per_robot=True),
    Parameter('lidar3d_range_min', 'double', 0.3,
              '3D lidar: closest range in m; nearer returns are NaN points.',
              'lidar3d_range_min_m', read.non_negative, Bounds(0.0, 100.0, 'm'), per_robot=True),
    Parameter('lidar3d_range_max', 'double', 100.0,
              '3D lidar: farthest range in m; beams without a return are NaN points.',
              'lidar3d_range_max_m', read.positive, Bounds(0.01, 1000.0, 'm'), per_robot=True),
    Parameter('lidar3d_height', 'double', 0.0,
              '3D lidar: height of its frame above the ground in m, on the body\'s axis; 0 puts '
              'it 5 cm above the robot\'s highest point.',
              'lidar3d_height_m', read.non_negative, Bounds(0.01, 100.0, 'm', 'on top'),
              per_robot=True),
    *_noise_parameters('lidar3d'),
    *_noise_parameters('imu_orientation'),
    *_noise_parameters('imu_angular_velocity'),
    *_noise_parameters('imu_linear_acceleration'),
    *_noise_parameters('encoder'),
    Parameter('noise_seed', 'integer', 0,
              'Seed of every noise stream of the robot\'s sensors, each its own stream from this, '
              'the robot\'s name and the sensor (runs and full resets repeat).',
              'noise_seed', read.integer, Bounds(0, 2**31 - 1), per_robot=True),
    Parameter('battery_rate', 'double', 0.0,
              'sensor_msgs/BatteryState messages per simulated second (Hz) on battery_state '
              '(Nav2 docking\'s topic); 0 turns the battery off (the robot never runs out).',
              'battery_rate_hz', read.non_negative, Bounds(0.001, 10000.0, 'Hz', 'off'),
              per_robot=True),
    Parameter('battery_capacity', 'double', 2.0, 'Battery capacity in Ah.',
              'battery_capacity_ah', read.positive, Bounds(1.0e-6, 10000.0, 'Ah'),
              per_robot=True),
    Parameter('battery_initial_charge', 'double', 1.0,
              'Charge at start-up and after a reset, as a fraction of the capacity.',
              'battery_initial_charge', read.non_negative, Bounds(0.0, 1.0), per_robot=True),
    Parameter('battery_voltage_empty', 'double', 12.8,
              'Battery voltage (V) when empty; it rises linearly with the charge.',
              'battery_voltage_empty_v', read.non_negative, Bounds(0.0, 1000.0, 'V'),
              per_robot=True),
    Parameter('battery_voltage_full', 'double', 16.8, 'Battery voltage (V) when full.',
              'battery_voltage_full_v', read.positive, Bounds(0.001, 1000.0, 'V'),
              per_robot=True),
    Parameter('battery_idle_current', 'double', 0.5,
              'Current (A) the robot draws standing still (its electronics).',
              'battery_idle_current_a', read.non_negative, Bounds(0.0, 1000.0, 'A'),
              per_robot=True),
    Parameter('battery_current_per_effort', 'double', 1.0,
              'Current (A) drawn per N m of torque the wheel motors apply, summed over the '
              'wheels.',
              'battery_current_per_effort_a_n_m', read.non_negative,
              Bounds(0.0, 1000.0, 'A/(N m)'), per_robot=True),
    Parameter('battery_current_per_speed', 'double', 0.02,
              'Current (A) drawn per rad/s of wheel speed, summed over the wheels.',
              'battery_current_per_speed_a_rad_s', read.non_negative,
              Bounds(0.0, 1000.0, 'A/(rad/s)'), per_robot=True),
    Parameter('battery_charge_current', 'double', 2.0,
              'Current (A) a dock feeds; above the robot\'s draw (and above Nav2\'s '
              'charging_threshold, 0.5 A) the battery charges.',
              'battery_charge_current_a', read.non_negative, Bounds(0.0, 1000.0, 'A'),
              per_robot=True),
    Parameter('battery_dock_pose', 'double_array', [],
              'The dock: [x (m), y (m), yaw (rad)] in the world frame, where a robot resting '
              '(base slower than 5 cm/s) charges; [] for none (or battery_dock\'s).',
              'battery_dock_pose', read.optional_numbers(3), per_robot=True),
    Parameter('battery_dock', 'string', '',
              'The dock as a named pose of the world (the room\'s is dock): its x, y and yaw, '
              'taken again when another world loads (a world without it: no dock); \'\' for '
              'battery_dock_pose\'s.',
              'battery_dock', read.string, per_robot=True),
    Parameter('battery_dock_tolerance', 'double_array', [0.1, 0.2],
              'How near the dock pose counts as on it: [position (m), yaw (rad)].',
              'battery_dock_tolerance', read.numbers(2), Bounds(0.0, 100.0), per_robot=True),
    Parameter('battery_empty_behaviour', 'string', 'stop',
              'What an empty robot does: stop (its wheels brake), slow (at '
              'battery_empty_speed of its commands) or continue.',
              'battery_empty_behaviour', read.choice(['stop', 'slow', 'continue']),
              per_robot=True),
    Parameter('battery_empty_speed', 'double', 0.3,
              'With battery_empty_behaviour slow: the fraction of its wheel speeds an empty '
              'robot keeps.',
              'battery_empty_speed', read.ratio, per_robot=True),
    Parameter('enable_stamped_cmd_vel', 'bool', False,
              'Take geometry_msgs/TwistStamped on cmd_vel instead of Twist (Nav2\'s name); a '
              'zero stamp means now, one older than cmd_vel_timeout is refused with a warning.',
              'enable_stamped_cmd_vel', read.boolean, per_robot=True),
    Parameter('foxglove_port', 'integer', 0,
              'Serve a Foxglove live view of every output on this port (ws://); 0 = off.',
              'foxglove_port', read.integer, Bounds(1, 65535, '', 'off')),
    Parameter('foxglove_host', 'string', '127.0.0.1',
              'Address the live view binds (0.0.0.0 shows it to the whole network).',
              'foxglove_host', read.string),
    Parameter('record', 'string', '',
              'Record every output into this MCAP file (ros2 bag play, Foxglove); refused if '
              'the file exists; empty = off.',
              'record', read.string),
    Parameter('robots', 'string_array', [],
              'Names of several robots in one world, each in its own namespace (its name '
              'unless NAME.namespace says otherwise), set per robot with NAME.<parameter> '
              '(NAME.initial_pose...); empty: one robot, named by its URDF, in the node\'s '
              'namespace.', 'robots', read.robot_names),
    Parameter('tf_layout', 'string', 'shared',
              'shared: one /tf and /tf_static; the frames of a robot listed in robots (or '
              'spawned with a namespace) are prefixed NAME/. namespaced: tf and tf_static in '
              'each robot\'s namespace, frames unprefixed (Nav2\'s multi-robot remap).',
              'tf_layout', read.choice(['shared', 'namespaced'])),
]

PARAMETERS_BY_NAME: Dict[str, Parameter] = {p.name: p for p in PARAMETERS}
