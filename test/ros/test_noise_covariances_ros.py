"""
Covariances in the messages follow the configured noise: IMU (REP-145) and wheel odometry.

The IMU's covariances are each quantity's mean square error (every noise
parameter, not only the white noise's spread). Odometry's pose and twist
covariances are the configured diagonals until the encoders err; then the
x, y, yaw and linear, angular entries (cross terms included) are those the
encoders' noise gives, patched into the pre-serialized message each
publication and read back here exactly.
"""

import math
import random

from nav_msgs.msg import Odometry
import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu

from helpers import make_sim, RATE_HZ
from r2d2_sim.model.kinematics import OdometryState
from r2d2_sim.model.transforms import BaseState
from r2d2_sim.physics.records import JointStates
from r2d2_sim.ros.outputs import OdometryOutput
from r2d2_sim.sim.settings.config import parse_config
from r2d2_sim.sim.robots.robot import Frame
from r2d2_sim.testing import wait_for


def subscribe(ros, msg_type, topic):
    """Return the list that receives ``topic`` in a listener node of the harness."""
    seen = []
    node = ros.create_node(f'listener_{topic}', use_sim_time=False)
    node.create_subscription(msg_type, topic, seen.append, 100)
    return seen


class RecordingNode:
    """Stands in for the rclpy node an output creates its publisher on; keeps the bytes."""

    def __init__(self):
        self.published = []

    def create_publisher(self, msg_type, topic, qos):
        return self

    def publish(self, data):
        self.published.append(data)


def frame_with(odometry):
    return Frame(1, 10**9 // 240, JointStates((), (), ()),
                 BaseState((0.0,) * 3, (0.0, 0.0, 0.0, 1.0), (0.0,) * 3, (0.0,) * 3), odometry)


POSE_DIAGONAL = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
TWIST_DIAGONAL = (7.0, 8.0, 9.0, 10.0, 11.0, 12.0)


def noisy_odometry_output():
    """Return a recording node and the odometry output of noisy encoders on it."""
    config = parse_config({'encoder_noise_std': 0.01,
                           'pose_covariance_diagonal': list(POSE_DIAGONAL),
                           'twist_covariance_diagonal': list(TWIST_DIAGONAL)})
    node = RecordingNode()
    return node, OdometryOutput(node, config, 0.47)


def diagonal(values):
    """Return the 6 x 6 matrix (row by row) with ``values`` on its diagonal."""
    matrix = [0.0] * 36
    for i, value in enumerate(values):
        matrix[7 * i] = value
    return matrix


def test_odometry_covariance_entries_are_patched_around_the_configured_diagonal():
    node, output = noisy_odometry_output()
    rng = random.Random(3)
    for _ in range(50):
        pose = tuple(rng.uniform(-1.0, 1.0) for _ in range(9))
        twist = tuple(rng.uniform(-1.0, 1.0) for _ in range(4))
        output.publish(frame_with(OdometryState(0.1, 0.2, 0.3, 0.4, 0.5, pose, twist)))
        msg = deserialize_message(node.published[-1], Odometry)
        expected = diagonal(POSE_DIAGONAL)
        for i, row in enumerate((0, 1, 5)):
            for j, column in enumerate((0, 1, 5)):
                expected[6 * row + column] = pose[3 * i + j]
        assert list(msg.pose.covariance) == expected
        expected = diagonal(TWIST_DIAGONAL)
        for i, row in enumerate((0, 5)):
            for j, column in enumerate((0, 5)):
                expected[6 * row + column] = twist[2 * i + j]
        assert list(msg.twist.covariance) == expected
        assert msg.pose.pose.position.x == 0.1 and msg.twist.twist.angular.z == 0.5


def test_exact_encoders_leave_the_configured_covariance(ros):
    sim = make_sim(ros, pose_covariance_diagonal=[1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    seen = subscribe(ros, Odometry, 'odom')
    sim.advance(2)
    assert wait_for(lambda: seen)
    assert [seen[-1].pose.covariance[7 * i] for i in range(6)] == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]


def test_odometry_covariance_grows_as_the_robot_drives_with_erring_encoders(ros):
    sim = make_sim(ros, cmd_vel_timeout=0.0, encoder_noise_std=0.02,
                   encoder_noise_bias_mean=0.01, encoder_noise_precision=0.001)
    seen = subscribe(ros, Odometry, 'odom')
    sim.simulation.robot.command(0.3, 0.2)
    variances = []
    for _ in range(3):
        sim.advance(RATE_HZ)
        count = len(seen)
        sim.advance(1)
        assert wait_for(lambda: len(seen) > count)
        variances.append(seen[-1].pose.covariance[0] + seen[-1].pose.covariance[7])
    assert 0.0 < variances[0] < variances[1] < variances[2]
    covariance = seen[-1].pose.covariance
    assert covariance[1] == covariance[6]  # symmetric: x-y
    assert covariance[5] == covariance[30]  # x-yaw
    assert covariance[14] == 1.0e6  # z: not measured, as configured
    assert seen[-1].twist.covariance[0] > 0.0


def test_imu_covariance_is_the_mean_square_error_of_the_noise(ros):
    sim = make_sim(ros, imu_angular_velocity_noise_std=0.01,
                   imu_angular_velocity_noise_bias_mean=0.02,
                   imu_linear_acceleration_noise_mean=0.1,
                   imu_linear_acceleration_noise_dynamic_bias_std=0.01,
                   imu_linear_acceleration_noise_dynamic_bias_correlation_time=200.0,
                   imu_orientation_noise_precision=0.003)
    seen = subscribe(ros, Imu, 'imu')
    sim.advance(RATE_HZ // 10)
    assert wait_for(lambda: seen)
    imu = seen[-1]
    angular = 0.01 ** 2 + 0.02 ** 2
    linear = 0.1 ** 2 + 0.01 ** 2 * 100.0
    orientation = 0.003 ** 2 / 12.0
    for covariance, variance in ((imu.angular_velocity_covariance, angular),
                                 (imu.linear_acceleration_covariance, linear),
                                 (imu.orientation_covariance, orientation)):
        assert [covariance[0], covariance[4], covariance[8]] == pytest.approx([variance] * 3)
        assert [covariance[i] for i in (1, 2, 3, 5, 6, 7)] == [0.0] * 6
    assert math.isfinite(imu.angular_velocity.z)


def test_imu_covariance_follows_the_noise_restarted_at_run_time(ros):
    """
    Simulation.restart_noise with new IMU noise: the next imu carries its covariance.

    The message's covariances were copied from the noise model once, when the
    node was built: after new noise, the readings scattered by 0.1 rad/s
    while the message still said 0 (exact).
    """
    sim = make_sim(ros, imu_rate=RATE_HZ)
    seen = subscribe(ros, Imu, 'imu')
    sim.advance(RATE_HZ // 10)
    assert wait_for(lambda: seen)
    assert list(seen[-1].angular_velocity_covariance) == [0.0] * 9
    with sim.lock:
        sim.simulation.restart_noise(3, imu_angular_velocity_noise_std=0.1,
                                     imu_orientation_noise_bias_mean=0.02)
    count = len(seen)
    sim.advance(RATE_HZ // 10)
    assert wait_for(lambda: len(seen) >= count + RATE_HZ // 10)
    imu = seen[-1]
    assert list(imu.angular_velocity_covariance) == pytest.approx(diagonal_3(0.1 ** 2))
    assert list(imu.orientation_covariance) == pytest.approx(diagonal_3(0.02 ** 2))
    assert list(imu.linear_acceleration_covariance) == [0.0] * 9
    with sim.lock:  # and back to exact
        sim.simulation.restart_noise(3, imu_angular_velocity_noise_std=0.0,
                                     imu_orientation_noise_bias_mean=0.0)
    count = len(seen)
    sim.advance(RATE_HZ // 10)
    assert wait_for(lambda: len(seen) >= count + RATE_HZ // 10)
    assert list(seen[-1].angular_velocity_covariance) == [0.0] * 9
    assert list(seen[-1].orientation_covariance) == [0.0] * 9


def diagonal_3(variance):
    """Return the 3 x 3 matrix (row by row) with ``variance`` on its diagonal."""
    return [variance, 0.0, 0.0, 0.0, variance, 0.0, 0.0, 0.0, variance]


def test_the_configured_diagonal_comes_back_when_the_encoders_stop_erring():
    # Encoder noise switched off at run time (restart_noise): the next odom carries the
    # configured covariance again, not the last one the encoders gave.
    node, output = noisy_odometry_output()
    output.publish(frame_with(OdometryState(0.1, 0.2, 0.3, 0.4, 0.5, (0.5,) * 9, (0.25,) * 4)))
    output.publish(frame_with(OdometryState(0.1, 0.2, 0.3, 0.4, 0.5, None, None)))
    msg = deserialize_message(node.published[-1], Odometry)
    assert list(msg.pose.covariance) == diagonal(POSE_DIAGONAL)
    assert list(msg.twist.covariance) == diagonal(TWIST_DIAGONAL)
