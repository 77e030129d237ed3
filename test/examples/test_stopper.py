from geometry_msgs.msg import Twist
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import LaserScan

from r2d2_sim.testing import box_urdf, scan_range

pytest_plugins = ['r2d2_sim.pytest_plugin']


class Stopper(Node):
    """Drive ahead at 0.3 m/s; stop while anything is nearer than stop_m ahead."""

    def __init__(self, stop_m=0.9, **node_kwargs):
        super().__init__('stopper', **node_kwargs)
        self.stop_m, self.ahead_m = stop_m, None
        self.cmd_vel = self.create_publisher(Twist, 'cmd_vel', 10)
        self.create_subscription(LaserScan, 'scan', self.on_scan, qos_profile_sensor_data)
        self.create_timer(0.05, self.on_tick)

    def on_scan(self, scan):
        self.ahead_m = scan_range(scan, 0.0)

    def on_tick(self):
        if self.ahead_m is not None:
            command = Twist()
            command.linear.x = 0.3 if self.ahead_m > self.stop_m else 0.0
            self.cmd_vel.publish(command)


def test_the_stopper_stops_before_the_wall(r2d2_sim):
    r2d2_sim.spawn(box_urdf((0.2, 2.0, 1.0)), name='wall', position=(2.0, 0.0, 0.5))
    r2d2_sim.add_node(Stopper(context=r2d2_sim.context))
    with r2d2_sim.watch() as run:
        r2d2_sim.advance(seconds=10.0)
    assert run.contacts == []                      # it never touched the wall
    assert 0.1 < run.clearance.distance_m < 0.5    # and stopped close to it
