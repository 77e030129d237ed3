#!/usr/bin/env python3
"""
A policy that learns: Stable-Baselines3 PPO on R2D2Nav-v0, against a random policy.

    .venv/bin/python bench/gym_ppo.py [--steps 200000] [--envs 2] [--backend inproc]

PPO (SB3's defaults but for the rollout size and batch) trains on ``--envs``
environments in spawned processes (``r2d2_sim.gym.recipes.make_sb3_vec_env``)
for ``--steps`` env steps. Every ``--eval-every`` steps the policy (acting
deterministically) runs the same ``--eval-episodes`` evaluation episodes
(seeds 10,000 and up, never trained on); a random policy runs them once.
The success rate is the share of episodes that reach the goal without
touching anything or falling (``info['is_success']``).

Writes ``bench/gym_ppo.json`` (the curve, the budget, the machine and its
load) and ``docs/learning_curve.png`` (success rate and return against env steps,
the random policy's as a line). Numbers are printed, never asserted.
"""

import argparse
import json
import os
import time

from common import BENCH_DIR, background_load, LoadMeter, local_date, machine_info, write_json

RESULTS_PATH = os.path.join(BENCH_DIR, 'gym_ppo.json')
PICTURE_PATH = os.path.join(os.path.dirname(BENCH_DIR), 'docs', 'learning_curve.png')
EVAL_SEED = 10_000


def evaluate(env, act, episodes):
    """Run ``episodes`` evaluation episodes with ``act(observation)``; success rate, return."""
    successes, returns = 0, []
    for index in range(episodes):
        observation, _ = env.reset(seed=EVAL_SEED + index)
        total, done, info = 0.0, False, {}
        while not done:
            observation, reward, terminated, truncated, info = env.step(act(observation))
            total += reward
            done = terminated or truncated
        successes += bool(info.get('is_success'))
        returns.append(total)
    return successes / episodes, sum(returns) / episodes


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--steps', type=int, default=200_000, help='env steps of training')
    parser.add_argument('--envs', type=int, default=2, help='environments (processes)')
    parser.add_argument('--backend', default='inproc', choices=('inproc', 'ros'))
    parser.add_argument('--eval-every', type=int, default=20_000)
    parser.add_argument('--eval-episodes', type=int, default=30)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--draw', action='store_true',
                        help='only draw the picture again from bench/gym_ppo.json')
    args = parser.parse_args()
    if args.draw:
        with open(RESULTS_PATH, encoding='utf-8') as results:
            draw(json.load(results))
        return
    import gymnasium
    import numpy
    import torch
    from stable_baselines3 import PPO
    import r2d2_sim.gym  # noqa: F401
    from r2d2_sim.gym.recipes import make_sb3_vec_env
    torch.set_num_threads(1)  # the environments have the other core
    results = {'date': local_date(), 'machine': machine_info(), 'args': vars(args),
               'load_average_before': os.getloadavg(), 'other_load_before': background_load(2.0)}
    evaluation = gymnasium.make('R2D2Nav-v0', backend=args.backend)
    rng = numpy.random.default_rng(args.seed)
    random_rate, random_return = evaluate(
        evaluation, lambda _: rng.uniform(-1, 1, 2).astype(numpy.float32), args.eval_episodes)
    results['random'] = {'success_rate': random_rate, 'mean_return': random_return}
    print(f'random policy: success {random_rate:.2f}, mean return {random_return:.2f}')
    vector = make_sb3_vec_env(args.envs, seed=args.seed, backend=args.backend)
    model = PPO('MlpPolicy', vector, n_steps=1024, batch_size=256, n_epochs=10,
                learning_rate=3e-4, gamma=0.99, gae_lambda=0.95, ent_coef=0.0, seed=args.seed,
                device='cpu', verbose=0)
    curve = []
    meter = LoadMeter().start()
    started = time.perf_counter()
    trained = 0
    while trained < args.steps:
        model.learn(total_timesteps=min(args.eval_every, args.steps - trained),
                    reset_num_timesteps=False)
        trained = model.num_timesteps
        train_s = time.perf_counter() - started
        rate, mean_return = evaluate(
            evaluation, lambda obs: model.predict(obs, deterministic=True)[0],
            args.eval_episodes)
        curve.append({'env_steps': trained, 'wall_s': train_s, 'success_rate': rate,
                      'mean_return': mean_return})
        print(f'{trained:7d} env steps, {train_s / 60:5.1f} min: success {rate:.2f}, '
              f'mean return {mean_return:.2f}', flush=True)
        started += time.perf_counter() - started - train_s  # evaluations are not training
    results['load_during_training'] = meter.stop()
    results['curve'] = curve
    results['trained'] = curve[-1]
    results['load_average_after'] = os.getloadavg()
    vector.close()
    evaluation.close()
    write_json(RESULTS_PATH, results)
    draw(results)
    print(f'PPO after {curve[-1]["env_steps"]} env steps ({curve[-1]["wall_s"] / 60:.1f} min of '
          f'training): success {curve[-1]["success_rate"]:.2f} against the random policy\'s '
          f'{random_rate:.2f}')


def draw(results):
    """Draw the learning curve: success rate and mean return against env steps."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    curve = results['curve']
    steps = [point['env_steps'] / 1000 for point in curve]
    figure, (success, returns) = plt.subplots(1, 2, figsize=(10, 4))
    success.plot(steps, [point['success_rate'] for point in curve], 'o-', label='PPO')
    success.axhline(results['random']['success_rate'], color='grey', ls='--', label='random')
    success.set_ylim(-0.02, 1.02)
    success.set_xlabel('env steps (thousands)')
    success.set_ylabel(f'success rate ({results["args"]["eval_episodes"]} episodes)')
    success.legend()
    returns.plot(steps, [point['mean_return'] for point in curve], 'o-', label='PPO')
    returns.axhline(results['random']['mean_return'], color='grey', ls='--', label='random')
    returns.set_xlabel('env steps (thousands)')
    returns.set_ylabel('mean return')
    returns.legend()
    figure.suptitle(f'SB3 PPO on R2D2Nav-v0 ({results["args"]["backend"]}, '
                    f'{results["args"]["envs"]} processes, {results["machine"]["cores"]} cores)')
    figure.tight_layout()
    figure.savefig(PICTURE_PATH, dpi=80)


if __name__ == '__main__':
    main()
