"""
Several robots in one world as a PettingZoo ParallelEnv, in process: PettingZoo's tests, seeds.

No ROS. PettingZoo's ``parallel_api_test`` (with few cycles: each is a
control period of a real world) and ``parallel_seed_test``; the robots see
each other and meet; an agent leaves when its episode ends; bad input is
one line.
"""

import warnings

import numpy
from pettingzoo.test import parallel_api_test, parallel_seed_test
import pytest

from common import gym_noisy, parallel_rollout as rollout
from r2d2_sim.farm.scenario import Box, Pose, Scenario
from r2d2_sim.gym import GymError
from r2d2_sim.gym.arena import Episode
from r2d2_sim.gym.multi import parallel_env
from r2d2_sim.model.regions import circle_region


@pytest.fixture
def make():
    """Provide parallel_env, every environment closed after the test."""
    made = []

    def build(**kwargs):
        env = parallel_env(**kwargs)
        made.append(env)
        return env
    yield build
    for env in made:
        env.close()


def test_pettingzoos_api_and_seed_tests_pass(make):
    """parallel_api_test (its unknown option is a warning here) and parallel_seed_test."""
    env = make()
    with warnings.catch_warnings(record=True):
        parallel_api_test(env, num_cycles=30)
    parallel_seed_test(lambda: make(), num_cycles=30)


def test_each_robot_is_an_agent_in_its_lane_and_the_run_repeats(make):
    """Two agents, lanes 3 m apart, each info its lane as placed; a seed repeats its run."""
    env = make()
    assert env.possible_agents == ['r2d2_0', 'r2d2_1']
    _, infos = env.reset(seed=3)
    episode = env.nav.episode
    drawn = [scenario.goal.values[1] for scenario in episode.scenarios]
    assert env.nav.goals[1][1] - env.nav.goals[0][1] == pytest.approx(3.0 + drawn[1] - drawn[0])
    lanes = []
    for agent, start, goal in zip(env.possible_agents, episode.starts, env.nav.goals):
        placed = Scenario.from_dict(infos[agent]['scenario'])
        assert (placed.start, tuple(placed.goal.values[:2])) == (start, tuple(goal))
        lanes.extend(placed.obstacles)
    assert tuple(lanes) == episode.obstacles  # every box placed is in one lane's scenario
    first = rollout(env, 5)
    rollout(env, 6)
    assert rollout(env, 5) == first == rollout(make(), 5)


def test_each_agents_scenario_replays_in_r2d2nav_with_the_noise_its_laser_had(make, gym_make):
    """
    Each agent's info['scenario'] replays in R2D2Nav-v0 of the same space, and states the noise.

    Before, it held every box of the episode (38 % of two-robot episodes more than
    R2D2Nav-v0's 4: "at most 4 boxes"), and each agent's own draw's noise, which
    only r2d2_0's laser ran with.
    """
    space = gym_noisy()['space']
    env, single = make(space=space), gym_make(space=space)
    crowded = 0
    for seed in range(8):
        _, infos = env.reset(seed=seed)
        crowded += len(env.nav.episode.obstacles) > space.obstacles[1]
        for agent, robot in zip(env.possible_agents, env.backend.simulation.robots):
            scenario = infos[agent]['scenario']
            assert (scenario['seed'], scenario['scan_noise_std']) == \
                (robot.config.noise_seed, robot.config.scan_noise_std_m), (seed, agent)
            _, replayed = single.reset(options={'scenario': scenario})
            assert replayed['scenario'] == scenario
            laser = single.unwrapped.backend.simulation.robot.config
            assert (laser.noise_seed, laser.scan_noise_std_m) == \
                (scenario['seed'], scenario['scan_noise_std'])
    assert crowded  # some episodes placed more boxes than one robot's space holds


def test_an_agent_leaves_at_its_end_and_the_other_goes_on(make):
    """r2d2_0 drives into a box in its lane and leaves the agents; r2d2_1 (standing) stays."""
    env = make(robots=2)
    env.reset(seed=1)
    lanes = env.settings.lanes()
    scenarios = env.nav.episode.scenarios
    env.nav.begin(Episode(scenarios, tuple(Pose(0.0, y, 0.0) for y in lanes),
                          tuple(circle_region(3.0, y, 0.3) for y in lanes),
                          (Box(1.2, lanes[0], 0.0, (0.4, 0.4, 0.5)),), 0, 0.0))
    for _ in range(40):
        _, rewards, terminations, _, infos = env.step({agent: numpy.array([1.0, 0.0])
                                                       if agent == 'r2d2_0' else numpy.zeros(2)
                                                       for agent in env.agents})
        if 'r2d2_0' not in env.agents:
            break
    assert terminations['r2d2_0'] and infos['r2d2_0']['contact'] == 'box_0'
    assert rewards['r2d2_0'] < -9.0 and not terminations['r2d2_1']
    assert env.agents == ['r2d2_1']
    with pytest.raises(GymError, match='^actions must be given for the live agents r2d2_1; no '
                                       'agent r2d2_0$'):
        env.step({'r2d2_0': numpy.zeros(2), 'r2d2_1': numpy.zeros(2)})
    env.step({'r2d2_1': numpy.zeros(2)})


def test_bad_input_is_one_line(make):
    """A missing agent, a bad action, a scenario option, a step after close."""
    env = make()
    env.reset(seed=0)
    with pytest.raises(GymError, match='^actions must be given for the live agents r2d2_0, '
                                       'r2d2_1; missing r2d2_1$'):
        env.step({'r2d2_0': numpy.zeros(2)})
    with pytest.raises(GymError, match=r'^the action of r2d2_1 must be within \[-1, 1\]'):
        env.step({'r2d2_0': numpy.zeros(2), 'r2d2_1': numpy.array([0.0, -3.0])})
    with pytest.raises(GymError, match="^NavParallelEnv: unexpected keyword argument 'colour'$"):
        make(colour='blue')
    with pytest.raises(GymError, match='^reset option scenario: several robots draw several'):
        env.reset(options={'scenario': {}})
    with pytest.warns(UserWarning, match="unknown reset option\\(s\\) 'x' ignored"):
        env.reset(options={'x': 1})
    with pytest.raises(GymError, match='^reset options must be a dict, got str '):
        env.reset(options='x')
    env.close()
    with pytest.raises(GymError, match='^the environment is closed'):
        env.step({'r2d2_0': numpy.zeros(2), 'r2d2_1': numpy.zeros(2)})
