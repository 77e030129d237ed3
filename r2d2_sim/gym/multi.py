"""
Several robots in one world, one clock: a PettingZoo ``ParallelEnv`` of ``R2D2Nav-v0``'s task.

Each robot is an agent (``r2d2_0``, ``r2d2_1``...) with ``R2D2Nav-v0``'s
observation, action and reward. Every step runs one control period for the
whole world, each robot driven by its action; the others see it in their
scans, and touching another robot is a contact like any other. Each robot
has a lane of its own (:meth:`NavSettings.lanes
<r2d2_sim.gym.settings.NavSettings.lanes>`, 3 m apart), its start, goal and
boxes drawn from the scenario space in it. An agent leaves when its episode
ends (the goal, a contact, a fall, or ``max_cycles`` steps); its robot
stays where it stopped, an obstacle for the others. One world, one noise:
every robot's sensors start from the episode's seed and every laser has
its scan noise (the first lane's draw), as each agent's info says. Both
backends, as the Gymnasium environments.

Reset options: PettingZoo's own API test passes options of its own, so an
option this environment does not know is a one-line warning here, not an
error; ``scenario`` is refused (several robots draw several).
"""

from typing import Any, Callable, Dict, List, Mapping, Optional, Tuple
import warnings

from gymnasium import spaces
import numpy
from pettingzoo import ParallelEnv

from r2d2_sim.gym.arena import placed_scenarios
from r2d2_sim.gym.backends import Backend
from r2d2_sim.gym.env import check_action, Navigation
from r2d2_sim.gym.settings import GymError, nav_settings, reset_options
from r2d2_sim.gym.task import Command, nav_observation, nav_reward

__all__ = ['NavParallelEnv', 'parallel_env', 'MAX_CYCLES']

# Steps before every agent is truncated (20 s at 10 Hz), as R2D2Nav-v0's time limit.
MAX_CYCLES = 200
STOP: Command = (0.0, 0.0)


def parallel_env(**kwargs: Any) -> 'NavParallelEnv':
    """Return a :class:`NavParallelEnv` (PettingZoo's constructor convention)."""
    return NavParallelEnv(**kwargs)


class NavParallelEnv(ParallelEnv):
    """
    R2D2Nav-v0's task for ``robots`` robots (default 2) in one world: a PettingZoo ParallelEnv.

    Keywords: :class:`~r2d2_sim.gym.settings.NavSettings`' fields,
    ``max_cycles`` (steps before truncation), ``render_mode``
    ('rgb_array': the world from above), and for ``backend='ros'``
    ``ros_nodes`` and ``topics`` (each robot's, under its namespace).
    """

    metadata = {'render_modes': ['rgb_array'], 'name': 'r2d2_nav_parallel_v0',
                'is_parallelizable': True, 'render_fps': 10}

    def __init__(self, *, robots: int = 2, max_cycles: int = MAX_CYCLES,
                 render_mode: Optional[str] = None,
                 ros_nodes: Optional[Callable[[Any], Any]] = None,
                 topics: Optional[dict] = None, **settings: Any) -> None:
        if render_mode not in (None, 'rgb_array'):
            raise GymError(f'render_mode must be None or \'rgb_array\', got {render_mode!r}')
        if isinstance(max_cycles, bool) or not isinstance(max_cycles, int) or max_cycles < 1:
            raise GymError(f'max_cycles must be an integer >= 1, got {max_cycles!r}')
        self.settings = nav_settings('NavParallelEnv', settings, robots=robots)
        self.render_mode = render_mode
        self.max_cycles = max_cycles
        self.metadata = dict(self.metadata, render_fps=self.settings.control_rate_hz)
        self.possible_agents: List[str] = list(self.settings.names)
        self.agents: List[str] = []
        self.cycles = 0
        self.np_random = numpy.random.default_rng()
        size = self.settings.shape.nav_size
        low = numpy.full(size, -1.0, dtype=numpy.float32)
        low[:self.settings.scan_beams] = 0.0
        self._observation_space = spaces.Box(low, numpy.ones(size, dtype=numpy.float32),
                                             dtype=numpy.float32)
        self._action_spaces = {agent: spaces.Box(-1.0, 1.0, shape=(2,), dtype=numpy.float32)
                               for agent in self.possible_agents}
        self._observation_spaces = {agent: self._observation_space
                                    for agent in self.possible_agents}
        self.nav = Navigation(self.settings, ros_nodes, topics)

    def observation_space(self, agent: str) -> spaces.Box:
        """Return an agent's observation space (the same object every time)."""
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        """Return an agent's action space: forward and turn in [-1, 1] (the same object)."""
        return self._action_spaces[agent]

    @property
    def backend(self) -> Backend:
        """Return the backend: its ``simulation``, and the ``ros`` one's ``harness``."""
        return self.nav.live

    def reset(self, seed: Optional[int] = None, options: Optional[Mapping[str, Any]] = None
              ) -> Tuple[Dict[str, numpy.ndarray], Dict[str, Dict[str, Any]]]:
        """
        Begin an episode drawn with ``seed`` (None: the generator's next draw).

        Each agent's info: ``distance`` to its goal and ``scenario``, its lane as
        placed (its start, goal and boxes, the episode's noise seed and scan
        noise), which ``R2D2Nav-v0`` made with the same space replays as
        ``reset(options={'scenario': ...})``. A reset its options refuse seeds
        nothing.
        """
        self.nav.check_open()
        unknown = sorted(reset_options(options))
        if 'scenario' in unknown:
            raise GymError('reset option scenario: several robots draw several; give a seed')
        if unknown:
            warnings.warn(f'unknown reset option(s) {", ".join(map(repr, unknown))} ignored: '
                          'NavParallelEnv takes none', stacklevel=2)
        if seed is not None:
            self.np_random = numpy.random.default_rng(seed)
        readings = self.nav.begin(self.nav.draw(self.np_random))
        self.agents = list(self.possible_agents)
        self.cycles = 0
        goals, shape = self.nav.goals, self.settings.shape
        episode = self.nav.episode
        observations = {agent: nav_observation(reading, goal, shape)
                        for agent, reading, goal in zip(self.possible_agents, readings, goals)}
        infos = {agent: {'scenario': placed.to_dict(), 'distance': distance}
                 for agent, placed, distance in zip(
                     self.possible_agents, placed_scenarios(episode) if episode else (),
                     self.nav.distances)}
        return observations, infos

    def step(self, actions: Mapping[str, Any]
             ) -> Tuple[Dict[str, numpy.ndarray], Dict[str, float], Dict[str, bool],
                        Dict[str, bool], Dict[str, Dict[str, Any]]]:
        """Drive every live agent's robot by its action for one period (the others stand)."""
        self.nav.check_open()
        if not self.agents:
            raise GymError('every agent is done: reset the environment')
        if not isinstance(actions, Mapping):
            raise GymError(f'actions must be a dict of agent to action, got '
                           f'{type(actions).__name__}')
        strangers = sorted(set(actions) - set(self.agents))
        missing = [agent for agent in self.agents if agent not in actions]
        if strangers or missing:
            raise GymError(f'actions must be given for the live agents {", ".join(self.agents)}'
                           + (f'; no agent {", ".join(map(str, strangers))}' if strangers else '')
                           + (f'; missing {", ".join(missing)}' if missing else ''))
        settings = self.settings
        commands: List[Command] = []
        for agent in self.possible_agents:
            if agent in actions:
                forward, turn = check_action(actions[agent], agent)
                commands.append((forward * settings.max_linear_m_s,
                                 turn * settings.max_angular_rad_s))
            else:
                commands.append(STOP)
        readings, before, outcomes = self.nav.advance(commands)
        self.cycles += 1
        truncated = self.cycles >= self.max_cycles
        observations, rewards, terminations, truncations, infos = {}, {}, {}, {}, {}
        for index, agent in enumerate(self.possible_agents):
            if agent not in self.agents:
                continue
            outcome = outcomes[index]
            after = self.nav.distances[index]
            observations[agent] = nav_observation(readings[index], self.nav.goals[index],
                                                  settings.shape)
            rewards[agent] = nav_reward(before[index], after, outcome, settings.rewards)
            terminations[agent] = outcome.terminated
            truncations[agent] = truncated and not outcome.terminated
            infos[agent] = {'distance': after, 'reached': outcome.reached,
                            'contact': outcome.contact or '', 'tipped': outcome.tipped,
                            'is_success': outcome.success}
        self.agents = [agent for agent in self.agents
                       if not (terminations[agent] or truncations[agent])]
        return observations, rewards, terminations, truncations, infos

    def render(self) -> Optional[numpy.ndarray]:
        """Return the world from above as an RGB array (render_mode 'rgb_array')."""
        if self.render_mode is None:
            warnings.warn('render() without a render_mode: make the environment with '
                          'render_mode=\'rgb_array\'', stacklevel=2)
            return None
        return self.nav.render('top')

    def close(self) -> None:
        """Close the simulator (and the ROS harness); safe to call twice."""
        self.nav.close()
