"""
The learning environments across processes: vector environments, Ray workers, the recipes.

Every process starts with ``spawn`` (a process forked after DDS started
blocks). The same seed and actions must give the same observations in
every worker as in this process, bit for bit: two AsyncVectorEnv workers,
two Ray actors, both backends. The recipes of docs/learning.md run:
Stable-Baselines3's SubprocVecEnv (a PPO update over it) and RLlib's env
runner with two sub-environments, each on a ROS domain of its own.
"""

import os

import numpy
import pytest

from common import gym_actions, gym_rollout, REPO
import r2d2_sim.gym  # noqa: F401 (registers the environments)
from r2d2_sim.gym.recipes import make_sb3_vec_env, make_vector_env, rllib_config

SEED = 21
STEPS = 25


def local_observations(backend):
    """Return the observations (bytes) of SEED and its actions in this process, to the end."""
    import gymnasium
    env = gymnasium.make('R2D2Nav-v0', backend=backend)
    try:
        observation, _ = env.reset(seed=SEED)
        seen = [observation.tobytes()]
        for action in gym_actions(SEED, STEPS):
            observation, _, terminated, truncated, _ = env.step(action)
            seen.append(observation.tobytes())
            if terminated or truncated:
                break
        return seen
    finally:
        env.close()


@pytest.mark.parametrize('backend', ['inproc', 'ros'])
def test_async_vector_workers_give_the_same_run_as_this_process(backend):
    """Two spawned workers, both seeded SEED, the same actions: equal to each other and here."""
    expected = local_observations(backend)
    vector = make_vector_env(2, backend=backend)
    try:
        assert vector.metadata['autoreset_mode'].value == 'NextStep'
        observations, _ = vector.reset(seed=[SEED, SEED])
        seen = [observations]
        for action in gym_actions(SEED, len(expected) - 1):
            observations, _, _, _, _ = vector.step(numpy.stack([action, action]))
            seen.append(observations)
    finally:
        vector.close()
    for step, (mine, theirs) in enumerate(zip(expected, seen)):
        assert theirs[0].tobytes() == theirs[1].tobytes() == mine, step


@pytest.fixture(scope='module')
def ray_session():
    """Provide a local Ray of two CPUs, its workers with the repository and tests on their path."""
    ray = pytest.importorskip('ray')
    paths = (REPO, os.path.join(REPO, 'test'), os.path.dirname(os.path.abspath(__file__)),
             os.environ.get('PYTHONPATH'))
    env_vars = {'PYTHONPATH': os.pathsep.join(filter(None, paths)),
                'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    ray.init(address='local', num_cpus=2, include_dashboard=False, log_to_driver=False,
             configure_logging=False, runtime_env={'env_vars': env_vars})
    try:
        yield ray
    finally:
        ray.shutdown()


class Roller:
    """A Ray actor: one process, running the rollouts it is asked for."""

    def pid(self):
        """Return the actor's process id."""
        return os.getpid()

    def rollout(self, backend):
        """Return the hash of SEED's rollout with its actions (see common.gym_rollout)."""
        import gymnasium
        env = gymnasium.make('r2d2_sim.gym:R2D2Nav-v0', backend=backend)
        try:
            return gym_rollout(env, SEED, gym_actions(SEED, STEPS))
        finally:
            env.close()


def test_two_ray_workers_give_the_same_runs_as_this_process_in_both_backends(ray_session):
    """Two actors (two processes): each backend's hash equal in both and here."""
    import gymnasium
    ray = ray_session
    actors = [ray.remote(num_cpus=1)(Roller).remote() for _ in range(2)]
    assert len(set(ray.get([actor.pid.remote() for actor in actors]))) == 2
    for backend in ('inproc', 'ros'):
        here = gymnasium.make('R2D2Nav-v0', backend=backend)
        try:
            expected = gym_rollout(here, SEED, gym_actions(SEED, STEPS))
        finally:
            here.close()
        assert ray.get([actor.rollout.remote(backend) for actor in actors]) == [expected] * 2


def test_rllib_env_runners_make_sub_environments_on_domains_of_their_own(ray_session):
    """num_envs_per_env_runner=2 over ROS, in a runner actor: two domains, a sample taken."""
    ray = ray_session
    from ray.rllib.env.single_agent_env_runner import SingleAgentEnvRunner
    config = rllib_config(num_env_runners=1, num_envs_per_env_runner=2, backend='ros')
    runner = ray.remote(num_cpus=1)(SingleAgentEnvRunner).remote(config=config, worker_index=1)
    episodes = ray.get(runner.sample.remote(num_timesteps=20, random_actions=True))
    assert sum(len(episode) for episode in episodes) >= 20
    domains = ray.get(runner.__ray_call__.remote(
        lambda runner: [env.unwrapped.backend.harness.domain_id
                        for env in runner.env.unwrapped.envs]))
    assert len(set(domains)) == 2, domains
    ray.get(runner.stop.remote())


def test_stable_baselines3_ppo_updates_over_spawned_workers_on_ros():
    """The SB3 recipe: two SubprocVecEnv workers over ROS, one PPO update."""
    from stable_baselines3 import PPO
    vector = make_sb3_vec_env(2, seed=0, backend='ros')
    try:
        model = PPO('MlpPolicy', vector, n_steps=16, batch_size=16, n_epochs=1, seed=0,
                    device='cpu')
        model.learn(total_timesteps=32)
        assert model.num_timesteps >= 32
    finally:
        vector.close()
