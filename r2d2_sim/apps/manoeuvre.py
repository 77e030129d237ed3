"""
The demo's manoeuvre: the tutorial's turn and drive as phases of simulated time, and its driver.

:class:`ManoeuvreDriver` sends the phase's command on ``cmd_vel``, timed by
the stamps of ``ground_truth``, and records both trajectories (wheel odometry
and the truth) for the demo's plot. The schedule itself is pure functions of
simulated time.
"""

import math
import sys
import time
from typing import Callable, List, NamedTuple, Optional, Sequence, TextIO, Tuple

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rclpy.context import Context
from rclpy.node import Node
from sensor_msgs.msg import Image, LaserScan

from r2d2_sim.client import Pose2D, pose_from_odometry, stamp_ns, twist_message
from r2d2_sim.apps.plots import scan_points_xy

__all__ = ['Phase', 'MANOEUVRE', 'manoeuvre_duration_s', 'phase_at', 'command_at',
           'format_progress', 'ManoeuvreDriver', 'NODE_NAME', 'COMMAND_RATE_HZ']

NODE_NAME = 'r2d2_demo'
# cmd_vel is re-sent at this rate of simulated time (the simulator brakes after 0.5 s).
COMMAND_RATE_HZ = 20.0


class Phase(NamedTuple):
    """One leg of the manoeuvre: a constant twist held for a span of simulated time."""

    name: str
    duration_s: float
    linear_m_s: float
    angular_rad_s: float


# The tutorial's manoeuvre: settle on the wheels, turn ~90 degrees CCW in place,
# drive 0.9 m forward (along world +y after the turn), then stand still.
MANOEUVRE: Tuple[Phase, ...] = (
    Phase('settle', 1.0, 0.0, 0.0),
    Phase('turn', math.pi / 2.0, 0.0, 1.0),
    Phase('forward', 3.0, 0.3, 0.0),
    Phase('stop', 1.0, 0.0, 0.0),
)


def manoeuvre_duration_s(phases: Sequence[Phase] = MANOEUVRE) -> float:
    """Return the total simulated time of a manoeuvre."""
    return sum(phase.duration_s for phase in phases)


def phase_at(t_s: float, phases: Sequence[Phase] = MANOEUVRE) -> Optional[Phase]:
    """Return the phase active at ``t_s`` seconds after the start (None outside)."""
    if t_s < 0.0:
        return None
    end_s = 0.0
    for phase in phases:
        end_s += phase.duration_s
        if t_s < end_s:
            return phase
    return None


def command_at(t_s: float, phases: Sequence[Phase] = MANOEUVRE) -> Tuple[float, float]:
    """Return the (linear.x m/s, angular.z rad/s) command at ``t_s``; zero outside."""
    phase = phase_at(t_s, phases)
    if phase is None:
        return 0.0, 0.0
    return phase.linear_m_s, phase.angular_rad_s


def format_progress(t_s: float, odom: Pose2D, truth: Pose2D) -> str:
    """Return one progress line: time, odometry pose and ground-truth pose."""
    def pose(p: Pose2D) -> str:
        return f'x={p.x_m:+.3f} y={p.y_m:+.3f} yaw={math.degrees(p.yaw_rad):+6.1f} deg'
    return f't={t_s:5.1f} s  odom {pose(odom)} | truth {pose(truth)}'


class ManoeuvreDriver(Node):
    """
    Sends the manoeuvre on ``cmd_vel``, timed by the stamps of ``ground_truth``.

    Records both trajectories from :meth:`begin` on and prints a progress line
    every simulated second; ``done`` turns True after the last phase. With
    ``send`` given, commands go to it instead of this node's publisher (the
    lockstep loop sends them and waits until the simulator has them). A
    command is sent on change and again every ``resend_period_s`` (the
    simulator brakes 0.5 s after the last one; inf: on change only).
    """

    def __init__(self, phases: Sequence[Phase] = MANOEUVRE, out: TextIO = sys.stdout,
                 context: Optional[Context] = None, send: Optional[Callable[[Twist], None]] = None,
                 resend_period_s: float = 1.0 / COMMAND_RATE_HZ) -> None:
        super().__init__(NODE_NAME, context=context)
        self.phases = tuple(phases)
        self.total_s = manoeuvre_duration_s(self.phases)
        self._out = out
        self._cmd_pub = self.create_publisher(Twist, 'cmd_vel', 10)
        self._send_twist = send or self._cmd_pub.publish
        self._resend_period_s = resend_period_s
        self.create_subscription(Odometry, 'odom', self._on_odom, 10)
        self.create_subscription(Odometry, 'ground_truth', self._on_truth, 10)
        self.create_subscription(Image, 'camera/image_raw', self._on_image, 2)
        self.create_subscription(LaserScan, 'scan', self._on_scan, 2)
        self.image: Optional[Image] = None
        self.scan_xy: List[Tuple[float, float]] = []
        self.odom: Optional[Pose2D] = None
        self.truth: Optional[Pose2D] = None
        self.truth_ns = -1
        self.odom_ns = -2
        self.handled_ns = -1  # the time (ns) of the last state the manoeuvre answered
        self.odom_xy: List[Tuple[float, float]] = []
        self.truth_xy: List[Tuple[float, float]] = []
        self.last_truth_wall_s = time.monotonic()
        self.done = False
        # (from s, to s) once a ground_truth stamp is older than the one before.
        self.time_went_back: Optional[Tuple[float, float]] = None
        self._recording = False
        self._start_s: Optional[float] = None
        self._phase: Optional[Phase] = None
        self._last_command: Optional[Tuple[float, float]] = None
        self._last_command_s = -math.inf
        self._next_report_s = 0.0

    def connected(self) -> bool:
        """Return True once the simulator publishes both poses and listens to cmd_vel."""
        return (self.odom is not None and self.truth is not None
                and self._cmd_pub.get_subscription_count() > 0)

    def linked(self) -> bool:
        """Return True once the graph shows the simulator's state publishers and cmd_vel reader."""
        return (self.count_publishers('ground_truth') > 0 and self.count_publishers('odom') > 0
                and self._cmd_pub.get_subscription_count() > 0)

    def begin(self, start_s: Optional[float] = None) -> None:
        """Start the manoeuvre at simulated time ``start_s`` (default: the next ground_truth)."""
        self._recording = True
        self._start_s = start_s

    @property
    def elapsed_s(self) -> float:
        """Return the simulated seconds since the manoeuvre started (0 before)."""
        if self._start_s is None or self.truth is None:
            return 0.0
        return self.truth.stamp_s - self._start_s

    def _on_image(self, msg: Image) -> None:
        self.image = msg

    def _on_scan(self, msg: LaserScan) -> None:
        # Scans come at 10 Hz, ground truth every step: the latest truth is the
        # pose the scan was taken from, give or take a step.
        if self.truth is not None:
            self.scan_xy = scan_points_xy(msg, self.truth)

    def _on_odom(self, msg: Odometry) -> None:
        self.odom = pose_from_odometry(msg)
        self.odom_ns = stamp_ns(msg.header.stamp)
        if self.truth_xy and not self.done:
            self.odom_xy.append((self.odom.x_m, self.odom.y_m))
        self._step_if_both()

    def _on_truth(self, msg: Odometry) -> None:
        if self.time_went_back is not None:
            return
        truth = pose_from_odometry(msg)
        if self.truth is not None and truth.stamp_s < self.truth.stamp_s:
            # Two simulators on one domain interleave their stamps; a run timed
            # by them means nothing.
            self.time_went_back = (self.truth.stamp_s, truth.stamp_s)
            return
        self.truth = truth
        self.truth_ns = stamp_ns(msg.header.stamp)
        self.last_truth_wall_s = time.monotonic()
        self._step_if_both()

    def _step_if_both(self) -> None:
        """Follow the manoeuvre once per step, when its truth and its odometry are both in."""
        odom, truth = self.odom, self.truth
        if (odom is not None and truth is not None and self._recording and not self.done
                and self.truth_ns == self.odom_ns and self.truth_ns > self.handled_ns):
            self.handled_ns = self.truth_ns
            self._follow_manoeuvre(odom, truth)

    def _follow_manoeuvre(self, odom: Pose2D, truth: Pose2D) -> None:
        if self._start_s is None:
            self._start_s = truth.stamp_s
        if not self.truth_xy:
            self.odom_xy.append((odom.x_m, odom.y_m))
        self.truth_xy.append((truth.x_m, truth.y_m))
        t_s = self.elapsed_s
        self._report(t_s, odom, truth)
        if t_s >= self.total_s:
            self._send((0.0, 0.0), t_s)
            self._print(format_progress(t_s, odom, truth))
            self.done = True
            return
        phase = phase_at(t_s, self.phases)
        if phase is None:  # begun for a later time: hold the robot until then
            self._send((0.0, 0.0), t_s)
            return
        if phase is not self._phase:
            self._phase = phase
            self._print(f'-- {phase.name}: linear.x {phase.linear_m_s:+.2f} m/s, angular.z '
                        f'{phase.angular_rad_s:+.2f} rad/s for {phase.duration_s:.2f} s')
        self._send((phase.linear_m_s, phase.angular_rad_s), t_s)

    def _report(self, t_s: float, odom: Pose2D, truth: Pose2D) -> None:
        if t_s >= self._next_report_s:
            self._print(format_progress(t_s, odom, truth))
            self._next_report_s = math.floor(t_s) + 1.0

    def _send(self, command: Tuple[float, float], t_s: float) -> None:
        """Send on change, and otherwise every ``resend_period_s`` of simulated time."""
        if command == self._last_command and t_s - self._last_command_s < self._resend_period_s:
            return
        self._send_twist(twist_message(*command))
        self._last_command = command
        self._last_command_s = t_s

    def _print(self, line: str) -> None:
        print(line, file=self._out, flush=True)
