"""
The Gymnasium environments: ``R2D2Nav-v0`` and its multi-goal form ``R2D2NavGoal-v0``.

Both drive R2D2 to a goal among boxes, one control period per step, in a
world drawn from the farm's scenario space at every reset. They share a
:class:`Navigation` (the backend, the episode drawn, the goals, rendering),
which the PettingZoo environment (:mod:`r2d2_sim.gym.multi`) shares too.

Seeding: ``reset(seed=s)`` seeds the environment's generator, which draws
each robot's scenario seed; the scenario's seed starts every noise stream
of the episode (the laser's...). So the same seed and the same actions give
the same observations, rewards and infos, bit for bit, in either backend and
in any process, whatever episodes ran before. Bad input is one line
(:class:`~r2d2_sim.gym.settings.GymError`): an action outside the space or
not a number, a reset option the environment does not know, a step after
``close``.
"""

import dataclasses
import math
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import gymnasium
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
import numpy

from r2d2_sim.errors import RefusedError, SetupError
from r2d2_sim.farm.scenario import Scenario, ScenarioError
from r2d2_sim.gym.arena import Episode, episode_of
from r2d2_sim.gym.backends import Backend, make_backend
from r2d2_sim.gym.settings import GymError, nav_settings, NavSettings, reset_options
from r2d2_sim.gym.task import (
    Command, goal_distance, goal_observation, goal_reward, nav_observation, nav_reward, Outcome,
    Reading, GOAL_MARGIN_M, WORLD_EXTENT_M)
from r2d2_sim.model.camera import projection_matrix, view_matrix
from r2d2_sim.model.regions import circle_region

__all__ = ['NavEnv', 'NavGoalEnv', 'Navigation', 'RENDER_VIEWS', 'check_action', 'SEED_LIMIT']

# Scenario seeds are drawn below this (the farm's range).
SEED_LIMIT = 2**31
# render(): the whole arena from above, or the robot's head camera.
RENDER_VIEWS = ('top', 'camera')
RENDER_SIZE_PX = (320, 240)
# The rate the head camera is made with for render() (it only renders when asked).
RENDER_RATE_HZ = 10.0
# The top view's camera: above the arena's middle, looking down, its field of view
# (vertical) framing everything at this height above the ground (the robot's middle: its
# head, nearer the camera, looks a little larger) with this margin around it, and at least
# this much of the arena, up the image.
TOP_VIEW_FOV_DEG = 60.0
TOP_VIEW_PLANE_M = 0.5
TOP_VIEW_MARGIN_M = 0.5
TOP_VIEW_MIN_HEIGHT_M = 2.0
# How far R2D2's body reaches from its centre, as the top view frames it (m).
ROBOT_RADIUS_M = 0.35
RESET_OPTIONS = ('scenario',)


def check_action(action: Any, robot: str = '') -> Command:
    """
    Return a robot's action (two numbers in [-1, 1]) as floats; GymError (one line) if not.

    Refuses anything else in one line: another shape, NaN or infinity,
    values outside [-1, 1].
    """
    who = f' of {robot}' if robot else ''
    try:
        values = numpy.asarray(action, dtype=numpy.float64)
    except (TypeError, ValueError):
        raise GymError(f'the action{who} must be two numbers in [-1, 1] (forward, turn), got '
                       f'{_short(action)}') from None
    if values.shape != (2,):
        raise GymError(f'the action{who} must be two numbers in [-1, 1] (forward, turn), got '
                       f'shape {values.shape}: {_short(action)}')
    if not numpy.all(numpy.isfinite(values)):
        raise GymError(f'the action{who} must be finite numbers, got {_short(action)}')
    if numpy.any(numpy.abs(values) > 1.0):
        raise GymError(f'the action{who} must be within [-1, 1], got {_short(action)}')
    return float(values[0]), float(values[1])


def _short(value: Any) -> str:
    text = repr(value).replace('\n', ' ')
    return text if len(text) <= 80 else text[:77] + '...'


class Navigation:
    """
    The task's world behind any API: the backend, the episode drawn, each robot's goal.

    :meth:`begin` draws and places an episode; :meth:`advance` runs one
    control period and says what happened to each robot. ``ros_nodes(harness)``
    and ``topics`` are the ``ros`` backend's (see
    :class:`~r2d2_sim.gym.ros_backend.RosBackend`).
    """

    def __init__(self, settings: NavSettings, ros_nodes: Optional[Callable[[Any], Any]] = None,
                 topics: Optional[dict] = None) -> None:
        self.settings = settings
        self.shape = settings.shape
        self.backend: Optional[Backend] = make_backend(settings, ros_nodes, topics)
        self.episode: Optional[Episode] = None
        self.goals: List[Tuple[float, float]] = []
        self.readings: List[Reading] = []
        self.distances: List[float] = []
        self._camera: Any = None  # the head camera render() looks through, made when first asked

    @property
    def live(self) -> Backend:
        """Return the backend; GymError once closed."""
        if self.backend is None:
            raise GymError('the environment is closed: make a new one')
        return self.backend

    def check_open(self) -> None:
        """Raise GymError (one line) once the environment is closed."""
        self.live  # noqa: B018 (the property raises)

    def draw(self, rng: numpy.random.Generator) -> Episode:
        """Return an episode drawn with ``rng``: a scenario seed per robot."""
        seeds = [int(rng.integers(0, SEED_LIMIT)) for _ in range(self.settings.robots)]
        return episode_of(self.settings.space, seeds, self.settings.lanes())

    def begin(self, episode: Episode) -> List[Reading]:
        """Place ``episode`` in the world; return each robot's first reading."""
        backend = self.live
        self.episode = None  # a start that fails leaves no episode to step ("reset first")
        try:
            with backend.core():
                readings = backend.start(episode)
        except (SetupError, RefusedError) as exc:  # a replayed scenario the world refuses
            raise GymError(f'the episode cannot start: {exc}') from None
        self.episode = episode
        self.goals = episode.goal_points()
        self._take(readings)
        return readings

    def advance(self, commands: Sequence[Command]
                ) -> Tuple[List[Reading], List[float], List[Outcome]]:
        """Run one period; return each robot's reading, distance before it, and outcome."""
        backend = self.live
        if self.episode is None:
            raise GymError('reset the environment before stepping it')
        before = list(self.distances)
        readings = backend.act(commands)
        outcomes = backend.outcomes()
        self._take(readings)
        return readings, before, outcomes

    def _take(self, readings: List[Reading]) -> None:
        self.readings = readings
        self.distances = [goal_distance(r, g) for r, g in zip(readings, self.goals)]

    def render(self, view: str = 'top') -> numpy.ndarray:
        """Return an RGB image (height, width, 3) of the world now: from above, or the camera."""
        backend = self.live
        width, height = RENDER_SIZE_PX
        with backend.core():
            simulation = backend.simulation
            if view == 'camera':
                if self._camera is None:
                    # The head camera of the first robot, made for rendering (it draws no
                    # noise): its size and field of view are the robot's camera parameters.
                    from r2d2_sim.sim.robots.sensors import HeadCamera
                    robot = simulation.robot
                    config = dataclasses.replace(robot.config, camera_rate_hz=RENDER_RATE_HZ)
                    self._camera = HeadCamera(simulation.world, robot.body, config)
                k = self._camera.intrinsics
                return numpy.frombuffer(self._camera.render().rgb, dtype=numpy.uint8).reshape(
                    k.height_px, k.width_px, 3).copy()
            rgb, _ = simulation.world.render(width, height, *self.top_view())
        return numpy.frombuffer(rgb, dtype=numpy.uint8).reshape(height, width, 3).copy()

    def top_view(self) -> Tuple[List[float], List[float]]:
        """
        Return the top view's view and projection matrices: every start, goal and box in sight.

        A map's axes, as RViz's top-down view and a plot: the world's x to the
        right, its y up (REP-103, seen from above). The camera looks straight
        down on the middle of the episode's starts, goals and boxes, from as
        high as the wider of their two extents needs (the image is 4:3), with
        ``TOP_VIEW_MARGIN_M`` around them.
        """
        width, height = RENDER_SIZE_PX
        # (x, y, radius) of what must be seen: the robots, the goal circles, the boxes.
        things = [(0.0, 0.0, ROBOT_RADIUS_M)]
        if self.episode is not None:
            things = ([(s.x, s.y, ROBOT_RADIUS_M) for s in self.episode.starts]
                      + [(g.values[0], g.values[1], g.values[2]) for g in self.episode.goals]
                      + [(b.x, b.y, math.hypot(b.size[0], b.size[1]) / 2.0)
                         for b in self.episode.obstacles])
        low_x, high_x = min(t[0] - t[2] for t in things), max(t[0] + t[2] for t in things)
        low_y, high_y = min(t[1] - t[2] for t in things), max(t[1] + t[2] for t in things)
        # Half the height seen at the framing plane: the y extent, or the x extent over 4:3.
        half_height = max(high_y - low_y + 2.0 * TOP_VIEW_MARGIN_M,
                          (high_x - low_x + 2.0 * TOP_VIEW_MARGIN_M) * height / width,
                          TOP_VIEW_MIN_HEIGHT_M) / 2.0
        distance = half_height / math.tan(math.radians(TOP_VIEW_FOV_DEG) / 2.0)
        eye = ((low_x + high_x) / 2.0, (low_y + high_y) / 2.0, TOP_VIEW_PLANE_M + distance)
        view = view_matrix(eye, (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))  # y up, so x to the right
        return view, projection_matrix(width, height, TOP_VIEW_FOV_DEG, 0.1, eye[2] + 10.0)

    def close(self) -> None:
        """Close the backend; safe to call twice."""
        if self.backend is not None:
            backend, self.backend = self.backend, None
            backend.close()


def _metadata(settings_rate_hz: float = 10.0) -> Dict[str, Any]:
    return {'render_modes': ['rgb_array'], 'render_fps': settings_rate_hz,
            'autoreset_mode': AutoresetMode.NEXT_STEP}


class _Env(gymnasium.Env):
    """What both Gymnasium environments share: settings, the Navigation, reset and checks."""

    metadata = _metadata()

    def __init__(self, *, render_mode: Optional[str] = None, render_view: str = 'top',
                 ros_nodes: Optional[Callable[[Any], Any]] = None,
                 topics: Optional[dict] = None, **settings: Any) -> None:
        if render_mode not in (None, 'rgb_array'):
            raise GymError(f'render_mode must be None or \'rgb_array\', got {render_mode!r} '
                           '(a live view: sim_parameters={\'gui\': True}, or '
                           '{\'foxglove_port\': 8765} with backend=\'ros\')')
        if render_view not in RENDER_VIEWS:
            raise GymError(f'render_view must be one of {", ".join(RENDER_VIEWS)}, got '
                           f'{render_view!r}')
        self.settings = nav_settings(type(self).__name__, settings)
        if self.settings.robots != 1:
            raise GymError('a Gymnasium environment drives one robot: robots=1 (several: '
                           'r2d2_sim.gym.parallel_env)')
        self.render_mode = render_mode
        self.render_view = render_view
        self.metadata = _metadata(self.settings.control_rate_hz)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=numpy.float32)
        self._configure()
        # Last: every check above raises before a simulator (a thread, a ROS domain) exists.
        self.nav = Navigation(self.settings, ros_nodes, topics)
        self.scenario: Optional[Scenario] = None
        self._terminated = False  # the episode ended: a step then is refused until a reset

    def _configure(self) -> None:
        """Set the observation space and check what the subclass needs, before any backend."""
        raise NotImplementedError

    @property
    def backend(self) -> Backend:
        """Return the backend: its ``simulation``, and the ``ros`` one's ``harness``."""
        return self.nav.live

    def _begin(self, seed: Optional[int], options: Optional[Mapping[str, Any]]
               ) -> Tuple[Reading, Dict[str, Any]]:
        """
        Seed, draw (or take the option's scenario) and place an episode; its info.

        Options are read first: a reset they refuse seeds nothing and leaves the
        episode as it was (a terminated one stays terminated).
        """
        options = reset_options(options)
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            raise GymError(f'unknown reset option(s) {", ".join(map(repr, unknown))}: '
                           f'{type(self).__name__} takes {", ".join(RESET_OPTIONS)}')
        self.nav.check_open()  # a closed environment says so before anything is drawn
        given = self._episode_of(options['scenario']) if 'scenario' in options else None
        super().reset(seed=seed)
        self._terminated = False
        episode = given if given is not None else self._checked(self.nav.draw(self.np_random))
        reading = self.nav.begin(episode)[0]
        self.scenario = episode.scenarios[0]
        return reading, {'scenario': self.scenario.to_dict(), 'distance': self.nav.distances[0]}

    def _episode_of(self, given: Any) -> Episode:
        """Return the episode of a scenario given as a reset option (Scenario, dict or JSON)."""
        try:
            if isinstance(given, str):
                given = Scenario.from_json(given)
            elif isinstance(given, Mapping):
                given = Scenario.from_dict(given)
        except ScenarioError as exc:
            raise GymError(f'reset option scenario: {exc}') from None
        if not isinstance(given, Scenario):
            raise GymError(f'reset option scenario must be a Scenario, its dict or JSON, got '
                           f'{type(given).__name__}')
        if len(given.obstacles) > self.settings.space.obstacles[1] or any(
                tuple(b.size) != (self.settings.space.box_size[0],) * 2
                + (self.settings.space.box_height,) for b in given.obstacles):
            raise GymError(f'reset option scenario: at most {self.settings.space.obstacles[1]} '
                           f'boxes of the space\'s size')
        goal = given.goal
        if goal.kind != 'circle':
            raise GymError('reset option scenario: the goal must be a circle')
        # What an environment keeps for all its episodes: a scenario may not change it
        # (it would run in the environment's own, and say otherwise in its info).
        if given.world != self.settings.space.world:
            raise GymError(f'reset option scenario: its world {given.world!r} is not the '
                           f'environment\'s ({self.settings.space.world!r})')
        if given.limits:
            raise GymError('reset option scenario: robot limits are the environment\'s '
                           '(max_linear_m_s, max_angular_rad_s), not a scenario\'s')
        return self._checked(Episode((given,), (given.start,), (circle_region(*goal.values[:3]),),
                                     given.obstacles, given.seed, given.scan_noise_std))

    def _checked(self, episode: Episode) -> Episode:
        """Return ``episode`` if this environment can run it (GymError if not): any, here."""
        return episode

    def _command(self, action: Any) -> Command:
        self.nav.check_open()  # a step after close: that line, not the action's
        if self._terminated:  # its outcome would be paid again, step after step
            raise GymError('the episode has terminated: reset the environment')
        forward, turn = check_action(action)
        settings = self.settings
        return forward * settings.max_linear_m_s, turn * settings.max_angular_rad_s

    def render(self) -> Optional[numpy.ndarray]:
        """Return the world as an RGB array (render_mode 'rgb_array'); None without a mode."""
        if self.render_mode is None:
            gymnasium.logger.warn('render() without a render_mode: make the environment with '
                                  'render_mode=\'rgb_array\'')
            return None
        return self.nav.render(self.render_view)

    def close(self) -> None:
        """Close the simulator (and the ROS harness); safe to call twice."""
        self.nav.close()


class NavEnv(_Env):
    """
    ``R2D2Nav-v0``: drive R2D2 to a goal among boxes (observation and rewards in docs/learning.md).

    Observation: float32, ``scan_beams`` scan sectors in [0, 1], then the
    goal ahead and left over ``goal_range_m``, then the forward and turning
    speeds over the limits (all in [-1, 1]). Action: forward and turn in
    [-1, 1], times the limits. Reward: progress toward the goal, a small
    cost per step, a bonus at the goal, a penalty for a contact or a fall
    (:class:`~r2d2_sim.gym.task.Rewards`). Terminated at the goal, a contact
    or a fall, as the run's watch saw any physics step; truncated by
    ``gymnasium.make``'s time limit (200 steps, 20 s at 10 Hz). Keywords:
    :class:`~r2d2_sim.gym.settings.NavSettings`' fields, ``render_mode``,
    ``render_view`` ('top', 'camera'), and for ``backend='ros'``
    ``ros_nodes`` and ``topics``.
    """

    def _configure(self) -> None:
        """Set the observation space: the scan sectors, the goal, the speeds."""
        size = self.settings.shape.nav_size
        low = numpy.full(size, -1.0, dtype=numpy.float32)
        low[:self.settings.scan_beams] = 0.0
        self.observation_space = spaces.Box(low, numpy.ones(size, dtype=numpy.float32),
                                            dtype=numpy.float32)

    def reset(self, *, seed: Optional[int] = None,
              options: Optional[Dict[str, Any]] = None) -> Tuple[numpy.ndarray, Dict[str, Any]]:
        """Begin an episode: drawn with ``seed``, or ``options={'scenario': ...}`` replayed."""
        reading, info = self._begin(seed, options)
        return nav_observation(reading, self.nav.goals[0], self.nav.shape), info

    def step(self, action: Any) -> Tuple[numpy.ndarray, float, bool, bool, Dict[str, Any]]:
        """Drive one control period; return observation, reward, terminated, False, info."""
        command = self._command(action)
        readings, before, outcomes = self.nav.advance([command])
        reading, outcome = readings[0], outcomes[0]
        after = self.nav.distances[0]
        reward = nav_reward(before[0], after, outcome, self.settings.rewards)
        info = {'distance': after, 'reached': outcome.reached, 'contact': outcome.contact or '',
                'tipped': outcome.tipped, 'is_success': outcome.success}
        self._terminated = outcome.terminated
        return (nav_observation(reading, self.nav.goals[0], self.nav.shape), reward,
                outcome.terminated, False, info)


class NavGoalEnv(_Env):
    """
    ``R2D2NavGoal-v0``: the same task as Gymnasium-Robotics' multi-goal dictionaries, for HER.

    Observation: ``observation`` (scan sectors, speeds, cos and sin of the
    heading), ``achieved_goal`` (where the robot stands, m, world frame) and
    ``desired_goal`` (the goal's centre). Reward: :meth:`compute_reward`, 0
    within the goal's tolerance and -1 elsewhere, for any goal (so replayed
    goals are scored alike). Terminated within the goal, or at a contact or
    a fall (:meth:`compute_terminated`); truncated where the robot leaves
    the ±``WORLD_EXTENT_M`` square positions are observed in
    (:meth:`compute_truncated`). Starts and goals keep ``GOAL_MARGIN_M``
    inside it, and every goal has the space's tolerance: a replayed
    scenario that does not is refused.
    """

    def _configure(self) -> None:
        """Check that the space's starts and goals lie in the observed square; the spaces."""
        space = self.settings.space
        extent = WORLD_EXTENT_M
        limit = extent - GOAL_MARGIN_M
        if max(map(abs, space.start_area)) > limit \
                or max(map(abs, space.goal_area)) + space.goal_tolerance > limit:
            raise GymError(f'space: R2D2NavGoal-v0\'s starts and goal circles must lie within '
                           f'{limit:g} m of the origin in x and y (start_area '
                           f'{space.start_area}, goal_area {space.goal_area})')
        self.tolerance_m = space.goal_tolerance  # one for every goal, relabelled ones too
        size = self.settings.shape.goal_observation_size
        low = numpy.full(size, -1.0, dtype=numpy.float32)
        low[:self.settings.scan_beams] = 0.0
        self.observation_space = spaces.Dict({
            'observation': spaces.Box(low, numpy.ones(size, dtype=numpy.float32),
                                      dtype=numpy.float32),
            'achieved_goal': spaces.Box(-extent, extent, shape=(2,), dtype=numpy.float32),
            'desired_goal': spaces.Box(-extent, extent, shape=(2,), dtype=numpy.float32)})

    def _checked(self, episode: Episode) -> Episode:
        """Return ``episode``; GymError if its goal's tolerance or its ends do not fit."""
        start, (x, y, radius) = episode.starts[0], episode.goals[0].values[:3]
        if radius != self.tolerance_m:
            raise GymError(f'the scenario\'s goal tolerance {radius:g} m is not the '
                           f'environment\'s {self.tolerance_m:g} m (the space\'s '
                           'goal_tolerance): compute_reward scores every goal with one')
        limit = WORLD_EXTENT_M - GOAL_MARGIN_M
        if max(abs(start.x), abs(start.y)) > limit or max(abs(x), abs(y)) + radius > limit:
            raise GymError(f'the scenario\'s start and goal circle must lie within {limit:g} m '
                           'of the origin in x and y')
        return episode

    def reset(self, *, seed: Optional[int] = None,
              options: Optional[Dict[str, Any]] = None) -> Tuple[Dict[str, numpy.ndarray],
                                                                 Dict[str, Any]]:
        """Begin an episode: drawn with ``seed``, or ``options={'scenario': ...}`` replayed."""
        reading, info = self._begin(seed, options)
        return goal_observation(reading, self.nav.goals[0], self.nav.shape), info

    def step(self, action: Any) -> Tuple[Dict[str, numpy.ndarray], float, bool, bool,
                                         Dict[str, Any]]:
        """Drive one control period; return observation, reward, terminated, False, info."""
        command = self._command(action)
        readings, _, outcomes = self.nav.advance([command])
        observation = goal_observation(readings[0], self.nav.goals[0], self.nav.shape)
        outcome = outcomes[0]
        info = {'distance': self.nav.distances[0], 'contact': outcome.contact or '',
                'tipped': outcome.tipped, 'failed': outcome.failed}
        achieved, desired = observation['achieved_goal'], observation['desired_goal']
        reward = float(self.compute_reward(achieved, desired, info))
        terminated = bool(self.compute_terminated(achieved, desired, info))
        truncated = bool(self.compute_truncated(achieved, desired, info))
        info['is_success'] = reward == 0.0 and not outcome.failed
        self._terminated = terminated
        return observation, reward, terminated, truncated, info

    def compute_reward(self, achieved_goal: numpy.ndarray, desired_goal: numpy.ndarray,
                       info: Any) -> numpy.ndarray:
        """Return 0 where the achieved goal is within the tolerance of the desired, else -1."""
        return goal_reward(achieved_goal, desired_goal, self.tolerance_m)

    def compute_terminated(self, achieved_goal: numpy.ndarray, desired_goal: numpy.ndarray,
                           info: Any) -> numpy.ndarray:
        """Return True within the goal, or where the info says the robot touched or fell."""
        within = goal_reward(achieved_goal, desired_goal, self.tolerance_m) == 0.0
        return numpy.logical_or(within, _failed(info))

    def compute_truncated(self, achieved_goal: numpy.ndarray, desired_goal: numpy.ndarray,
                          info: Any) -> numpy.ndarray:
        """
        Return True where the robot stands on the edge of the observed square (or beyond).

        The time limit truncates too (gymnasium.make's wrapper).
        """
        return numpy.any(numpy.abs(numpy.asarray(achieved_goal)) >= WORLD_EXTENT_M, axis=-1)


def _failed(info: Any) -> Any:
    """Return the info's 'failed' (one dict, or an array or list of them)."""
    if isinstance(info, Mapping):
        return bool(info.get('failed', False))
    return numpy.array([bool(i.get('failed', False)) for i in info], dtype=bool)
