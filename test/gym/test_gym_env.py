"""
R2D2Nav-v0 and R2D2NavGoal-v0 in process (backend ``inproc``): checkers, seeds, rewards, errors.

No ROS: the fast tier. Gymnasium's ``check_env`` runs on environments made
with ``gymnasium.make``, so that its determinism checks run (they are
skipped without a spec); Stable-Baselines3's too. A reset then a rollout
must equal the same rollout in a fresh environment, bit for bit, after any
history of episodes (a reset only puts bodies back in place would not: see
test/sim/test_saved_states.py). Bad input is one line.
"""

import json
import math
import os
import subprocess
import sys
import warnings

from gymnasium.utils.env_checker import check_env
import numpy
import pytest

from common import (
    connected_clients, gym_actions as actions, gym_noisy, gym_rollout as rollout, REPO)
import r2d2_sim.gym  # noqa: F401 (registers the environments)
from r2d2_sim.farm.scenario import Box, Pose, Scenario
from r2d2_sim.gym import GymError
from r2d2_sim.gym.task import Rewards
from r2d2_sim.model.regions import circle_region


@pytest.mark.parametrize('env_id', ['R2D2Nav-v0', 'R2D2NavGoal-v0'])
def test_gymnasiums_checker_passes_with_its_determinism_checks(gym_make, env_id):
    """check_env on a made environment (spec: nondeterministic False), with no warning."""
    env = gym_make(env_id, **gym_noisy())
    assert env.spec.nondeterministic is False and not env.spec.disable_env_checker
    assert env.spec.max_episode_steps == 200
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        check_env(env.unwrapped)


@pytest.mark.parametrize('env_id', ['R2D2Nav-v0', 'R2D2NavGoal-v0'])
def test_stable_baselines3s_checker_passes(gym_make, env_id):
    """SB3's own check_env (its warnings are errors here)."""
    from stable_baselines3.common.env_checker import check_env as sb3_check_env
    env = gym_make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        sb3_check_env(env.unwrapped)


def test_a_reset_then_a_rollout_equals_a_fresh_environments_after_any_history(gym_make):
    """Seeds 1, 2, 3 fresh; then in one environment 3, 1, 2, 1, 3: each equal, noise and all."""
    fresh = {}
    for seed in (1, 2, 3):
        fresh[seed] = rollout(gym_make(**gym_noisy()), seed, actions(seed))
    env = gym_make(**gym_noisy())
    for seed in (3, 1, 2, 1, 3):
        assert rollout(env, seed, actions(seed)) == fresh[seed], seed
    assert len(set(fresh.values())) == 3


def test_after_a_blow_up_the_next_episodes_equal_a_fresh_environments(gym_make):
    """
    The blow-up loads bodies again, and the saved state is refused: the arena builds it again.

    Before, the next reset raised PyBullet's "Couldn't restore state".
    """
    fresh = gym_make(**gym_noisy())
    first = [rollout(fresh, seed, actions(seed)) for seed in (2, 3)]
    env = gym_make(**gym_noisy())
    env.reset(seed=1)
    simulation = env.unwrapped.nav.backend.simulation
    env.step(actions(1)[0])
    simulation.robot.body.set_base_state(linear_velocity=(math.nan, 0.0, 0.0))
    env.step(actions(1)[1])
    assert simulation.blow_ups == 1
    assert [rollout(env, seed, actions(seed)) for seed in (2, 3)] == first


def test_the_seed_draws_the_scenario_and_its_noise(gym_make):
    """The same seed, the same world and scan noise; the seed's scenario replayed, the same run."""
    env = gym_make(**gym_noisy())
    first, info = env.reset(seed=7)
    # The space's noise, drawn for the episode, is the laser's (not a sim_parameters value,
    # which a reset would overwrite: refused, below).
    assert 0.02 <= info['scenario']['scan_noise_std'] <= 0.05
    assert env.unwrapped.backend.simulation.robots[0].config.scan_noise_std_m == \
        info['scenario']['scan_noise_std']
    again, _ = env.reset(seed=7)
    other, other_info = env.reset(seed=8)
    assert first.tobytes() == again.tobytes() and first.tobytes() != other.tobytes()
    assert info['scenario'] != other_info['scenario']
    scenario = info['scenario']
    assert rollout(env, 7, actions(0)) == rollout(env, None, actions(0),
                                                  {'scenario': json.dumps(scenario)})


def test_driving_into_a_box_ends_the_episode_with_the_collision_penalty(gym_make):
    """A box 1.2 m ahead: full speed ahead touches it, terminated, reward about -10."""
    scenario = Scenario(obstacles=(Box(1.2, 0.0, 0.0, (0.4, 0.4, 0.5)),),
                        start=Pose(0.0, 0.0, 0.0), goal=circle_region(3.0, 0.0, 0.3))
    env = gym_make()
    env.reset(options={'scenario': scenario})
    for _ in range(40):
        _, reward, terminated, truncated, info = env.step(numpy.array([1.0, 0.0]))
        if terminated:
            break
    assert terminated and not truncated
    assert info['contact'] == 'box_0' and not info['is_success']
    assert reward < -9.0


def test_reaching_the_goal_ends_the_episode_with_the_bonus(gym_make):
    """Nothing in the way, a goal 1.5 m ahead: full speed ahead reaches it, reward above 10."""
    scenario = Scenario(start=Pose(0.0, 0.0, 0.0), goal=circle_region(1.5, 0.0, 0.3))
    env = gym_make()
    env.reset(options={'scenario': scenario})
    total = 0.0
    for step in range(40):
        _, reward, terminated, truncated, info = env.step(numpy.array([1.0, 0.0]))
        total += reward
        if terminated:
            break
    assert terminated and info['is_success'] and info['reached'] and info['contact'] == ''
    assert reward > 10.0
    assert total == pytest.approx(1.2 + 10.0 - 0.01 * (step + 1), abs=0.15)  # 1.2 m nearer


def test_renders_the_arena_from_above_and_the_head_camera(gym_make):
    """rgb_array: 240 x 320 x 3 bytes from above; the camera's size from its parameters."""
    top = gym_make(render_mode='rgb_array')
    top.reset(seed=1)
    image = top.render()
    assert image.shape == (240, 320, 3) and image.dtype == numpy.uint8 and image.std() > 0
    camera = gym_make(render_mode='rgb_array', render_view='camera')
    camera.reset(seed=1)
    assert camera.render().shape == (240, 320, 3)


@pytest.mark.parametrize('goal, aside', [
    ((8.0, 0.0), (4.0, 1.5)),   # long in x
    ((1.0, 6.0), (3.0, 3.0)),   # long in y
])
def test_the_top_view_is_a_map_of_the_whole_arena(monkeypatch, gym_make, goal, aside):
    """
    The world's x to the right, y up (RViz's top-down view); robot and goal inside the image.

    A box marks the goal and another stands aside; each body's pixels are where the
    renderer's segmentation mask sees it, in the very image render() gives. Before,
    x ran up the short side of the image: a goal 8 m ahead was cut off, and y ran left.
    """
    box = (0.4, 0.4, 0.5)
    env = gym_make(render_mode='rgb_array')
    env.reset(options={'scenario': Scenario(
        obstacles=(Box(*goal, 0.0, box), Box(*aside, 0.0, box)), start=Pose(0.0, 0.0, 0.0),
        goal=circle_region(*goal, 0.3))})
    world = env.unwrapped.backend.simulation.world
    taken = []  # the camera render() asks the world for
    real = world.render
    monkeypatch.setattr(world, 'render', lambda *camera: taken.append(camera) or real(*camera))
    image = env.render()
    (camera,) = taken
    seen = {}
    for name in ('r2d2', 'box_0', 'box_1'):
        rgb, _, mask = world.render_seeing(world.bodies[name], *camera)
        assert rgb == image.tobytes()
        rows, columns = numpy.nonzero(mask)
        assert rows.size, name
        assert 0 < rows.min() and rows.max() < 239 and 0 < columns.min() and columns.max() < 319, \
            name  # wholly inside, the border untouched
        seen[name] = (columns.mean(), rows.mean())  # (right, down)
    robot, goal_box, aside_box = seen['r2d2'], seen['box_0'], seen['box_1']
    for (x, y), (right, down) in ((goal, goal_box), (aside, aside_box)):  # the robot at 0, 0
        assert x < 0.5 or right > robot[0] + 20, (x, y)  # farther along x: to the right
        assert y < 0.5 or down < robot[1] - 20, (x, y)  # farther along y: up


@pytest.mark.parametrize('action, message', [
    (numpy.array([2.0, 0.0]), r'^the action must be within \[-1, 1\], got array\(\[2., 0.\]\)$'),
    (numpy.array([numpy.nan, 0.0]),
     r'^the action must be finite numbers, got array\(\[nan,  0.\]\)$'),
    ([0.1, 0.2, 0.3], r'^the action must be two numbers in \[-1, 1\] \(forward, turn\), got '
                      r'shape \(3,\): \[0.1, 0.2, 0.3\]$'),
    ('ahead', r'^the action must be two numbers in \[-1, 1\] \(forward, turn\), got '
              r"'ahead'$"),
])
def test_a_bad_action_is_one_line_and_the_episode_goes_on(gym_make, action, message):
    """Out of the space, NaN, another shape, no number: GymError in one line; stepping goes on."""
    env = gym_make()
    env.reset(seed=0)
    with pytest.raises(GymError, match=message):
        env.unwrapped.step(action)
    env.step(numpy.zeros(2, dtype=numpy.float32))


def test_an_unknown_reset_option_and_a_step_after_close_are_one_line(gym_make):
    """Reset options are checked; a closed environment says so (reset and step)."""
    env = gym_make()
    with pytest.raises(GymError, match=r"^unknown reset option\(s\) 'goal', 'seed': NavEnv takes "
                                       r'scenario$'):
        env.reset(options={'goal': 1, 'seed': 2})
    with pytest.raises(GymError, match='^reset option scenario: not JSON'):
        env.reset(options={'scenario': '{'})
    for options, kind in ((['scenario'], 'list'), ('scenario', 'str')):
        with pytest.raises(GymError, match=f'^reset options must be a dict, got {kind} '):
            env.reset(options=options)
    env.reset(seed=0)
    env.close()
    env.close()  # twice is fine
    for call in (lambda: env.unwrapped.step(numpy.zeros(2)), lambda: env.unwrapped.reset()):
        with pytest.raises(GymError, match='^the environment is closed: make a new one$'):
            call()


# What only building the simulator finds out (test/gym_ros: the same over ROS).
SIMULATOR_REFUSES = [
    ({'urdf': '/nonexistent/robot.urdf'},
     '^sim_parameters: URDF file not found: /nonexistent/robot.urdf'),
    ({'left_wheel_names': ['nope']}, r'^sim_parameters: wheel joint\(s\) nope not in the URDF'),
    ({'gui': True}, '^sim_parameters: gui needs a display, and DISPLAY is not set'),
]


@pytest.mark.parametrize('kwargs, message', [
    ({'control_rate_hz': 7.0}, 'control_rate_hz must divide the physics rate'),
    ({'scan_beams': 7}, r'scan_beams must divide scan_rays \(360\) into equal sectors, got 7'),
    ({'backend': 'gazebo'}, "backend must be one of inproc, ros, got 'gazebo'"),
    ({'sim_parameters': {'scan_rate': 5.0}}, 'sim_parameters: scan_rate are set by the env'),
    ({'robots': 2, 'sim_parameters': {'r2d2_1.scan_rate': 5.0}},
     r'sim_parameters: r2d2_1\.scan_rate are set by the env'),
    ({'rewards': Rewards(goal=float('nan'))}, 'rewards.goal must be a finite number, got nan'),
    ({'backend': 'ros', 'sim_parameters': {'enable_stamped_cmd_vel': True}},
     "sim_parameters: enable_stamped_cmd_vel cannot be used with backend='ros'"),
    ({'backend': 'ros', 'sim_parameters': {'outputs_process': True}},
     "sim_parameters: outputs_process cannot be used with backend='ros'"),
    ({'sim_parameters': {'record': 'run.mcap', 'foxglove_port': 18765}},
     "^sim_parameters: foxglove_port, record work only with backend='ros' "),
    ({'sim_parameters': {'foxglove_host': '0.0.0.0'}},
     "^sim_parameters: foxglove_host work only with backend='ros' "),
    ({'sim_parameters': {'publish_rat': 3}},
     r'sim_parameters: unknown parameter\(s\): publish_rat'),
    ({'sim_parameters': {'scan_noise_mean': 'x'}, 'backend': 'ros'},
     "sim_parameters: parameter scan_noise_mean must be a number, got 'x'"),
    ({'sim_parameters': {'scan_noise_std': 0.02}},
     r'sim_parameters: scan_noise_std is drawn for each episode from the space: give '
     r'space=dataclasses\.replace\(DEFAULT_SPACE, scan_noise_std=\(low, high\)\)'),
    ({'color': 'blue'}, "^NavEnv: unexpected keyword argument 'color'$"),
    ({'sim_parameters': {1: 2}}, r'^sim_parameters: parameter names are strings, got 1 \(int\)$'),
    ({'sim_parameters': ['gui']}, '^sim_parameters must be a dict of parameter names to values, '
                                  'got list$'),
    ({'scan_beams': numpy.float64(36.0)}, r'^scan_beams must be an integer >= 1, got '),
    ({'control_rate_hz': numpy.bool_(True)}, '^control_rate_hz must be a number > 0, got '),
    ({'render_mode': 'human'}, "render_mode must be None or 'rgb_array', got 'human'"),
])
def test_settings_that_cannot_be_are_one_line_at_construction(kwargs, message):
    """Each: GymError naming the setting, no simulator left behind."""
    from r2d2_sim.gym.env import NavEnv  # imported here: alone, the test found no gym.env
    before = connected_clients()
    with pytest.raises(GymError, match=message) as caught:
        NavEnv(**kwargs)
    assert '\n' not in str(caught.value)
    assert connected_clients() == before  # (caught holds the failed constructor's frames)


def test_numpys_scalars_are_numbers_and_run_as_pythons(gym_make):
    """
    Sweep tools hand out numpy scalars: taken where numbers are, the same run as Python's.

    Before, control_rate_hz=numpy.float32(10) was "must be a number > 0", and
    scan_beams=numpy.int64(36) "must be an integer".
    """
    env = gym_make(control_rate_hz=numpy.float32(10.0), scan_beams=numpy.int64(36),
                   max_linear_m_s=numpy.float64(0.5), rewards=Rewards(goal=numpy.int32(10)),
                   sim_parameters={'ray_threads': numpy.int64(1)})
    settings = env.unwrapped.settings
    assert type(settings.control_rate_hz) is float and type(settings.scan_beams) is int
    assert type(settings.rewards.goal) is int
    assert settings.sim_parameters == {'ray_threads': 1}
    assert rollout(env, 3, actions(3)) == rollout(gym_make(), 3, actions(3))


@pytest.mark.parametrize('parameters, message', SIMULATOR_REFUSES)
def test_settings_the_simulator_refuses_are_one_line_too(monkeypatch, parameters, message):
    """
    A URDF it cannot load, wheels the URDF lacks, a window without a display: GymError.

    The simulator's own error is its cause. Before, its traceback escaped (a
    WorldError or ConfigError here, a StartupError over ROS), past code that
    catches GymError.
    """
    from r2d2_sim.errors import SetupError
    from r2d2_sim.gym.env import NavEnv
    monkeypatch.delenv('DISPLAY', raising=False)
    before = connected_clients()
    with pytest.raises(GymError, match=message) as caught:
        NavEnv(sim_parameters=parameters)
    assert '\n' not in str(caught.value) and isinstance(caught.value.__cause__, SetupError)
    assert connected_clients() == before


def test_a_space_the_goal_env_refuses_leaves_no_simulator_behind():
    """
    R2D2NavGoal-v0 checks its space before it builds its backend: no PyBullet client is left.

    Before, the check ran after the backend was made, and nothing closed it (with
    backend='ros': a harness thread and a leased ROS domain per refused make).
    """
    import dataclasses
    from r2d2_sim.gym.env import NavGoalEnv
    from r2d2_sim.gym.settings import DEFAULT_SPACE
    before = connected_clients()
    with pytest.raises(GymError, match="^space: R2D2NavGoal-v0's starts and goal circles") \
            as caught:
        NavGoalEnv(space=dataclasses.replace(DEFAULT_SPACE, goal_area=(24.0, -1.0, 25.0, 1.0)))
    assert connected_clients() == before, caught.value  # the failed frames are still held


def test_a_replayed_scenario_the_world_refuses_is_one_line_and_the_env_goes_on(gym_make):
    """A start 1e6 m away: GymError; a step then says reset first; the next reset works."""
    env = gym_make()
    scenario = env.reset(seed=0)[1]['scenario']
    scenario['start']['x'] = 1e6
    with pytest.raises(GymError, match='^the episode cannot start: INVALID_POSE: '):
        env.reset(options={'scenario': scenario})
    with pytest.raises(GymError, match='^reset the environment before stepping it$'):
        env.unwrapped.step(numpy.zeros(2, dtype=numpy.float32))
    again, _ = env.reset(seed=0)
    assert env.step(numpy.zeros(2, dtype=numpy.float32))[0].shape == again.shape
    scenario = env.reset(seed=0)[1]['scenario']
    for key, value, says in (('world', 'room.world.yaml', "its world 'room.world.yaml'"),
                             ('limits', [['max_linear_velocity', 0.2]], 'robot limits')):
        with pytest.raises(GymError, match=f'^reset option scenario: {says}'):
            env.reset(options={'scenario': dict(scenario, **{key: value})})


@pytest.mark.parametrize('env_id', ['R2D2Nav-v0', 'R2D2NavGoal-v0'])
def test_a_reset_its_options_refuse_changes_nothing(gym_make, env_id):
    """A terminated episode stays terminated; the refused reset's seed seeds nothing."""
    env, same = gym_make(env_id), gym_make(env_id)
    env.reset(options={'scenario': Scenario(obstacles=(Box(1.2, 0.0, 0.0, (0.4, 0.4, 0.5)),),
                                            start=Pose(0.0, 0.0, 0.0),
                                            goal=circle_region(3.0, 0.0, 0.3))})
    for _ in range(100):  # into the box
        if env.step(numpy.array([1.0, 0.0], dtype=numpy.float32))[2]:
            break
    env.unwrapped.np_random = numpy.random.default_rng(7)
    same.unwrapped.np_random = numpy.random.default_rng(7)
    for bad in ({'goal': 1}, {'scenario': 'not json'}):
        with pytest.raises(GymError):
            env.reset(seed=3, options=bad)
        with pytest.raises(GymError, match='^the episode has terminated: reset the environment$'):
            env.unwrapped.step(numpy.zeros(2, dtype=numpy.float32))
    assert env.reset()[1]['scenario'] == same.reset()[1]['scenario']  # the generator's own draw


@pytest.mark.parametrize('env_id', ['R2D2Nav-v0', 'R2D2NavGoal-v0'])
def test_a_step_after_the_episode_terminated_is_refused_until_a_reset(gym_make, env_id):
    """Its outcome would be paid again, step after step: GymError, then a reset goes on."""
    env = gym_make(env_id)
    env.reset(seed=3)
    terminated = False
    for _ in range(300):  # straight ahead, full speed: into a box, or the goal
        terminated = env.step(numpy.array([1.0, 0.0], dtype=numpy.float32))[2]
        if terminated:
            break
    assert terminated
    with pytest.raises(GymError, match='^the episode has terminated: reset the environment$'):
        env.unwrapped.step(numpy.zeros(2, dtype=numpy.float32))
    env.reset(seed=3)
    env.step(numpy.zeros(2, dtype=numpy.float32))


def test_the_goal_env_rewards_as_its_compute_reward_for_any_goal(gym_make):
    """Each step's reward is compute_reward of its goals; a batch of relabelled goals too."""
    env = gym_make('R2D2NavGoal-v0')
    observation, _ = env.reset(seed=4)
    for action in actions(4, 10):
        observation, reward, terminated, _, info = env.step(action)
        achieved, desired = observation['achieved_goal'], observation['desired_goal']
        assert reward == env.unwrapped.compute_reward(achieved, desired, info)
        if terminated:
            break
    batch = env.unwrapped.compute_reward(numpy.stack([achieved, achieved]),
                                         numpy.stack([achieved, achieved + 5.0]), [info, info])
    assert batch.tolist() == [0.0, -1.0]


def test_the_goal_env_scores_every_goal_with_the_spaces_tolerance(gym_make):
    """A stored transition scores the same after any later episode; another tolerance: refused."""
    env = gym_make('R2D2NavGoal-v0')
    observation, _ = env.reset(options={'scenario': Scenario(start=Pose(0.0, 0.0, 0.0),
                                                             goal=circle_region(0.5, 0.0, 0.3))})
    observation, reward, _, _, info = env.step(numpy.zeros(2, dtype=numpy.float32))
    stored = (observation['achieved_goal'].copy(), observation['desired_goal'].copy(), info)
    assert reward == env.unwrapped.compute_reward(*stored) == -1.0  # 0.5 m from the goal
    with pytest.raises(GymError, match=r"^the scenario's goal tolerance 1 m is not the "
                                       r"environment's 0\.3 m"):
        env.reset(options={'scenario': Scenario(start=Pose(0.0, 0.0, 0.0),
                                                goal=circle_region(3.0, 0.0, 1.0))})
    env.reset(seed=5)
    assert env.unwrapped.compute_reward(*stored) == reward


def test_the_goal_env_never_scores_a_clipped_goal(gym_make):
    """Ends and goals beyond 19 m: refused; a robot driving out of ±20 m: truncated, scored -1."""
    import dataclasses
    from r2d2_sim.gym.settings import DEFAULT_SPACE
    with pytest.raises(GymError, match=r"^space: R2D2NavGoal-v0's starts and goal circles must "
                                       r'lie within 19 m of the origin'):
        gym_make('R2D2NavGoal-v0', space=dataclasses.replace(
            DEFAULT_SPACE, goal_area=(24.0, -1.0, 25.0, 1.0)))
    env = gym_make('R2D2NavGoal-v0')
    env.reset(seed=0)  # (Gymnasium's passive checker needs a first reset that succeeds)
    with pytest.raises(GymError, match=r"^the scenario's start and goal circle must lie within "
                                       r'19 m'):
        env.reset(options={'scenario': Scenario(start=Pose(18.9, 0.0, 0.0),
                                                goal=circle_region(25.0, 0.0, 0.3))})
    env.reset(options={'scenario': Scenario(start=Pose(18.9, 0.0, 0.0),
                                            goal=circle_region(10.0, 0.0, 0.3))})
    for _ in range(60):  # away from the goal, out of the square
        observation, reward, terminated, truncated, info = env.step(
            numpy.array([1.0, 0.0], dtype=numpy.float32))
        achieved, desired = observation['achieved_goal'], observation['desired_goal']
        assert env.observation_space.contains(observation)
        assert reward == env.unwrapped.compute_reward(achieved, desired, info) == -1.0
        assert truncated == env.unwrapped.compute_truncated(achieved, desired, info)
        assert not terminated
        if truncated:
            break
    assert truncated and achieved[0] == 20.0 and info['distance'] > 10.0


def test_hindsight_replay_learns_from_the_goal_env(gym_make):
    """SB3's HerReplayBuffer relabels goals through compute_reward: SAC takes a few updates."""
    from stable_baselines3 import HerReplayBuffer, SAC
    env = gym_make('R2D2NavGoal-v0', max_episode_steps=30)  # an episode ends before the updates
    model = SAC('MultiInputPolicy', env, replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs={'n_sampled_goal': 4, 'goal_selection_strategy': 'future'},
                learning_starts=40, batch_size=32, device='cpu', seed=0)
    model.learn(50)
    assert model.num_timesteps == 50 and model.replay_buffer.size() > 0


def test_importing_and_running_in_process_loads_no_ros():
    """A fresh interpreter: import r2d2_sim.gym, make, reset and step an environment; no rclpy."""
    code = ('import sys, gymnasium, numpy\n'
            'env = gymnasium.make("r2d2_sim.gym:R2D2Nav-v0")\n'
            'env.reset(seed=0); env.step(numpy.zeros(2, dtype=numpy.float32)); env.close()\n'
            'import r2d2_sim.gym.multi, r2d2_sim.gym.recipes\n'
            'print("rclpy" in sys.modules)\n')
    env = dict(os.environ, PYTHONPATH=REPO)
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            env=env, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip().splitlines()[-1] == 'False'


def test_the_vector_recipe_takes_gymnasiums_own_vector_kwargs():
    """make_vector_env passes vector_kwargs on: here the same-step autoreset Gymnasium offers."""
    from gymnasium.vector import AutoresetMode
    from r2d2_sim.gym.recipes import make_vector_env
    vector = make_vector_env(1, vectorization_mode='sync',
                             vector_kwargs={'autoreset_mode': AutoresetMode.SAME_STEP})
    try:
        assert vector.metadata['autoreset_mode'] == AutoresetMode.SAME_STEP
    finally:
        vector.close()
