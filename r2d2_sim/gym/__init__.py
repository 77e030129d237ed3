"""
Learning on the simulator: Gymnasium and PettingZoo environments, deterministic by seed.

Importing this package registers with Gymnasium (``nondeterministic=False``,
the environment checker left on):

- ``R2D2Nav-v0`` (:class:`~r2d2_sim.gym.env.NavEnv`): drive R2D2 to a goal
  among boxes; a laser scan, the goal in the robot's frame and its speeds
  in, forward and turning speed out;
- ``R2D2NavGoal-v0`` (:class:`~r2d2_sim.gym.env.NavGoalEnv`): the same task
  with Gymnasium-Robotics' multi-goal dictionaries, for hindsight replay.

``gymnasium.make('r2d2_sim.gym:R2D2Nav-v0')`` imports it first. Several
robots in one world are a PettingZoo ``ParallelEnv``
(:func:`~r2d2_sim.gym.multi.parallel_env`). Each has two backends with the
same observations and rewards, bit for bit: ``inproc`` (the ROS-free core
in this process) and ``ros`` (the simulator node in lockstep, its topics in
the loop, where a node of yours can sit between the policy and the robot).
By role: :mod:`~r2d2_sim.gym.settings` (what an environment takes, checked),
:mod:`~r2d2_sim.gym.task` (observation, reward, outcome as numbers),
:mod:`~r2d2_sim.gym.arena` (one world for many episodes: its boxes, a state
saved once), :mod:`~r2d2_sim.gym.backends` and
:mod:`~r2d2_sim.gym.ros_backend`, :mod:`~r2d2_sim.gym.env`,
:mod:`~r2d2_sim.gym.multi` and :mod:`~r2d2_sim.gym.recipes` (vector
environments for Gymnasium, Stable-Baselines3 and RLlib). ``docs/learning.md``
has the spaces, the reward table, the backends, speed and recipes.
Importing it loads no rclpy: only ``backend='ros'`` does.
"""

import gymnasium

from r2d2_sim.gym.settings import BACKENDS, GymError, NavSettings

__all__ = ['GymError', 'NavSettings', 'BACKENDS', 'ENV_IDS', 'MAX_EPISODE_STEPS']

# An episode's time limit (steps of the control period: 20 s at 10 Hz), gymnasium.make's.
MAX_EPISODE_STEPS = 200
ENV_IDS = {'R2D2Nav-v0': 'r2d2_sim.gym.env:NavEnv',
           'R2D2NavGoal-v0': 'r2d2_sim.gym.env:NavGoalEnv'}

for _id, _entry_point in ENV_IDS.items():
    if _id not in gymnasium.registry:
        gymnasium.register(_id, entry_point=_entry_point, max_episode_steps=MAX_EPISODE_STEPS,
                           nondeterministic=False)
