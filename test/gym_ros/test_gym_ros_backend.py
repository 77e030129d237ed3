"""
The ``ros`` backend: the simulator node in lockstep over its topics, equal to ``inproc`` bitwise.

ROS in this process (a SimHarness per environment, each on a domain of its
own). Gymnasium's and Stable-Baselines3's checkers and PettingZoo's tests on
environments made with ``backend='ros'``; the same seed and actions give the
same observations, rewards and infos as the ``inproc`` backend, after any
history; a node of the user's own between the policy and the robot runs in
lockstep (a filter that halves the command equals ``inproc`` driven by half
the actions); the CDR readers read what rclpy would.
"""

import dataclasses
import math
import threading
import warnings

from gymnasium.utils.env_checker import check_env
from nav_msgs.msg import Odometry
import numpy
from pettingzoo.test import parallel_api_test, parallel_seed_test
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import LaserScan

from common import (
    connected_clients, gym_actions as actions, gym_noisy, gym_rollout as rollout,
    parallel_rollout)
import r2d2_sim.gym  # noqa: F401 (registers the environments)
from r2d2_sim.gym import GymError
from r2d2_sim.gym.multi import parallel_env
from r2d2_sim.gym.ros_backend import read_odometry, read_scan, twist_bytes


@pytest.mark.parametrize('env_id', ['R2D2Nav-v0', 'R2D2NavGoal-v0'])
def test_gymnasiums_checker_passes_over_ros(gym_make, env_id):
    """check_env with its determinism checks (three simulator nodes: its own make() twice)."""
    env = gym_make(env_id, backend='ros')
    assert env.spec.nondeterministic is False
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        check_env(env.unwrapped)


def test_stable_baselines3s_checker_passes_over_ros(gym_make):
    """SB3's check_env on the ros backend (its warnings are errors here, not the imports')."""
    from stable_baselines3.common.env_checker import check_env as sb3_check_env
    env = gym_make(backend='ros')
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        sb3_check_env(env.unwrapped)


def test_pettingzoos_tests_pass_over_ros():
    """parallel_api_test and parallel_seed_test with two robots, each on its namespace's topics."""
    env = parallel_env(backend='ros')
    try:
        with warnings.catch_warnings(record=True):
            parallel_api_test(env, num_cycles=20)
    finally:
        env.close()
    parallel_seed_test(lambda: parallel_env(backend='ros'), num_cycles=20)


@pytest.mark.parametrize('env_id', ['R2D2Nav-v0', 'R2D2NavGoal-v0'])
def test_the_same_seed_and_actions_give_the_same_run_in_both_backends(gym_make, env_id):
    """Seeds 11, 12, then 11 again in each: every run equal across the backends, noise and all."""
    ros, inproc = gym_make(env_id, backend='ros', **gym_noisy()), gym_make(env_id, **gym_noisy())
    # Both cast their scans on one thread (vector envs run one per core): the node's auto
    # would take two.
    assert ros.unwrapped.backend.harness.sim.simulation.world.ray_threads == 1
    assert inproc.unwrapped.backend.simulation.world.ray_threads == 1
    for seed in (11, 12, 11):
        assert rollout(ros, seed, actions(seed)) == rollout(inproc, seed, actions(seed)), seed


def test_several_robots_run_the_same_in_both_backends():
    """Two robots, seed 5, the same random actions: the same hash."""
    ros, inproc = parallel_env(backend='ros'), parallel_env()
    try:
        assert parallel_rollout(ros, 5) == parallel_rollout(inproc, 5)
    finally:
        ros.close()
        inproc.close()


def halving_filter(harness):
    """Add a node between the policy and the robot: policy/cmd_vel, halved, to cmd_vel."""
    from geometry_msgs.msg import Twist
    node = harness.create_node('halving_filter')
    out = node.create_publisher(Twist, 'cmd_vel', 10)

    def halve(msg):
        msg.linear.x *= 0.5
        msg.angular.z *= 0.5
        out.publish(msg)
    node.create_subscription(Twist, 'policy/cmd_vel', halve, 10)


def test_a_node_between_the_policy_and_the_robot_runs_in_lockstep(gym_make):
    """The filter halves each command in the step it is sent: inproc with half the actions."""
    filtered = gym_make(backend='ros', ros_nodes=halving_filter,
                        topics={'command': 'policy/cmd_vel'})
    inproc = gym_make()
    full = actions(3, 30)
    assert rollout(filtered, 3, full) == rollout(inproc, 3, full * 0.5)
    assert rollout(filtered, 3, full) != rollout(inproc, 3, full)


@pytest.mark.parametrize('topics, says', [
    ({'odom': 'odometry'}, '^topics takes command, scan, state, got odom$'),
    ('abc', '^topics must be a dict of command, scan, state, got str$'),
    ({'command': 5}, '^topics: command must be a topic name, got int$'),
    ({'command': 'bad name!'}, "^topics: command 'bad name!' is not a topic name: "),
])
def test_topics_that_cannot_be_are_one_line(gym_make, topics, says):
    """The topics keyword takes names of command, scan and state, nothing else."""
    with pytest.raises(GymError, match=says) as refused:
        gym_make(backend='ros', topics=topics)
    assert '\n' not in str(refused.value)


def test_ros_nodes_that_is_no_function_is_one_line_before_a_harness_starts(gym_make):
    """ros_nodes=5: GymError, nothing left running (before: a TypeError traceback)."""
    before = (harness_threads(), connected_clients())
    with pytest.raises(GymError, match=r'^ros_nodes must be a function of the harness, '
                                       r'ros_nodes\(harness\), got int 5$'):
        gym_make(backend='ros', ros_nodes=5)
    assert (harness_threads(), connected_clients()) == before


@pytest.mark.parametrize('frame_id', ['', 'base_scan', 'a' * 13])
def test_the_cdr_readers_read_what_rclpy_deserializes(frame_id):
    """A LaserScan's stamp and ranges, an Odometry's stamp, pose and twist: as rclpy reads them."""
    scan = LaserScan()
    scan.header.stamp.sec, scan.header.stamp.nanosec = 3, 250_000_000
    scan.header.frame_id = frame_id
    scan.ranges = [1.5, math.inf, -math.inf, 0.25]
    stamp, ranges = read_scan(serialize_message(scan))
    assert stamp == 3_250_000_000
    assert ranges.tobytes() == numpy.array(scan.ranges, dtype=numpy.float32).tobytes()
    odometry = Odometry()
    odometry.header.stamp.sec = 7
    odometry.header.frame_id = frame_id
    odometry.child_frame_id = frame_id[:5] + 'x'
    pose, twist = odometry.pose.pose, odometry.twist.twist
    pose.position.x, pose.position.y, pose.position.z = 1.0, -2.0, 0.47
    pose.orientation.z, pose.orientation.w = 0.6, 0.8
    twist.linear.x, twist.angular.z = 0.3, -0.1
    odometry.pose.covariance[0] = 99.0  # between the pose and the twist: not read
    stamp, values = read_odometry(serialize_message(odometry))
    assert stamp == 7_000_000_000
    assert values == (1.0, -2.0, 0.47, 0.0, 0.0, 0.6, 0.8, 0.3, 0.0, 0.0, 0.0, 0.0, -0.1)
    twist_message = deserialize_message(twist_bytes(0.2, -0.7), type(twist))
    assert (twist_message.linear.x, twist_message.angular.z) == (0.2, -0.7)


def test_a_space_the_goal_env_refuses_leaves_no_harness_behind(gym_make):
    """
    R2D2NavGoal-v0 checks its space before it starts a simulator node: no thread, no client.

    Before, each refused make left a SimHarness running: its thread, its PyBullet
    client and its leased ROS domain (a sweep would use the domains up).
    """
    from r2d2_sim.gym.settings import DEFAULT_SPACE
    before = (harness_threads(), connected_clients())
    bad = dataclasses.replace(DEFAULT_SPACE, goal_area=(24.0, -1.0, 25.0, 1.0))
    for _ in range(2):
        with pytest.raises(GymError, match="^space: R2D2NavGoal-v0's starts") as caught:
            gym_make('R2D2NavGoal-v0', space=bad, backend='ros')
    assert (harness_threads(), connected_clients()) == before, caught.value


def harness_threads():
    """Return the names of the ROS harnesses' threads alive in this process."""
    return sorted(t.name for t in threading.enumerate() if t.name.startswith('ros-harness-'))


@pytest.mark.parametrize('parameters, message', [
    ({'urdf': '/nonexistent/robot.urdf'},
     '^sim_parameters: URDF file not found: /nonexistent/robot.urdf'),
    ({'gui': True}, '^sim_parameters: gui needs a display, and DISPLAY is not set'),
])
def test_settings_the_simulator_node_refuses_are_one_line(monkeypatch, gym_make, parameters,
                                                          message):
    """The node's StartupError becomes the inproc backend's GymError line, its cause kept."""
    from r2d2_sim.errors import StartupError
    monkeypatch.delenv('DISPLAY', raising=False)
    before = (harness_threads(), connected_clients())
    with pytest.raises(GymError, match=message) as caught:
        gym_make(backend='ros', sim_parameters=parameters)
    assert '\n' not in str(caught.value) and isinstance(caught.value.__cause__, StartupError)
    assert (harness_threads(), connected_clients()) == before
