"""
The ``demo`` executable's pure helpers and its driver node, in this process.

The manoeuvre, its progress line, the trajectory plot and the camera snapshot;
the demo and ``drive`` as real processes are in system/test_demo.py.
"""

import math

import pytest

from common import PNG_SIGNATURE, PROGRESS
from r2d2_sim.apps.demo import (
    command_at, format_progress, manoeuvre_duration_s, MANOEUVRE, phase_at)
from r2d2_sim.apps.plots import write_trajectory_plot
from r2d2_sim.client import Pose2D

TURN_END_S = 1.0 + math.pi / 2.0
FORWARD_END_S = TURN_END_S + 3.0


@pytest.mark.parametrize('t_s, expected', [
    (-0.5, (0.0, 0.0)),              # before the start
    (0.0, (0.0, 0.0)),               # settling
    (0.99, (0.0, 0.0)),
    (1.0, (0.0, 1.0)),               # turn starts exactly at 1 s
    (TURN_END_S - 0.01, (0.0, 1.0)),
    (TURN_END_S + 0.01, (0.3, 0.0)),  # then straight ahead
    (FORWARD_END_S - 0.01, (0.3, 0.0)),
    (FORWARD_END_S + 0.01, (0.0, 0.0)),  # stopped
    (100.0, (0.0, 0.0)),             # after the end
])
def test_command_at_returns_the_phase_command(t_s, expected):
    assert command_at(t_s) == pytest.approx(expected)


def test_manoeuvre_turns_90_degrees_then_drives_0_9_m():
    # Integrals of the open-loop schedule: 1 rad/s for pi/2 s, then 0.3 m/s for 3 s.
    turned_rad = sum(p.angular_rad_s * p.duration_s for p in MANOEUVRE)
    driven_m = sum(p.linear_m_s * p.duration_s for p in MANOEUVRE)
    assert turned_rad == pytest.approx(math.pi / 2.0)
    assert driven_m == pytest.approx(0.9)
    assert manoeuvre_duration_s() == pytest.approx(FORWARD_END_S + 1.0)
    assert [phase_at(t).name for t in (0.5, 2.0, 3.0, 6.0)] == [
        'settle', 'turn', 'forward', 'stop']


def test_format_progress_shows_both_poses_in_degrees():
    line = format_progress(3.0, Pose2D(0.0, 0.412, -0.01, math.radians(88.1)),
                           Pose2D(0.0, 0.405, -0.012, math.radians(87.0)))
    assert line == ('t=  3.0 s  odom x=+0.412 y=-0.010 yaw= +88.1 deg | '
                    'truth x=+0.405 y=-0.012 yaw= +87.0 deg')
    assert PROGRESS.match(line)


def test_trajectory_plot_is_a_real_png(tmp_path):
    truth = [(0.01 * math.sin(i / 10.0), 0.01 * i) for i in range(100)]
    odom = [(0.0, 0.0101 * i) for i in range(100)]
    path = write_trajectory_plot(tmp_path / 'plot.png', odom, truth)
    assert path == tmp_path / 'plot.png'
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert len(data) > 10_000


def test_trajectory_plot_copes_with_a_missing_trajectory(tmp_path):
    path = write_trajectory_plot(tmp_path / 'plot.png', [], [(0.0, 0.0), (0.1, 0.2)])
    assert path.read_bytes()[:8] == PNG_SIGNATURE


def _odometry_at(stamp_s, x_m=0.0):
    from nav_msgs.msg import Odometry
    msg = Odometry()
    msg.header.stamp.sec, nanosec = divmod(round(stamp_s * 1e9), 10**9)
    msg.header.stamp.nanosec = nanosec
    msg.pose.pose.position.x = x_m
    msg.pose.pose.orientation.w = 1.0
    return msg


def test_driver_stops_timing_when_ground_truth_goes_back_in_time(ros):
    """Two simulators interleave their stamps: the driver records it instead of crashing."""
    import io

    from r2d2_sim.apps.demo import ManoeuvreDriver

    out = io.StringIO()
    driver = ros.add_node(ManoeuvreDriver(out=out, context=ros.context), use_sim_time=False)
    driver._on_odom(_odometry_at(15.0))
    driver.begin()
    driver._on_truth(_odometry_at(15.0))  # each step's odometry and truth: answered
    driver._on_odom(_odometry_at(15.5))
    driver._on_truth(_odometry_at(15.5, x_m=0.1))
    assert driver.elapsed_s == 0.5 and driver.time_went_back is None
    driver._on_truth(_odometry_at(0.1))  # before the start: no phase to follow
    assert driver.time_went_back == (15.5, 0.1)
    driver._on_odom(_odometry_at(15.6))
    driver._on_truth(_odometry_at(15.6, x_m=0.2))  # nothing is timed from here on
    assert driver.elapsed_s == 0.5 and driver.truth_xy[-1] == (0.1, 0.0)


def test_driver_begun_for_a_later_time_holds_the_robot_until_then(ros):
    """begin(start_s) ahead of the states: a stop command meanwhile, then the first phase."""
    import io

    from r2d2_sim.apps.demo import ManoeuvreDriver

    sent = []
    driver = ros.add_node(ManoeuvreDriver(out=io.StringIO(), context=ros.context,
                                          send=sent.append, resend_period_s=math.inf),
                          use_sim_time=False)
    driver.begin(start_s=20.0)
    driver._on_odom(_odometry_at(15.0))
    driver._on_truth(_odometry_at(15.0))  # 5 s before the start: no phase yet
    assert [(t.linear.x, t.angular.z) for t in sent] == [(0.0, 0.0)] and not driver.done


def test_camera_snapshot_writer_round_trips(tmp_path):
    """An rgb8 Image with a padded row stride becomes a PNG of the right size and colours."""
    from matplotlib import pyplot
    from sensor_msgs.msg import Image
    from r2d2_sim.apps.plots import write_camera_snapshot
    image = Image(height=2, width=3, encoding='rgb8', step=11)
    image.data = bytes([255, 0, 0] * 3 + [0, 0]) + bytes([0, 0, 255] * 3 + [0, 0])
    path = write_camera_snapshot(tmp_path / 'snap.png', image)
    pixels = pyplot.imread(path)
    assert pixels.shape[:2] == (2, 3)
    assert tuple(pixels[0, 0, :3]) == (1.0, 0.0, 0.0)
    assert tuple(pixels[1, 2, :3]) == (0.0, 0.0, 1.0)


def test_scan_points_are_placed_in_the_world_from_the_pose():
    """A robot at (1, 2) facing +y sees a return 1 m ahead at (1, 3); infinities are skipped."""
    from sensor_msgs.msg import LaserScan
    from r2d2_sim.apps.plots import scan_points_xy
    scan = LaserScan(angle_min=-math.pi / 2, angle_increment=math.pi / 2,
                     ranges=[2.0, 1.0, math.inf, -math.inf])
    points = scan_points_xy(scan, Pose2D(0.0, 1.0, 2.0, math.pi / 2))
    assert points == [pytest.approx((3.0, 2.0)), pytest.approx((1.0, 3.0))]
