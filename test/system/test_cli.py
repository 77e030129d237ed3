"""
The real sim_node executable in its own process, driven from this test process.

Its ``main`` called in this process is apps/test_cli_apps.py's.
"""

import signal
import subprocess
import sys

from helpers import (
    drive_forward_until, next_domain_id, RemoteProbe, ros_env, sim_node_command,
    start_sim_process, stop_process)
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import pytest
from sensor_msgs.msg import JointState

from common import _check_help


@pytest.fixture
def domain():
    """Provide a fresh ROS domain id."""
    return next_domain_id()


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_sim_node_process_drives_and_stops_cleanly(domain, sig):
    """Start sim_node, drive it with cmd_vel from here, stop it: exit code 0, no traceback."""
    process = start_sim_process(domain)
    probe = RemoteProbe(domain, 'cli_probe')
    node, spin_until = probe.node, probe.spin_until
    try:
        joints, truth = [], []
        node.create_subscription(JointState, 'joint_states', joints.append, 10)
        node.create_subscription(Odometry, 'ground_truth', truth.append, 10)
        pub = node.create_publisher(Twist, 'cmd_vel', 10)
        assert spin_until(lambda: joints and truth, 20.0), 'no state from sim_node'
        assert 'left_front_wheel_joint' in joints[-1].name
        assert drive_forward_until(spin_until, pub, truth, 0.1, 10.0), 'robot did not move'
    finally:
        code, out, err = stop_process(process, sig)
        probe.close()
    assert code == 0, err
    assert 'Traceback' not in err + out


def test_parameters_without_ros_args_are_refused_not_ignored(domain):
    """A forgotten --ros-args would run on the defaults: one line naming it, exit 2."""
    process = start_sim_process(domain, command=[sys.executable, '-m', 'r2d2_sim', '-p',
                                                 'wheel_radius:=1e308'])
    out, err = process.communicate(timeout=30.0)
    assert process.returncode == 2 and 'Traceback' not in err
    lines = [line for line in err.splitlines() if 'error' in line]
    assert len(lines) == 1 and 'go after --ros-args' in lines[0], err


@pytest.mark.parametrize('args, fragment', [
    (['-p', 'physics_rate:=-5.0'], 'physics_rate must be in [10, 10000] Hz, got -5'),
    (['-p', 'physics_rate:=0.0'], 'physics_rate must be in [10, 10000] Hz, got 0'),
    (['-p', 'publish_rate:=-1.0'], 'publish_rate must be in [0.001, 10000] Hz (every step'),
    (['-p', 'publish_rate:=480.0'], 'cannot exceed physics_rate'),
    (['-p', 'camera_rate:=1000.0'], 'cannot exceed physics_rate'),
    (['-p', 'physics_rate:=50.0'], 'imu_rate (100.0 Hz, its default) cannot exceed physics_rate '
     '(50.0 Hz): set imu_rate to 50 Hz or less (0: off)'),
    (['-p', 'lidar3d_angle_min:=-1.5708'], 'must be in [-1.57079, 1.57079] rad, got -1.5708'),
    (['-p', 'real_time_factor:=-1.0'], 'real_time_factor must be in [1e-06, 1000] (as fast'),
    (['-p', 'real_time_factor:=1.0e-13'], 'real_time_factor must be in [1e-06, 1000]'),
    (['-p', 'cmd_vel_timeout:=fast'], 'cmd_vel_timeout must be a number'),
    (['-p', 'max_linear_acceleration:=-1.0'],
     'max_linear_acceleration must be in [0.001, 1000] m/s^2'),
    (['-p', 'urdf:=/nonexistent/robot.urdf'], 'not found'),
    (['-p', 'urdf:=/etc/hostname'], 'not well-formed XML'),
    (['-p', 'left_wheel_names:=[nope]'], 'wheel joint(s) nope not in the URDF'),
    (['-p', 'right_wheel_names:=[base_to_right_leg]'], 'base_to_right_leg is fixed'),
    (['-p', 'left_wheel_names:=[gripper_extension]'], 'gripper_extension is prismatic'),
    (['-p', 'left_wheel_names:=[]', '-p', 'right_wheel_names:=[]'],
     'list them as left and right wheels'),
    (['-p', 'right_wheel_names:=[]'], 'both be empty'),
    (['-p', 'initial_pose:=[1.0e5, 0.0, 0.0]'], 'off the ground plane'),
    (['-p', 'gravity:=[0.0]'], 'gravity must be a list of 3 numbers'),
    (['-p', 'wheel_radius:=1.0e308'], 'wheel_radius must be in [0.001, 10] m'),
    (['-p', 'wheel_radius:=1.0e-9'], 'wheel_radius must be in [0.001, 10] m'),
    (['-p', 'max_wheel_force:=1.0e308'], 'max_wheel_force must be in'),
    (['-p', 'wheel_separation:=1.0e6'], 'wheel_separation must be in'),
    (['-p', 'real_time_factor:=1.0e308'], 'real_time_factor must be in [1e-06, 1000]'),
    (['-p', 'odom_frame_id:=base_link'],
     "parameters odom_frame_id and base_frame_id both name the frame 'base_link'"),
    (['-p', 'footprint_frame_id:=base_link'], 'footprint_frame_id and base_frame_id'),
    (['-p', 'world_frame_id:=odom', '-p', 'publish_ground_truth_tf:=true'],
     'world_frame_id and odom_frame_id'),
    (['-p', 'frame_prefix:=/robot1/'], "frame_prefix must not start with '/'"),
    (['-p', 'base_frame_id:=base link'], 'base_frame_id must be a tf2 frame id'),
    (['-p', 'use_sim_time:=1'],
     'r2d2_sim: error: parameter use_sim_time must be true or false, got 1 (an integer)'),
    (['-p', 'start_type_description_service:=3'],
     'parameter start_type_description_service must be true or false, got 3 (an integer)'),
    (['-p', 'world_paths:=[/nonexistent/worlds]'],
     'parameter world_paths: /nonexistent/worlds is not a directory'),
    (['-p', 'model_paths:=[/etc/passwd]'],
     'parameter model_paths: /etc/passwd is not a directory'),
    (['--params-file', '/nonexistent/params.yaml'],
     '--params-file /nonexistent/params.yaml: no such file'),
])
def test_bad_parameter_is_one_line_and_nonzero_exit(domain, args, fragment):
    """A wrong parameter stops start-up with one readable line and exit code 2."""
    process = start_sim_process(domain, *args)
    try:
        out, err = process.communicate(timeout=30.0)
    finally:
        if process.poll() is None:  # it started instead: leave no simulator on the domain
            stop_process(process)
    code = process.returncode
    assert code == 2
    assert 'Traceback' not in err
    lines = [line for line in err.splitlines() if 'error' in line]
    assert len(lines) == 1 and fragment in lines[0], err


@pytest.mark.parametrize('domain_id, fragment', [
    ('300', 'ROS_DOMAIN_ID must be in 0..231, got 300'),
    ('one', "ROS_DOMAIN_ID must be an integer, got 'one'")])
def test_a_domain_id_ros_cannot_use_is_one_line_before_ros_starts(domain_id, fragment):
    """Fast DDS would end the process itself at domain 300, in lines of its own: checked first."""
    env = dict(ros_env(next_domain_id()), ROS_DOMAIN_ID=domain_id)
    result = subprocess.run(sim_node_command(), capture_output=True, text=True, timeout=60.0,
                            env=env)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [f'r2d2_sim: error: {fragment}']


@pytest.mark.parametrize('args', [
    ['--help'], ['-h'], ['--ros-args', '-p', 'physics_rate:=100.0', '--help']])
def test_help_prints_usage_and_parameters_and_exits_0(args):
    """Print the usage and the parameter table on stdout for --help (or -h), status 0."""
    result = subprocess.run([sys.executable, '-m', 'r2d2_sim'] + args, capture_output=True,
                            text=True, timeout=60.0, env=ros_env(next_domain_id()))
    assert result.returncode == 0 and result.stderr == '', result.stderr
    _check_help(result.stdout, 'python -m r2d2_sim')
