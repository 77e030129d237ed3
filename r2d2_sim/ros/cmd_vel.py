"""
``cmd_vel`` into a robot, and what the node says about the commands it gets.

:class:`CmdVelInput` is a robot's one subscription: ``Twist``, or
``TwistStamped`` with ``enable_stamped_cmd_vel`` (a zero stamp means now, a
stale one is refused). Each command goes to the drive controller, whose
verdict (refused, clamped, axes a differential drive cannot follow) becomes a
throttled warning. Once a second it looks at the graph for ``cmd_vel``
publishers of the other type, which the middleware never delivers.
"""

from typing import Callable

from geometry_msgs.msg import Twist, TwistStamped
from rclpy.clock import Clock as RclpyClock, ClockType
from rclpy.node import Node
from rclpy.qos import ReliabilityPolicy

from r2d2_sim.client import UNKNOWN_NODE_NAME
from r2d2_sim.model.drive_controller import NO_WHEELS
from r2d2_sim.model.timing import stamp_ns, ThrottledLog
from r2d2_sim.ros.seams import Commandable
from r2d2_sim.sim.settings.config import SimConfig

# Warnings about rejected commands repeat at most this often per kind of problem.
WARNING_PERIOD_S = 5.0
# How often (wall-clock seconds) to look for cmd_vel publishers of a wrong type.
GRAPH_CHECK_PERIOD_S = 1.0
CMD_VEL_TYPE = 'geometry_msgs/msg/Twist'
CMD_VEL_STAMPED_TYPE = 'geometry_msgs/msg/TwistStamped'


class CmdVelInput:
    """
    The ``cmd_vel`` subscription of ``node``, feeding ``robot.command`` (a Robot's).

    ``received`` counts the messages taken (refused ones too, so a client can
    confirm its command arrived), ``rejected`` those refused. A message is
    counted last, once the robot holds it and its warnings are out: a test
    that waits for the count and then steps is sure to step with it.
    ``now_ns`` gives the simulated time, against which a TwistStamped's age
    is judged; the graph is looked at every ``graph_check_period_s`` of wall time.
    """

    def __init__(self, node: Node, config: SimConfig, robot: Commandable,
                 throttled: ThrottledLog, now_ns: Callable[[], int], *,
                 graph_check_period_s: float = GRAPH_CHECK_PERIOD_S) -> None:
        self.received = 0
        self.rejected = 0
        self._node, self._config, self._robot = node, config, robot
        self._now_ns = now_ns
        self._throttled = throttled
        self._stamped = config.enable_stamped_cmd_vel
        if self._stamped:
            node.create_subscription(TwistStamped, 'cmd_vel', self.on_twist_stamped, 10)
        else:
            node.create_subscription(Twist, 'cmd_vel', self.on_twist, 10)
        node.create_timer(graph_check_period_s, self.check_publishers,
                          clock=RclpyClock(clock_type=ClockType.STEADY_TIME))

    def _warn(self, kind: str, text: str) -> None:
        self._throttled(kind, self._node.get_logger().warning, text)

    def on_twist_stamped(self, msg: TwistStamped) -> None:
        """Take a stamped command unless its stamp is older than ``cmd_vel_timeout``."""
        stamped_ns = stamp_ns(msg.header.stamp)
        timeout_s = self._config.cmd_vel_timeout_s
        # A timeout beyond any run (1e308 s is accepted) is none, as the drive's own is
        # (timeout_steps): rounding it to nanoseconds would overflow.
        timeout_ns = round(timeout_s * 1e9) if timeout_s * 1e9 < 2.0 ** 62 else 0
        now_ns = self._now_ns()
        # A zero stamp means "now" (as Nav2's and teleop's unstamped senders fill it).
        age_ns = now_ns - stamped_ns
        if stamped_ns and timeout_ns and age_ns > timeout_ns:
            self.rejected += 1
            self._warn('cmd_vel stale', f'rejected cmd_vel stamped {stamped_ns / 1e9:.3f} s: '
                       f'{age_ns / 1e9:.3f} s old at t={now_ns / 1e9:.3f} s, more than '
                       f'cmd_vel_timeout ({timeout_s:g} s)')
            self.received += 1
            return
        self.on_twist(msg.twist)

    def on_twist(self, msg: Twist) -> None:
        """Hand a command to the simulation and report its verdict."""
        try:
            self._take(msg)
        finally:
            self.received += 1

    def _take(self, msg: Twist) -> None:
        linear, angular = msg.linear, msg.angular
        verdict = self._robot.command(linear.x, angular.z, linear_y=linear.y,
                                      linear_z=linear.z, angular_x=angular.x,
                                      angular_y=angular.y)
        if verdict is NO_WHEELS:
            self._warn('cmd_vel no wheels', 'cmd_vel ignored: the robot has no wheels configured')
            return
        if verdict.problem is not None:
            self.rejected += 1
            self._warn(f'cmd_vel {verdict.problem}', f'rejected cmd_vel with {verdict.problem}; '
                       'keeping the last valid command')
            return
        accepted = verdict.accepted
        assert accepted is not None, 'a command without a problem was accepted'
        if verdict.ignored_axes:
            self._warn('cmd_vel ignored axes',
                       f'cmd_vel {", ".join(verdict.ignored_axes)} ignored: a differential '
                       'drive follows linear.x and angular.z only')
        if verdict.clamped:
            self._warn('cmd_vel clamped',
                       f'cmd_vel (linear.x {linear.x:.4g}, angular.z {angular.z:.4g}) exceeds '
                       f'the speed limits: scaled to ({accepted.linear_m_s:.4g}, '
                       f'{accepted.angular_rad_s:.4g})')

    def check_publishers(self) -> None:
        """Warn about ``cmd_vel`` publishers ROS does not deliver here: wrong type, best effort."""
        node = self._node
        topic = node.resolve_topic_name('cmd_vel')
        expected = CMD_VEL_STAMPED_TYPE if self._stamped else CMD_VEL_TYPE
        for info in node.get_publishers_info_by_topic('cmd_vel'):
            # An endpoint can be discovered before its node's name: the next check names it.
            if info.node_name == UNKNOWN_NODE_NAME:
                continue
            publisher = f'{info.node_namespace.rstrip("/")}/{info.node_name}'
            if info.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT:
                # A reliable subscription and a best-effort publisher do not match
                # (only the publisher's side warns): say so on this side too.
                self._warn(f'cmd_vel best effort {publisher}',
                           f'{publisher} publishes on {topic} best effort, which this node\'s '
                           'reliable subscription does not take (ROS delivers nothing): '
                           'publish cmd_vel reliable, as teleop and Nav2 do')
            if info.topic_type != expected:
                self._warn(f'cmd_vel type {info.topic_type}',
                           f'{publisher} publishes {info.topic_type} on {topic}, which ROS '
                           f'does not deliver: this node takes {expected}'
                           + ('' if self._stamped else
                              ' (set enable_stamped_cmd_vel for TwistStamped)'))
