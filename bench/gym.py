#!/usr/bin/env python3
"""
What a learning environment costs: R2D2Nav-v0 against raw PyBullet, over ROS, its reset, Ant-v5.

    .venv/bin/python bench/gym.py [--quick]

Everything in one run, ratios side by side, on whatever else the machine runs
(its load is measured and written beside the numbers):

- **inproc / raw PyBullet**: R2D2Nav-v0 (``inproc``, default settings: a
  360-beam scan, 24 physics steps per 10 Hz step) against a raw PyBullet loop
  doing the same physics steps and ray casts on the same world: each episode
  is run once with the environment's motor commands and ray casts recorded,
  then, in turns, by the environment (``step``) and by the raw loop replaying
  the recording on the environment's own client (``setJointMotorControlArray``
  when a command changes, ``stepSimulation``, ``rayTestBatch``), from the same
  restored start. The raw loop ends where the environment ended, bit for bit
  (checked), so both did the same physics. Env steps per second of each. And
  a third loop in the same turns, the raw replay plus only the PyBullet
  queries an environment that watches every physics step cannot do without
  (the base's velocity for the blow-up check, its pose for the goal and the
  tip, the robot's contact points), no Python around them: the ceiling of
  the ratio for any environment that checks every physics step.
- **ros overhead**: the same episodes' actions in the ``ros`` backend and in
  ``inproc``, a step of each in turn: the median of the differences (ms).
- **reset**: the median wall time of ``reset(seed)`` after a few steps, both backends.
- **MuJoCo Ant-v5** (Gymnasium, random actions) env steps per second, in
  turns with R2D2Nav-v0's.
- **scaling**: ``AsyncVectorEnv`` (spawn) of 1 and 2 ``inproc`` environments, env
  steps per second over all.

Prints a table and writes ``bench/gym.json``. Numbers are printed, never asserted.
"""

import argparse
import os
import statistics
import time

from common import BENCH_DIR, background_load, LoadMeter, local_date, machine_info, write_json

RESULTS_PATH = os.path.join(BENCH_DIR, 'gym.json')


# -- a policy that drives somewhere: long episodes, both backends given the same actions ----

def heuristic(observation, beams, rng):
    """Return an action heading for the goal (ahead/left in the observation), a little noise."""
    import math
    import numpy
    ahead, left = float(observation[beams]), float(observation[beams + 1])
    turn = max(-1.0, min(1.0, 2.0 * math.atan2(left, ahead) / math.pi + rng.normal(0.0, 0.2)))
    forward = 0.8 if abs(turn) < 0.5 else 0.2
    return numpy.array([forward, turn], dtype=numpy.float32)


def episode_actions(env, seeds, max_steps):
    """Return each seed's actions (the heuristic's, in the inproc environment) to its end."""
    import numpy
    beams = env.unwrapped.settings.scan_beams
    episodes = []
    for seed in seeds:
        rng = numpy.random.default_rng(seed)
        observation, _ = env.reset(seed=seed)
        actions = []
        for _ in range(max_steps):
            action = heuristic(observation, beams, rng)
            actions.append(action)
            observation, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
        episodes.append((seed, actions))
    return episodes


# -- the raw loop: what the environment did to PyBullet, replayed --------------------------

def record(env, seed, actions):
    """Run an episode recording every motor command, physics step and ray cast; and the end."""
    import pybullet
    from r2d2_sim.physics.raycast import ray_mask
    unwrapped = env.unwrapped
    simulation = unwrapped.backend.simulation
    world, body = simulation.world, simulation.robot.body
    events = []
    originals = {'step': world.step, 'cast': world.cast_requests,
                 'drive': body.set_joint_velocities, 'hold': body.hold_joints}

    def step(steps=1):
        events.append(('step', steps))
        originals['step'](steps)

    def cast(requests):
        for request in requests:
            events.append(('rays', request.starts.copy(), request.ends.copy(),
                           ray_mask(request.group) if request.group else -1))
        return originals['cast'](requests)

    def anchor(indices, anchored):
        changed = [link for link in indices if (link in body._anchored) != anchored]
        if changed:
            events.append(('anchor', changed, int(anchored)))

    def drive(indices, velocities, forces):
        anchor(indices, False)
        events.append(('motor', list(indices), pybullet.VELOCITY_CONTROL,
                       {'targetVelocities': list(velocities), 'forces': list(forces)}))
        originals['drive'](indices, velocities, forces)

    def hold(indices, forces, positions=None):
        if positions is None:
            positions = body.joint_states(indices).positions
        anchor(indices, True)
        events.append(('motor', list(indices), pybullet.POSITION_CONTROL,
                       {'targetPositions': list(positions),
                        'targetVelocities': [0.0] * len(indices), 'forces': list(forces)}))
        originals['hold'](indices, forces, positions)

    env.reset(seed=seed)
    world.step, world.cast_requests = step, cast
    body.set_joint_velocities, body.hold_joints = drive, hold
    try:
        for action in actions:
            env.step(action)
    finally:
        world.step, world.cast_requests = originals['step'], originals['cast']
        del body.set_joint_velocities, body.hold_joints  # the class's again
    return events, body.world_state()


def replay(env, seed, events, queries=False):
    """
    Restore the episode's start, replay ``events`` with PyBullet alone; return (s, end).

    ``queries``: after each physics step also ask what a per-step watch must
    (base velocity, base pose, contact points), without looking at the answers.
    """
    simulation = env.unwrapped.backend.simulation
    env.reset(seed=seed)
    world, body = simulation.world, simulation.robot.body
    client = world.client
    cid, robot_id = client._client, body.id
    import pybullet
    step, motors, cast = pybullet.stepSimulation, pybullet.setJointMotorControlArray, \
        pybullet.rayTestBatch
    dynamics = pybullet.changeDynamics
    velocity, pose = pybullet.getBaseVelocity, pybullet.getBasePositionAndOrientation
    contacts = pybullet.getContactPoints
    started = time.perf_counter()
    for event in events:
        kind = event[0]
        if kind == 'step':
            if queries:
                for _ in range(event[1]):
                    step(physicsClientId=cid)
                    velocity(robot_id, physicsClientId=cid)
                    pose(robot_id, physicsClientId=cid)
                    contacts(bodyA=robot_id, physicsClientId=cid)
                continue
            for _ in range(event[1]):
                step(physicsClientId=cid)
        elif kind == 'rays':
            cast(event[1], event[2], collisionFilterMask=event[3], physicsClientId=cid)
        elif kind == 'motor':
            motors(robot_id, event[1], event[2], physicsClientId=cid, **event[3])
        else:  # the wheels' contacts anchored (braked) or let go
            for link in event[1]:
                dynamics(robot_id, link, frictionAnchor=event[2], physicsClientId=cid)
    seconds = time.perf_counter() - started
    # The body remembers which wheels' contacts are anchored: as the replay left them.
    anchored = set(body._anchored)
    for event in events:
        if event[0] == 'anchor':
            (anchored.update if event[2] else anchored.difference_update)(event[1])
    body._anchored = anchored
    return seconds, body.world_state()


def timed_episode(env, seed, actions):
    """Return the wall time of an episode's steps (its reset untimed)."""
    env.reset(seed=seed)
    started = time.perf_counter()
    for action in actions:
        env.step(action)
    return time.perf_counter() - started


def inproc_against_raw(env, episodes, rounds):
    """Return env and raw env-steps per second over ``rounds`` of the episodes, in turns."""
    recordings = [record(env, seed, actions) for seed, actions in episodes]
    env_s = raw_s = queried_s = 0.0
    steps = 0
    same = True
    for _ in range(rounds):
        for (seed, actions), (events, end) in zip(episodes, recordings):
            env_s += timed_episode(env, seed, actions)
            seconds, raw_end = replay(env, seed, events)
            raw_s += seconds
            same = same and raw_end == end
            seconds, raw_end = replay(env, seed, events, queries=True)
            queried_s += seconds
            same = same and raw_end == end
            steps += len(actions)
    return {'env_steps_per_s': steps / env_s, 'raw_steps_per_s': steps / raw_s,
            'ratio': raw_s / env_s, 'env_steps': steps, 'raw_ends_where_env_ended': same,
            'raw_with_queries_steps_per_s': steps / queried_s,
            'ceiling_with_queries': raw_s / queried_s,
            'physics_steps_per_env_step': env.unwrapped.settings.steps_per_period}


def ros_overhead(inproc, ros, episodes):
    """Return per-step wall times of both backends, stepped in turns with the same actions."""
    inproc_ms, ros_ms, differences = [], [], []
    for seed, actions in episodes:
        inproc.reset(seed=seed)
        ros.reset(seed=seed)
        for action in actions:
            t0 = time.perf_counter()
            inproc.step(action)
            t1 = time.perf_counter()
            ros.step(action)
            t2 = time.perf_counter()
            inproc_ms.append((t1 - t0) * 1e3)
            ros_ms.append((t2 - t1) * 1e3)
            differences.append((t2 - t1 - (t1 - t0)) * 1e3)
    return {'median_overhead_ms': statistics.median(differences),
            'inproc_median_step_ms': statistics.median(inproc_ms),
            'ros_median_step_ms': statistics.median(ros_ms),
            'ros_steps_per_s': len(ros_ms) / (sum(ros_ms) / 1e3), 'steps': len(ros_ms)}


def reset_times(env, seeds):
    """Return the median and 90th percentile (ms) of reset(seed), each after 3 steps."""
    import numpy
    times = []
    for seed in seeds:
        env.reset(seed=seed)  # an episode to step: the last one may have ended
        for _ in range(3):
            if env.step(numpy.array([0.5, 0.2], dtype=numpy.float32))[2]:
                break  # terminated: a step after it is refused
        started = time.perf_counter()
        env.reset(seed=seed)
        times.append((time.perf_counter() - started) * 1e3)
    times.sort()
    return {'median_ms': statistics.median(times), 'p90_ms': times[int(0.9 * len(times))],
            'samples': len(times)}


def against_ant(env, episodes, rounds, ant_steps):
    """Return R2D2Nav-v0's and Ant-v5's env steps per second, blocks of each in turns."""
    import gymnasium
    ant = gymnasium.make('Ant-v5')
    ant.reset(seed=0)
    ant.action_space.seed(0)
    ours_s = ant_s = 0.0
    ours = 0
    for _ in range(rounds):
        for seed, actions in episodes:
            ours_s += timed_episode(env, seed, actions)
            ours += len(actions)
        started = time.perf_counter()
        for _ in range(ant_steps):
            _, _, terminated, truncated, _ = ant.step(ant.action_space.sample())
            if terminated or truncated:
                ant.reset()
        ant_s += time.perf_counter() - started
    ant.close()
    return {'r2d2_nav_steps_per_s': ours / ours_s,
            'ant_v5_steps_per_s': rounds * ant_steps / ant_s, 'ant_frame_skip': 5}


def vector_rates(steps):
    """Return env steps per second of AsyncVectorEnv (spawn) of 1 and 2 inproc environments."""
    import numpy
    from r2d2_sim.gym.recipes import make_vector_env
    rates = {}
    for count in (1, 2):
        vector = make_vector_env(count)
        try:
            vector.reset(seed=list(range(count)))
            rng = numpy.random.default_rng(0)
            for _ in range(10):  # warm up the workers
                vector.step(rng.uniform(-1, 1, (count, 2)).astype(numpy.float32))
            started = time.perf_counter()
            for _ in range(steps):
                vector.step(rng.uniform(-0.3, 1, (count, 2)).astype(numpy.float32))
            rates[count] = count * steps / (time.perf_counter() - started)
        finally:
            vector.close()
    return {'processes_1_steps_per_s': rates[1], 'processes_2_steps_per_s': rates[2],
            'scaling': rates[2] / rates[1]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='fewer episodes and rounds')
    args = parser.parse_args()
    import gymnasium
    import r2d2_sim.gym  # noqa: F401
    episodes_n, rounds = (4, 1) if args.quick else (8, 3)
    load_before = background_load(2.0)
    results = {'date': local_date(), 'machine': machine_info(),
               'load_average_before': os.getloadavg(), 'other_load_before': load_before}
    inproc = gymnasium.make('R2D2Nav-v0')
    episodes = episode_actions(inproc, range(100, 100 + episodes_n), 200)
    meter = LoadMeter().start()
    results['inproc_vs_raw'] = inproc_against_raw(inproc, episodes, rounds)
    results['inproc_vs_raw']['load'] = meter.stop()
    ros = gymnasium.make('R2D2Nav-v0', backend='ros')
    meter = LoadMeter().start()
    results['ros'] = ros_overhead(inproc, ros, episodes)
    results['ros']['load'] = meter.stop()
    seeds = range(200, 230 if args.quick else 300)
    results['reset'] = {'inproc': reset_times(inproc, seeds), 'ros': reset_times(ros, seeds)}
    ros.close()
    meter = LoadMeter().start()
    results['ant'] = against_ant(inproc, episodes, rounds, 1000)
    results['ant']['load'] = meter.stop()
    inproc.close()
    meter = LoadMeter().start()
    results['vector'] = vector_rates(100 if args.quick else 300)
    results['vector']['load'] = meter.stop()
    results['load_average_after'] = os.getloadavg()
    write_json(RESULTS_PATH, results)
    report(results)


def report(results):
    """Print the table."""
    raw, ros, reset = results['inproc_vs_raw'], results['ros'], results['reset']
    ant, vector = results['ant'], results['vector']
    rows = [
        ('inproc env steps/s / raw PyBullet (same physics and rays), target >= 0.9',
         f"{raw['env_steps_per_s']:.0f} / {raw['raw_steps_per_s']:.0f} = {raw['ratio']:.3f}"
         f" (raw ended where the env did: {raw['raw_ends_where_env_ended']})"),
        ('raw + the per-step watch\'s PyBullet queries alone / raw: the ceiling',
         f"{raw['raw_with_queries_steps_per_s']:.0f} / {raw['raw_steps_per_s']:.0f} = "
         f"{raw['ceiling_with_queries']:.3f}"),
        ('ros backend: median overhead per step over inproc, target <= 1 ms',
         f"{ros['median_overhead_ms']:.3f} ms (steps {ros['inproc_median_step_ms']:.2f} / "
         f"{ros['ros_median_step_ms']:.2f} ms; {ros['ros_steps_per_s']:.0f} ros steps/s)"),
        ('reset median (p90), target <= 2 ms', f"inproc {reset['inproc']['median_ms']:.2f} "
         f"({reset['inproc']['p90_ms']:.2f}) ms, ros {reset['ros']['median_ms']:.2f} "
         f"({reset['ros']['p90_ms']:.2f}) ms"),
        ('R2D2Nav-v0 / MuJoCo Ant-v5 env steps/s, one core',
         f"{ant['r2d2_nav_steps_per_s']:.0f} / {ant['ant_v5_steps_per_s']:.0f}"),
        ('AsyncVectorEnv 1 / 2 processes, env steps/s',
         f"{vector['processes_1_steps_per_s']:.0f} / {vector['processes_2_steps_per_s']:.0f} "
         f"= x{vector['scaling']:.2f}"),
    ]
    print(f"{results['date']}, {results['machine']['cpu_model']}, load average before "
          f"{results['load_average_before'][0]:.2f}, other processes' cores before "
          f"{results['other_load_before']['busy_cores']:.2f}")
    for name, value in rows:
        print(f'{name:75s} {value}')


if __name__ == '__main__':
    main()
