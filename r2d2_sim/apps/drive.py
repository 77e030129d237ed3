"""
``drive``: publish one Twist on ``cmd_vel`` for a while, then stop the robot.

For users without the ``ros2`` CLI (``ros2 topic pub``)::

    drive --linear 0.3 --angular 0.0 --duration 2.0 [--rate 20] [--topic cmd_vel]
          [--stamped]

``--stamped`` publishes a TwistStamped (stamped now, on the node's clock) for a
simulator with ``enable_stamped_cmd_vel``; when only a subscriber of the other
type is there, the error line says to add or drop it.

The command is re-sent at ``--rate`` Hz because the simulator brakes the wheels
after 0.5 s without one. The duration runs on the node's clock, so
``--ros-args -p use_sim_time:=true`` makes it simulated seconds.
"""

import argparse
import os
import sys
from typing import Any, Callable, List, Optional, Sequence

from geometry_msgs.msg import Twist, TwistStamped
import rclpy
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.time import Time
from rclpy.timer import Timer

from r2d2_sim.apps.cli import (
    EXIT_INTERRUPTED, finite_number, init_ros, non_ros_args, number_in, raise_if_stopped,
    stop_on_signals, topic_name_arg)
from r2d2_sim.client import spin_until, twist_stamped_message
from r2d2_sim.ros.parameters import rclpy_parameter_problem

NODE_NAME = 'drive'
# Wall-clock seconds to wait for the simulator's cmd_vel subscription (and, with
# use_sim_time, for its first /clock message).
DISCOVERY_TIMEOUT_S = 5.0
# Wall-clock seconds the final zero Twist gets to reach subscribers before exit.
STOP_LINGER_S = 0.25
# The longest --duration: 31 years, far within rcl's int64 nanoseconds (1e10 s overflowed).
MAX_DURATION_S = 1.0e9
# --rate: a timer period from 1000 s to 0.1 ms (1e-10 Hz overflowed rcl's timer period,
# after the command had gone out, and no zero Twist followed), as the simulator's rates.
RATE_RANGE_HZ = (0.001, 10000.0)
TWIST_TYPE = 'geometry_msgs/msg/Twist'
TWIST_STAMPED_TYPE = 'geometry_msgs/msg/TwistStamped'


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser (ROS arguments are removed before it runs)."""
    parser = argparse.ArgumentParser(
        prog=NODE_NAME,
        description='Publish a Twist (or TwistStamped) on cmd_vel at a fixed rate for a '
                    'duration, then a zero one. Add --ros-args -p use_sim_time:=true to time '
                    'it in simulated seconds.')
    parser.add_argument('--linear', type=finite_number, default=0.0, metavar='M_S',
                        help='forward speed, linear.x in m/s (default 0)')
    parser.add_argument('--angular', type=finite_number, default=0.0, metavar='RAD_S',
                        help='counter-clockwise yaw rate, angular.z in rad/s (default 0)')
    parser.add_argument('--duration', type=number_in(0.0, MAX_DURATION_S, 's'), default=1.0,
                        metavar='S', help='how long to drive, in seconds of the node clock, '
                                          f'0 to {MAX_DURATION_S:g} (default 1)')
    parser.add_argument('--rate', type=number_in(*RATE_RANGE_HZ, 'Hz'), default=20.0,
                        metavar='HZ',
                        help=f'publishing rate, {RATE_RANGE_HZ[0]:g} to {RATE_RANGE_HZ[1]:g} Hz; '
                             'keep it >= 2 Hz, the simulator brakes after 0.5 s without a '
                             'command (default 20)')
    parser.add_argument('--topic', type=topic_name_arg, default='cmd_vel',
                        help='topic name (default cmd_vel)')
    parser.add_argument('--stamped', action='store_true',
                        help='publish geometry_msgs/TwistStamped, stamped now, for a simulator '
                             'with enable_stamped_cmd_vel (default: geometry_msgs/Twist)')
    return parser


class DriveCommand(Node):
    """
    Publishes one Twist at a fixed rate for a duration on its clock, then a zero Twist.

    ``stamped``: a TwistStamped instead, each stamped when it is sent.
    """

    def __init__(self, linear_m_s: float, angular_rad_s: float, duration_s: float,
                 rate_hz: float, topic: str = 'cmd_vel', stamped: bool = False) -> None:
        super().__init__(NODE_NAME)
        self._twist = Twist()
        self._twist.linear.x = linear_m_s
        self._twist.angular.z = angular_rad_s
        self._duration = Duration(nanoseconds=round(duration_s * 1e9))
        self._period_s = 1.0 / rate_hz
        self.stamped = stamped
        self._publisher = self.create_publisher(TwistStamped if stamped else Twist, topic, 10)
        self._start: Optional[Time] = None  # both from start() on
        self._timer: Optional[Timer] = None
        self.done = False

    def wait_for_subscriber(self, executor: Executor, timeout_s: float,
                            abort: Optional[Callable[[], bool]] = None) -> bool:
        """Spin until something subscribes to the topic; False at the deadline or on abort()."""
        return spin_until(executor, lambda: self._publisher.get_subscription_count() > 0,
                          timeout_s, abort)

    def other_type_subscribers(self) -> List[str]:
        """Return the nodes subscribing the topic as the other type (Twist or TwistStamped)."""
        other = TWIST_TYPE if self.stamped else TWIST_STAMPED_TYPE
        return sorted({f'{info.node_namespace.rstrip("/")}/{info.node_name}'
                       for info in self.get_subscriptions_info_by_topic(self.topic)
                       if info.topic_type == other})

    def _publish(self, twist: Twist) -> None:
        message: Any = twist
        if self.stamped:
            message = twist_stamped_message(stamp_ns=self.get_clock().now().nanoseconds,
                                            twist=twist)
        self._publisher.publish(message)

    def wait_for_clock(self, executor: Executor, timeout_s: float,
                       abort: Optional[Callable[[], bool]] = None) -> bool:
        """Spin until the clock runs (with use_sim_time it reads 0 until /clock arrives)."""
        return spin_until(executor, lambda: self.get_clock().now().nanoseconds > 0, timeout_s,
                          abort)

    def start(self) -> None:
        """Publish the command now and from then on at the rate, on the node's clock."""
        self._start = self.get_clock().now()
        self._publish(self._twist)
        self._timer = self.create_timer(self._period_s, self._on_timer)

    def _on_timer(self) -> None:
        if self.done:
            return
        assert self._start is not None  # start() sets it before it makes this timer
        if self.get_clock().now() - self._start >= self._duration:
            self.stop()
        else:
            self._publish(self._twist)

    def stop(self) -> None:
        """
        Publish one zero Twist and give it up to ``STOP_LINGER_S`` to be acknowledged.

        Exiting right after ``publish()`` loses the sample now and then: on a
        loaded machine the subscriber had not taken it before this participant
        left, and it was dropped with the writer (3 of 10 interrupts with two
        busy cores, none of 40 with the linger). An acknowledgement usually
        waits for Fast DDS's next heartbeat (about 3 s), too long for Ctrl-C,
        so the wait is capped; the simulator brakes after 0.5 s without a
        command anyway.
        """
        self.done = True
        if self._timer is not None:
            self._timer.cancel()
        self._publish(Twist())
        self._publisher.wait_for_all_acked(Duration(seconds=STOP_LINGER_S))

    @property
    def topic(self) -> str:
        """Return the fully resolved topic name."""
        return self._publisher.topic_name


def no_subscriber_problem(node: DriveCommand) -> str:
    """Say why nothing took the command: a subscriber of the other type, or none at all."""
    others = node.other_type_subscribers()
    if others:
        mine, theirs = ((TWIST_STAMPED_TYPE, TWIST_TYPE) if node.stamped
                        else (TWIST_TYPE, TWIST_STAMPED_TYPE))
        return (f'nothing subscribed to {node.topic} as {mine} within '
                f'{DISCOVERY_TIMEOUT_S:g} s, but {", ".join(others)} subscribes to it as '
                f'{theirs}: {"drop --stamped" if node.stamped else "use --stamped"}')
    return (f'nothing subscribed to {node.topic} within {DISCOVERY_TIMEOUT_S:g} s: is the '
            'simulator running (same ROS_DOMAIN_ID)?')


def main(args: Optional[Sequence[str]] = None) -> int:
    """
    Drive, then stop; return the exit status (1 if nobody subscribes to the topic).

    Ctrl-C (or SIGTERM) publishes the zero Twist before exiting with 130. The
    signals only set an event that the loops check, so the context is still up
    to publish it and no exception lands inside rclpy's message handling.
    """
    argv = list(sys.argv if args is None else args)
    options = build_parser().parse_args(non_ros_args(argv, NODE_NAME))
    # Discovery stays on this host unless the user says otherwise, as the .venv/bin/drive
    # wrapper and demo keep it (python -m has no wrapper); set before rclpy.init.
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    stop = stop_on_signals()
    if not init_ros(argv, NODE_NAME):
        return 2
    node = None
    executor = SingleThreadedExecutor()
    try:
        node = DriveCommand(options.linear, options.angular, options.duration,
                            options.rate, options.topic, options.stamped)
        executor.add_node(node)
        if not node.wait_for_subscriber(executor, DISCOVERY_TIMEOUT_S, stop.is_set):
            raise_if_stopped(stop)
            print(f'{NODE_NAME}: error: {no_subscriber_problem(node)}', file=sys.stderr)
            return 1
        if not node.wait_for_clock(executor, DISCOVERY_TIMEOUT_S, stop.is_set):
            raise_if_stopped(stop)
            print(f'{NODE_NAME}: error: no /clock within {DISCOVERY_TIMEOUT_S:g} s '
                  '(use_sim_time is true)', file=sys.stderr)
            return 1
        node.start()
        while not node.done:
            executor.spin_once(timeout_sec=0.1)
            raise_if_stopped(stop)
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):
        if node is not None and not node.done and node.context.ok():
            node.stop()
        return EXIT_INTERRUPTED
    except ParameterException as exc:  # rclpy's own, such as use_sim_time:=1, as it builds node
        print(f'{NODE_NAME}: error: {rclpy_parameter_problem(exc)}', file=sys.stderr)
        return 2
    finally:
        # Shut the executor down before the context: left to the garbage
        # collector at exit, its __del__ met a destroyed guard condition and
        # printed "Exception ignored in Executor.__del__" now and then.
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
