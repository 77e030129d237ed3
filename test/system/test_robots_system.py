"""
Robot descriptions in the real executable: the classic's params file, bad descriptions.

The same descriptions in process are ros/test_robots.py's.
"""

from helpers import (
    drive_forward_until, next_domain_id, RemoteProbe, start_sim_process, stop_process)
import pytest

from common import CLASSIC_YAML


def test_classic_params_file_cross_process():
    """The real executable with --params-file urdf/classic_r2d2.yaml drives +x on cmd_vel."""
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry
    domain = next_domain_id()
    process = start_sim_process(domain, '--params-file', CLASSIC_YAML)
    probe = RemoteProbe(domain, 'classic_probe')
    try:
        truth = []
        probe.node.create_subscription(Odometry, 'ground_truth', truth.append, 10)
        pub = probe.node.create_publisher(Twist, 'cmd_vel', 10)
        spin_until = probe.spin_until
        assert spin_until(lambda: truth, 20.0), 'no ground_truth from sim_node'
        start = truth[-1].pose.pose.position
        assert drive_forward_until(spin_until, pub, truth, 0.15, 15.0), \
            'classic did not move forward'
        assert abs(truth[-1].pose.pose.position.y - start.y) < 0.05
    finally:
        code, out, err = stop_process(process)
        probe.close()
    assert code == 0, err
    assert 'Traceback' not in err + out


@pytest.mark.parametrize('args, fragment', [
    (['-p', 'robot_description:=<robot name="x"><link name="a"></robot'], 'not well-formed'),
    (['-p', 'urdf:=package://no_such_package/urdf/robot.urdf'], 'no_such_package'),
    (['-p', 'extra_models:=["cube.urdf 0 0"]'], 'extra_models'),
])
def test_bad_description_is_one_line_and_exit_2(args, fragment):
    """The executable refuses bad descriptions with one error line and exit code 2."""
    process = start_sim_process(next_domain_id(), *args)
    out, err = process.communicate(timeout=30.0)
    assert process.returncode == 2, err
    assert 'Traceback' not in err
    lines = [line for line in err.splitlines() if 'error' in line]
    assert len(lines) == 1 and fragment in lines[0], err


def test_robot_without_wheels_warns_once_at_start_up():
    """urdf:=cube.urdf runs, warns once that cmd_vel is ignored, and stops cleanly."""
    from nav_msgs.msg import Odometry
    domain = next_domain_id()
    process = start_sim_process(domain, '-p', 'urdf:=cube.urdf')
    probe = RemoteProbe(domain, 'cube_probe')
    try:
        truth = []
        probe.node.create_subscription(Odometry, 'ground_truth', truth.append, 10)
        assert probe.spin_until(lambda: len(truth) > 5, 20.0), 'no ground_truth from the cube'
    finally:
        code, out, err = stop_process(process)
        probe.close()
    assert code == 0, err
    assert (out + err).count('none of the default wheel joints') == 1, out + err
