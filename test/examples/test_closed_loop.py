from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
from rclpy.node import Node

pytest_plugins = ['r2d2_sim.pytest_plugin']


class DriveToX(Node):
    """A P-controller at 20 Hz: drive along x to goal_m and stop there."""

    def __init__(self, goal_m=1.0, **node_kwargs):
        super().__init__('drive_to_x', **node_kwargs)
        self.goal_m, self.x_m = goal_m, None
        self.cmd_vel = self.create_publisher(Twist, 'cmd_vel', 10)
        self.create_subscription(Odometry, 'odom', self.on_odom, 10)
        self.create_timer(0.05, self.on_tick)

    def on_odom(self, odom):
        self.x_m = odom.pose.pose.position.x

    def on_tick(self):
        if self.x_m is not None:
            command = Twist()
            command.linear.x = max(-0.5, min(0.5, 1.5 * (self.goal_m - self.x_m)))
            self.cmd_vel.publish(command)


def test_p_controller_stops_at_one_metre(r2d2_sim):
    r2d2_sim.add_node(DriveToX(context=r2d2_sim.context))  # now on simulated time
    r2d2_sim.advance(seconds=5.0)  # in lockstep: each message answered before the next step
    truth = r2d2_sim.ground_truth()
    assert truth.pose.pose.position.x == pytest.approx(1.0, abs=0.01)
    assert abs(truth.twist.twist.linear.x) < 0.01
