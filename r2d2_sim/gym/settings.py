"""
An environment's settings, checked once: the task's sizes, the world's variations, the simulator's.

No PyBullet, no ROS. :class:`NavSettings` holds what every environment of
this package takes as keywords (the control period, the scan, the robot's
limits, the scenario space the episodes are drawn from, the rewards, more
simulator parameters) and turns them into the simulator's parameters
(:meth:`NavSettings.sim_parameters`), the same for both backends. A value
that cannot be is a :class:`GymError` in one line, at construction.
"""

from dataclasses import dataclass, field, fields
import math
import numbers
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy

from r2d2_sim.errors import SetupError
from r2d2_sim.farm.scenario import ScenarioSpace
from r2d2_sim.gym.task import ObservationShape, Rewards
from r2d2_sim.sim.settings.given import plain_value
from r2d2_sim.sim.settings.robots import parse_world

__all__ = ['GymError', 'NavSettings', 'nav_settings', 'reset_options', 'DEFAULT_SPACE', 'BACKENDS',
           'PHYSICS_RATE_HZ', 'robot_names']

# The backends: the core in this process, or the simulator node in lockstep over ROS.
BACKENDS = ('inproc', 'ros')
PHYSICS_RATE_HZ = 240.0
# What R2D2Nav-v0's episodes vary, by default: up to four 0.4 m pillars between a start
# near the origin and a goal 3 to 3.5 m ahead. One box size: the boxes are a pool made
# once per environment (each episode places them; none is loaded again).
DEFAULT_SPACE = ScenarioSpace(obstacles=(0, 4), area=(0.8, -1.2, 2.4, 1.2),
                              box_size=(0.4, 0.4), box_height=0.5,
                              start_area=(-0.2, -0.2, 0.2, 0.2), start_yaw=(-0.5, 0.5),
                              goal_area=(3.0, -1.0, 3.5, 1.0), goal_tolerance=0.3,
                              keep_out=0.7)
# The simulator's parameters an environment sets itself: given in sim_parameters they
# would break what the task measures, or the lockstep.
OWN_PARAMETERS = ('physics_rate', 'publish_rate', 'scan_rate', 'scan_samples', 'scan_range_max',
                  'scan_angle_min', 'scan_angle_max', 'max_linear_velocity',
                  'max_angular_velocity', 'cmd_vel_timeout', 'world', 'robots', 'noise_seed',
                  'real_time_factor', 'start_paused', 'initial_pose')
# What every episode draws from the space instead (ScenarioSpace.scan_noise_std): given in
# sim_parameters it would be overwritten at every reset.
SPACE_PARAMETERS = ('scan_noise_std',)
# What the ros backend cannot run with: a TwistStamped cmd_vel, the outputs in a child.
ROS_BACKEND_REFUSED = ('enable_stamped_cmd_vel', 'outputs_process')
# What only the ros backend's simulator node does: record its outputs, serve the live view.
# The inproc backend runs no node, so it would ignore them without a word.
ROS_BACKEND_ONLY = ('record', 'foxglove_port', 'foxglove_host')
# Robots of a several-robot world stand this far apart (m, along y) before each episode.
LANE_SPACING_M = 3.0


class GymError(ValueError):
    """An environment's setting or an input it cannot take: one line."""


def _is_number(value: Any) -> bool:
    """Return True for a real number (numpy's too), False for a bool (numpy's too)."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, numpy.bool_))


def _plain(value: Any) -> Any:
    """Return a number as Python's int or float (the same value; either kept as it is)."""
    return int(value) if isinstance(value, numbers.Integral) else float(value)


def _named(parameters: Mapping[str, Any], names: Sequence[str]) -> List[str]:
    """Return the parameters among ``names``, a robot's own (``r2d2_1.scan_rate``) too."""
    return sorted(name for name in parameters if str(name).rpartition('.')[2] in names)


def nav_settings(owner: str, keywords: Mapping[str, Any], **fixed: Any) -> 'NavSettings':
    """
    Return the settings of an environment's keywords; GymError (one line) if it cannot be.

    ``owner`` names the environment in the line for a keyword it does not take;
    ``fixed`` are keywords the environment gives itself (``robots``).
    """
    unknown = sorted(set(keywords) - {f.name for f in fields(NavSettings)}, key=str)
    if unknown:
        raise GymError(f'{owner}: unexpected keyword argument {", ".join(map(repr, unknown))}')
    return NavSettings(**keywords, **fixed)


def reset_options(options: Any) -> Dict[str, Any]:
    """Return ``reset``'s options as a dict (None: none); GymError if they are not a mapping."""
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise GymError(f'reset options must be a dict, got {type(options).__name__} '
                       f'{options!r:.60}')
    return dict(options)


def robot_names(count: int) -> Tuple[str, ...]:
    """Return the robots' names of a world of ``count`` (one robot: the URDF's, r2d2)."""
    return ('r2d2',) if count == 1 else tuple(f'r2d2_{i}' for i in range(count))


@dataclass(frozen=True)
class NavSettings:
    """
    What an environment is made of; every keyword of ``gymnasium.make('R2D2Nav-v0', ...)``.

    - ``backend``: ``'inproc'`` (the core in this process, no ROS) or
      ``'ros'`` (the simulator node, in lockstep over its topics);
    - ``control_rate_hz``: policy steps per simulated second (the physics
      runs at 240 Hz underneath: a whole number of steps per period);
    - ``scan_rays``: the laser's beams (a full circle), ``scan_beams`` the
      sectors the policy sees (each the nearest of ``scan_rays / scan_beams``
      beams), ``scan_range_m`` its range;
    - ``max_linear_m_s``, ``max_angular_rad_s``: the robot's limits, what an
      action of 1 asks; ``goal_range_m``: a goal this far is 1 in the observation;
    - ``space``: the farm's :class:`~r2d2_sim.farm.scenario.ScenarioSpace`
      the episodes are drawn from (obstacles, start, goal, scan noise, world);
      its boxes are of one size;
    - ``rewards``: the weights of :class:`~r2d2_sim.gym.task.Rewards`;
    - ``robots``: how many robots share the world (the PettingZoo environment);
    - ``sim_parameters``: more of the simulator's parameters (``gui`` for
      PyBullet's window, ``foxglove_port`` for the live view over ROS...);
    - ``tip_angle_deg``: leaning further is a fall.
    """

    backend: str = 'inproc'
    control_rate_hz: float = 10.0
    scan_rays: int = 360
    scan_beams: int = 36
    scan_range_m: float = 4.0
    max_linear_m_s: float = 0.5
    max_angular_rad_s: float = 1.5
    goal_range_m: float = 5.0
    space: ScenarioSpace = DEFAULT_SPACE
    rewards: Rewards = Rewards()
    robots: int = 1
    sim_parameters: Mapping[str, Any] = field(default_factory=dict)
    tip_angle_deg: float = 45.0

    def __post_init__(self) -> None:
        if self.backend not in BACKENDS:
            raise GymError(f'backend must be one of {", ".join(BACKENDS)}, got {self.backend!r}')
        # Numbers of any kind (numpy's scalars too: sweep tools hand them out), kept as
        # Python's own, so the settings read, print and compare as given.
        for name in ('control_rate_hz', 'scan_range_m', 'max_linear_m_s', 'max_angular_rad_s',
                     'goal_range_m', 'tip_angle_deg'):
            value = getattr(self, name)
            if not _is_number(value) or not math.isfinite(value) or value <= 0.0:
                raise GymError(f'{name} must be a number > 0, got {value!r}')
            object.__setattr__(self, name, _plain(value))
        if self.tip_angle_deg >= 180.0:
            raise GymError(f'tip_angle_deg must be below 180, got {self.tip_angle_deg!r}')
        steps = PHYSICS_RATE_HZ / self.control_rate_hz
        if abs(steps - round(steps)) > 1e-9:
            raise GymError(f'control_rate_hz must divide the physics rate '
                           f'({PHYSICS_RATE_HZ:g} Hz) into whole steps, got '
                           f'{self.control_rate_hz!r}')
        for name in ('scan_rays', 'scan_beams', 'robots'):
            value = getattr(self, name)
            if not _is_number(value) or not isinstance(value, numbers.Integral) or value < 1:
                raise GymError(f'{name} must be an integer >= 1, got {value!r}')
            object.__setattr__(self, name, int(value))
        if self.scan_rays % self.scan_beams:
            raise GymError(f'scan_beams must divide scan_rays ({self.scan_rays}) into equal '
                           f'sectors, got {self.scan_beams}')
        if not isinstance(self.space, ScenarioSpace):
            raise GymError(f'space must be a ScenarioSpace, got {type(self.space).__name__}')
        if self.space.box_size[0] != self.space.box_size[1]:
            raise GymError(f'the space\'s boxes must be of one size (box_size low == high), got '
                           f'{self.space.box_size}: they are a pool made once per environment')
        if self.space.limits:
            raise GymError('the space may not draw robot limits: give max_linear_m_s and '
                           'max_angular_rad_s instead')
        if not isinstance(self.rewards, Rewards):
            raise GymError(f'rewards must be a Rewards, got {type(self.rewards).__name__}')
        for name, value in zip(self.rewards._fields, self.rewards):
            if not _is_number(value) or not math.isfinite(value):
                raise GymError(f'rewards.{name} must be a finite number, got {value!r}')
        object.__setattr__(self, 'rewards', Rewards(*map(_plain, self.rewards)))
        if not isinstance(self.sim_parameters, Mapping):
            raise GymError(f'sim_parameters must be a dict of parameter names to values, got '
                           f'{type(self.sim_parameters).__name__}')
        for key in self.sim_parameters:
            if not isinstance(key, str):
                raise GymError(f'sim_parameters: parameter names are strings, got {key!r:.60} '
                               f'({type(key).__name__})')
        object.__setattr__(self, 'sim_parameters', {
            key: plain_value(value) for key, value in self.sim_parameters.items()})
        taken = _named(self.sim_parameters, OWN_PARAMETERS)
        if taken:
            raise GymError(f'sim_parameters: {", ".join(taken)} are set by the environment '
                           '(give its own keywords instead)')
        drawn = _named(self.sim_parameters, SPACE_PARAMETERS)
        if drawn:
            raise GymError(f'sim_parameters: {", ".join(drawn)} is drawn for each episode from '
                           'the space: give space=dataclasses.replace(DEFAULT_SPACE, '
                           'scan_noise_std=(low, high))')
        if self.backend == 'ros':
            # The ros backend drives over Twist and steps in lockstep in its own process.
            ros_refused = _named(self.sim_parameters, ROS_BACKEND_REFUSED)
            if ros_refused:
                raise GymError(f'sim_parameters: {", ".join(ros_refused)} cannot be used with '
                               "backend='ros' (it commands over Twist, in lockstep in this "
                               'process)')
        else:
            ros_only = _named(self.sim_parameters, ROS_BACKEND_ONLY)
            if ros_only:
                raise GymError(f'sim_parameters: {", ".join(ros_only)} work only with '
                               "backend='ros' (the inproc backend runs no ROS node: nothing "
                               'records its outputs or serves a live view)')
        try:  # read as the simulator will, so a bad name or value is this line, both backends
            parse_world(self.sim_parameters_for())
        except SetupError as exc:
            raise GymError(f'sim_parameters: {exc}') from None

    @property
    def steps_per_period(self) -> int:
        """Return physics steps per control period."""
        return round(PHYSICS_RATE_HZ / self.control_rate_hz)

    @property
    def pool(self) -> int:
        """Return how many boxes an episode may place: the space's most, for each robot."""
        return self.space.obstacles[1] * self.robots

    @property
    def box_size(self) -> Tuple[float, float, float]:
        """Return the boxes' size: the space's side, both ways, and its height (m)."""
        side = self.space.box_size[0]
        return (side, side, self.space.box_height)

    @property
    def tip_angle_rad(self) -> float:
        """Return the lean (rad) past which the robot has fallen."""
        return math.radians(self.tip_angle_deg)

    @property
    def shape(self) -> ObservationShape:
        """Return the observation's sizes and scales."""
        return ObservationShape(self.scan_beams, self.scan_range_m, self.goal_range_m,
                                self.max_linear_m_s, self.max_angular_rad_s)

    @property
    def names(self) -> Tuple[str, ...]:
        """Return the robots' names, in the simulator's order."""
        return robot_names(self.robots)

    def lanes(self) -> Sequence[float]:
        """Return each robot's offset along y (m): its start and goal are shifted by it."""
        middle = (self.robots - 1) / 2.0
        return tuple((i - middle) * LANE_SPACING_M for i in range(self.robots))

    def sim_parameters_for(self, extra: Optional[Mapping[str, Any]] = None) -> Dict[str, Any]:
        """Return the simulator's parameters: the task's, then ``sim_parameters``."""
        parameters: Dict[str, Any] = {
            'physics_rate': PHYSICS_RATE_HZ, 'publish_rate': float(self.control_rate_hz),
            'scan_rate': float(self.control_rate_hz), 'scan_samples': self.scan_rays,
            'scan_angle_min': -math.pi, 'scan_angle_max': math.pi,
            'scan_range_max': float(self.scan_range_m), 'imu_rate': 0.0,
            'max_linear_velocity': float(self.max_linear_m_s),
            'max_angular_velocity': float(self.max_angular_rad_s), 'cmd_vel_timeout': 0.0,
            'world': self.space.world, 'real_time_factor': 0.0,
            'ray_threads': 1}  # vector envs run one per core (sim_parameters may say 2)
        if self.robots > 1:
            parameters['robots'] = list(self.names)
            for name, lane in zip(self.names, self.lanes()):
                parameters[f'{name}.initial_pose'] = [0.0, lane, 0.0]
        parameters.update(self.sim_parameters)
        parameters.update(extra or {})
        return parameters
