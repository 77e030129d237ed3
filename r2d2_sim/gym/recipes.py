"""
Many environments at once: Gymnasium's vector environments, Stable-Baselines3's, RLlib's.

Each sub-environment is a world of its own; with ``backend='ros'`` each
also leases a ROS domain of its own when it is made (its
:class:`~r2d2_sim.testing.SimHarness` does), so sub-environments in one
process or many never hear each other, and nothing needs to tell them
apart (RLlib gives every sub-environment of a runner the same context).
Processes are started with ``spawn``: a process forked after DDS started
blocks forever (rclpy PR #328), and ``fork`` is the default on Linux.

- :func:`make_vector_env`: ``gymnasium.make_vec`` of ``R2D2Nav-v0``, its
  ``async`` workers spawned;
- :func:`make_sb3_vec_env`: Stable-Baselines3's ``SubprocVecEnv`` (or
  ``DummyVecEnv`` for one process), each sub-environment seeded;
- :func:`rllib_config`: an RLlib ``PPOConfig`` whose env runners make
  ``num_envs_per_env_runner`` sub-environments each.

Stable-Baselines3 and Ray are optional (``pip install r2d2_sim[rl]``):
imported only here, when asked for.
"""

from typing import Any, Callable, Mapping, Optional

import gymnasium

__all__ = ['make_vector_env', 'make_sb3_vec_env', 'make_env', 'rllib_config', 'ENV_ID',
           'START_METHOD']

# gymnasium.make of this id imports r2d2_sim.gym first, in any process.
ENV_ID = 'r2d2_sim.gym:R2D2Nav-v0'
START_METHOD = 'spawn'


def make_vector_env(num_envs: int, *, vectorization_mode: str = 'async', env_id: str = ENV_ID,
                    vector_kwargs: Optional[Mapping[str, Any]] = None,
                    **kwargs: Any) -> gymnasium.vector.VectorEnv:
    """
    Return ``num_envs`` environments as one Gymnasium vector environment.

    ``vectorization_mode``: ``'async'`` (a process each, spawned) or
    ``'sync'`` (all in this process). ``kwargs`` go to every environment
    (``backend``, ``scan_beams``...). Autoreset: the next step (the
    environments' ``metadata['autoreset_mode']``) unless ``vector_kwargs``
    (the vector environment's own arguments, as ``gymnasium.make_vec`` takes
    them) choose another ``autoreset_mode``; the async one's processes are
    spawned unless they name another ``context``.
    """
    own = {'context': START_METHOD} if vectorization_mode == 'async' else {}
    return gymnasium.make_vec(env_id, num_envs=num_envs, vectorization_mode=vectorization_mode,
                              vector_kwargs={**own, **(vector_kwargs or {})}, **kwargs)


def make_env(env_id: str = ENV_ID, **kwargs: Any) -> Callable[[], gymnasium.Env]:
    """Return a function that makes one environment (what vector environments take)."""
    return _Maker(env_id, kwargs)


class _Maker:
    """Makes one environment: a picklable callable, for processes started with ``spawn``."""

    def __init__(self, env_id: str, kwargs: dict) -> None:
        self.env_id = env_id
        self.kwargs = kwargs

    def __call__(self) -> gymnasium.Env:
        return gymnasium.make(self.env_id, **self.kwargs)


def make_sb3_vec_env(num_envs: int, *, seed: Optional[int] = None, env_id: str = ENV_ID,
                     **kwargs: Any) -> Any:
    """
    Return Stable-Baselines3's vector environment of ``num_envs`` environments.

    One: a ``DummyVecEnv`` (this process); more: a ``SubprocVecEnv``, its
    workers spawned. Each is wrapped in SB3's ``Monitor`` (episode returns,
    lengths and ``is_success`` for the logs); ``seed`` seeds environment i
    with ``seed + i`` at its first reset.
    """
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv
    many = num_envs > 1
    return make_vec_env(make_env(env_id, **kwargs), n_envs=num_envs, seed=seed,
                        vec_env_cls=SubprocVecEnv if many else DummyVecEnv,
                        vec_env_kwargs={'start_method': START_METHOD} if many else None,
                        monitor_kwargs={'info_keywords': ('is_success',)})


def rllib_config(*, num_env_runners: int = 1, num_envs_per_env_runner: int = 2,
                 env_id: str = ENV_ID, **env_config: Any) -> Any:
    """
    Return an RLlib ``PPOConfig`` of ``R2D2Nav-v0`` (RLlib's new API stack).

    Each of ``num_env_runners`` runners (a Ray actor, a process each; 0:
    the driver's own) makes ``num_envs_per_env_runner`` sub-environments
    with ``env_config`` as keywords, one after another in its process
    (Gymnasium's ``SyncVectorEnv``): with ``backend='ros'`` each leases its
    own domain. Seeds: RLlib's, ``config.debugging(seed=...)``.
    """
    from ray.rllib.algorithms.ppo import PPOConfig
    return (PPOConfig()
            .environment(env=env_id, env_config=dict(env_config))
            .env_runners(num_env_runners=num_env_runners,
                         num_envs_per_env_runner=num_envs_per_env_runner))
