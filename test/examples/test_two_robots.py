import math

import pytest
from sensor_msgs.msg import LaserScan

pytest_plugins = ['r2d2_sim.pytest_plugin']


@pytest.fixture
def r2d2_sim_parameters():
    # Two robots in one world, in namespaces /a and /b, 3 m apart and facing each other.
    return {'cmd_vel_timeout': 0.0,
            'robots': {'a': {}, 'b': {'initial_pose': [3.0, 0.0, math.pi]}}}


def test_b_sees_a_coming_and_only_a_moves(r2d2_sim):
    a, b = r2d2_sim.robot('a'), r2d2_sim.robot('b')
    scans = []
    r2d2_sim.create_node('watcher').create_subscription(LaserScan, '/b/scan', scans.append, 10)
    a.send_cmd_vel(linear=0.5)
    r2d2_sim.advance(seconds=2.0)
    driven = a.ground_truth().pose.pose.position.x
    assert driven == pytest.approx(0.875, abs=0.01)  # 0.5 s of 1 m/s^2 ramp, then 0.5 m/s
    assert b.ground_truth().pose.pose.position.x == pytest.approx(3.0, abs=0.001)
    ahead = [scan.ranges[180] for scan in scans]  # b's beam 180 looks straight at a
    assert ahead[0] - ahead[-1] == pytest.approx(driven, abs=0.02)
