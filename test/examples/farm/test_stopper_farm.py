import math
import os

from geometry_msgs.msg import Twist
from hypothesis import given
from nav_msgs.msg import Odometry
import pytest
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import LaserScan

from r2d2_sim.farm import FarmJob, farm_settings, ROOM, safe, scenarios, ScenarioSpace

# Up to 5 boxes across the room, between a start at its west end and a goal at its east end.
SPACE = ScenarioSpace(world=ROOM, obstacles=(0, 5), area=(-1.8, -2.2, 0.9, 2.2),
                      start_area=(-2.6, -0.4, -2.2, 0.6), start_yaw=(-0.5, 0.5),
                      goal_area=(1.2, -0.4, 1.6, 0.6))
# What the stopper reads, at its own rate: odom at 20 Hz and the laser's front half.
PARAMETERS = {'publish_rate': 20.0, 'imu_rate': 0.0, 'publish_tf': False,
              'scan_angle_min': -math.pi / 2, 'scan_angle_max': math.pi / 2, 'scan_samples': 181}
VARIATIONS = int(os.environ.get('VARIATIONS', '200'))


class GoalStopper(Node):
    """Drive to the goal on odom at 20 Hz; stop while the laser sees anything in the way."""

    def __init__(self, goal, stop_m=0.6, half_width_m=0.35, **node_kwargs):
        super().__init__('goal_stopper', **node_kwargs)
        self.goal, self.stop_m, self.half_width_m = goal, stop_m, half_width_m
        self.pose = self.blocked = None
        self.cmd_vel = self.create_publisher(Twist, 'cmd_vel', 10)
        self.create_subscription(Odometry, 'odom', self.on_odom, 10)
        self.create_subscription(LaserScan, 'scan', self.on_scan, qos_profile_sensor_data)
        self.create_timer(0.05, self.on_tick)

    def on_odom(self, odom):
        p, q = odom.pose.pose.position, odom.pose.pose.orientation
        self.pose = p.x, p.y, 2.0 * math.atan2(q.z, q.w)

    def on_scan(self, scan):
        # In the way: a return ahead, nearer than stop_m, within the robot's half width.
        self.blocked = False
        for i, r in enumerate(scan.ranges):
            angle = scan.angle_min + i * scan.angle_increment
            if math.isfinite(r) and 0.0 < r * math.cos(angle) < self.stop_m:
                self.blocked |= abs(r * math.sin(angle)) < self.half_width_m

    def on_tick(self):
        if self.pose is None or self.blocked is None:
            return
        x, y, yaw = self.pose
        distance = math.hypot(self.goal[0] - x, self.goal[1] - y)
        turn = math.atan2(self.goal[1] - y, self.goal[0] - x) - yaw
        turn = math.atan2(math.sin(turn), math.cos(turn))
        command = Twist()
        command.angular.z = max(-0.8, min(0.8, 1.5 * turn))
        if not self.blocked and abs(turn) < 0.4:
            command.linear.x = min(0.4, 0.5 * distance)
        self.cmd_vel.publish(command)


def goal_stopper(harness, scenario):
    harness.add_node(GoalStopper(scenario.goal_point, context=harness.context))


# The same farm for the runner: python -m r2d2_sim.farm run test_stopper_farm.py:FARM
FARM = FarmJob(SPACE, goal_stopper, seconds=20.0, verdict=safe, parameters=PARAMETERS,
               name='stopper')


@pytest.mark.parametrize('seed', range(VARIATIONS))
def test_the_stopper_never_touches_anything(r2d2_farm, seed):
    outcome = r2d2_farm.run(SPACE.draw(seed), goal_stopper, seconds=20.0, verdict=safe,
                            parameters=PARAMETERS)
    assert outcome.passed, outcome


@farm_settings(max_examples=int(os.environ.get('EXAMPLES', '20')))
@given(scenario=scenarios(SPACE))
def test_no_layout_of_up_to_5_boxes_makes_it_touch_one(r2d2_farm, scenario):
    outcome = r2d2_farm.run(scenario, goal_stopper, seconds=20.0, verdict=safe,
                            parameters=PARAMETERS)
    assert outcome.passed, outcome
