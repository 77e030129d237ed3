"""
Stepping sim_node across processes reproduces ros/test_control.py's in-process run.

The command schedule and its in-process run are in helpers.py.
"""

import math

from geometry_msgs.msg import Twist
from helpers import _run_schedule_in_process, SCHEDULE, SCHEDULE_STEPS
from nav_msgs.msg import Odometry
import pytest
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from r2d2_sim.testing import SimProcess


@pytest.mark.parametrize('real_time_factor', ['1.0', '10.0', '0.0'])
def test_cross_process_stepping_matches_in_process(ros, real_time_factor):
    """~/step across processes reproduces the in-process run bit for bit, at any speed."""
    expected = _run_schedule_in_process(ros)
    sim = SimProcess(start_paused=True, ros_args=['-p', f'real_time_factor:={real_time_factor}'])
    node = sim.probe.node
    joints, truth, clocks = [], [], []
    subscriptions = [node.create_subscription(JointState, 'joint_states', joints.append, 1000),
                     node.create_subscription(Odometry, 'ground_truth', truth.append, 1000),
                     node.create_subscription(Clock, '/clock', clocks.append, 1000)]
    try:
        assert sim.probe.spin_until(
            lambda: all(s.get_publisher_count() > 0 for s in subscriptions), 10.0)
        commands = {step: (v, w) for step, v, w in SCHEDULE}
        # The schedule's NaN is for the node to refuse: send_cmd_vel refuses it first.
        raw = node.create_publisher(Twist, 'cmd_vel', 10)
        assert sim.probe.spin_until(lambda: raw.get_subscription_count() > 0, 10.0)
        for step in range(SCHEDULE_STEPS):
            if step in commands and all(map(math.isfinite, commands[step])):
                sim.send_cmd_vel(*commands[step])  # returns once the node has counted it
            elif step in commands:
                before = sim.robot().commands_received()
                message = Twist()
                message.linear.x, message.angular.z = commands[step]
                raw.publish(message)
                assert sim.probe.spin_until(
                    lambda: sim.robot().commands_received() > before, 10.0)
            assert sim.step()['steps'] == 1
            assert sim.probe.spin_until(
                lambda: len(joints) >= step + 1 and len(truth) >= step + 1, 10.0)
    finally:
        code, out, err = sim.stop()
    assert code == 0, err
    got = [(tuple(j.position), tuple(j.velocity)) for j in joints[-SCHEDULE_STEPS:]]
    assert got == [(e[0], e[1]) for e in expected]
    got_truth = [((t.pose.pose.position.x, t.pose.pose.position.y, t.pose.pose.position.z),
                  (t.twist.twist.linear.x, t.twist.twist.linear.y, t.twist.twist.linear.z))
                 for t in truth[-SCHEDULE_STEPS:]]
    assert got_truth == [(e[2], e[4]) for e in expected]
    assert clocks[-1].clock.sec * 10**9 + clocks[-1].clock.nanosec == \
        SCHEDULE_STEPS * 10**9 // 240
