"""
Harness features a user reaches for, across processes: stamped commands, remaps, gui, TF.

Each of these once failed for a new user of the public API (issue 21). The
same features in process are testing/test_harness_features.py's.
"""

import subprocess
import sys

import pytest

from helpers import REPO, wait_for
from r2d2_sim.client import ros_child_env


def test_stamped_cmd_vel_in_another_process(r2d2_sim_process):
    """In another process the harness publishes what the node subscribes: TwistStamped."""
    sim = r2d2_sim_process(enable_stamped_cmd_vel=True, start_paused=True, cmd_vel_timeout=0.0)
    sim.send_cmd_vel(linear=0.3)
    sim.step(240)
    assert sim.ground_truth().pose.pose.position.x > 0.1


@pytest.mark.parametrize('kwargs', [
    {'namespace': '/a', 'ros_args': ['-r', '/clock:=/a/clock']},
    {'ros_args': ['-r', '__ns:=/b', '-r', '/clock:=/b/clock']},
], ids=['namespace-and-clock-remap', 'namespace-in-ros-args'])
def test_sim_process_with_the_readmes_isolation_remaps(r2d2_sim_process, kwargs):
    """The README's two-simulators-on-one-domain remaps: SimProcess follows them."""
    sim = r2d2_sim_process(cmd_vel_timeout=0.0, **kwargs)
    namespace = kwargs.get('namespace', '/b')
    assert sim.node_path == f'{namespace}/r2d2_sim'
    assert wait_for(lambda: sim.status()['step'] > 0)  # running (its remapped /clock came)
    sim.send_cmd_vel(linear=0.3)
    assert sim.ground_truth().header.frame_id == 'world'


def test_gui_without_a_display_is_one_line_and_exit_2():
    """sim_node -p gui:=true without a display: one r2d2_sim: error line, status 2."""
    env = ros_child_env()
    env.pop('DISPLAY', None)
    result = subprocess.run([sys.executable, '-m', 'r2d2_sim', '--ros-args', '-p', 'gui:=true'],
                            env=env, cwd=REPO, capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('r2d2_sim: error: gui needs a display')


def test_lookup_transform_in_another_process(r2d2_sim_process):
    """Looked up across processes too: base_scan is 0.25 m above the ground."""
    sim = r2d2_sim_process()
    scan_in_odom = sim.lookup_transform('odom', 'base_scan')
    assert scan_in_odom.translation[2] == pytest.approx(0.25, abs=1e-6)
    assert sim.lookup_transform('base_link', 'imu_link').translation == (0.0, 0.0, 0.0)
