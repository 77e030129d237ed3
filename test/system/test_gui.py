"""
gui:=true opens PyBullet's window; tested on a virtual X display (Xvfb).

PyBullet allows one GUI connection per process, so the node runs in a
subprocess that reports what it saw as one JSON line.
"""

import json
import os
import select
import shutil
import subprocess
import sys

from helpers import next_domain_id, ros_env
import pytest

GUI_SCRIPT = r'''
import json, sys, threading, time
import rclpy
from rclpy.context import Context
from rclpy.parameter import Parameter
from r2d2_sim.ros.node import SimNode
from r2d2_sim.apps.sim_node import run_paced

STEPS = 240
ctx = Context()
rclpy.init(context=ctx, domain_id=int(sys.argv[1]))
node = SimNode(context=ctx, parameter_overrides=[
    Parameter('gui', value=True), Parameter('initial_pose', value=[0.5, 0.3, 0.0])])
stop = threading.Event()
advance = node.advance


def advance_then_stop(steps=1):
    advance(steps)
    if node.step_count >= STEPS:
        stop.set()


node.advance = advance_then_stop
start = time.monotonic()
run_paced(node, stop)
elapsed = time.monotonic() - start
camera_target = node.world.client.getDebugVisualizerCamera()[11]
report = {'gui': node.world.gui, 'steps': node.step_count, 'elapsed_s': elapsed,
          'camera_target': list(camera_target),
          'base': list(node.simulation.robot.body.base_state().position)}
node.destroy_node()
rclpy.try_shutdown(context=ctx)
print('REPORT ' + json.dumps(report))
'''


def _xvfb_binary():
    """Return the Xvfb path, installing Debian's xvfb if possible; None if unavailable."""
    found = shutil.which('Xvfb')
    if found or os.geteuid() != 0 or not shutil.which('apt-get'):
        return found
    env = dict(os.environ, DEBIAN_FRONTEND='noninteractive')
    for command in (['apt-get', 'update', '-qq'], ['apt-get', 'install', '-y', '-qq', 'xvfb']):
        try:
            subprocess.run(command, env=env, capture_output=True, timeout=300, check=False)
        except (OSError, subprocess.TimeoutExpired):
            return None
    return shutil.which('Xvfb')


@pytest.fixture
def display():
    """Start Xvfb on a free display number and return ':N'; stop it afterwards."""
    binary = _xvfb_binary()
    if binary is None:
        pytest.skip('Xvfb is not installed and cannot be installed here '
                    '(needs root and apt-get: Debian package xvfb)')
    # Xvfb picks a free display itself and writes its number down the pipe once it takes
    # connections (-displayfd): a socket file seen on disk could be a stale one, and the
    # display not ready ("cannot connect to X server", seen once in CI). It writes the
    # number again later (after its first client left, the node's check of the display:
    # with -noreset too, measured): to a closed pipe that is a fatal error ("Cannot write
    # display number to fd 4"), and the window then found no display, in about half the
    # runs. So the pipe stays open as long as the server.
    read_end, write_end = os.pipe()
    process = subprocess.Popen(
        [binary, '-displayfd', str(write_end), '-screen', '0', '800x600x24', '-nolisten', 'tcp'],
        pass_fds=(write_end,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write_end)
    try:
        ready, _, _ = select.select([read_end], [], [], 10.0)
        reported = os.read(read_end, 16).strip() if ready else b''
        if not reported.isdigit():
            raise AssertionError('Xvfb reported no display within 10 s')
        yield f':{int(reported)}'
    finally:
        process.terminate()
        try:
            process.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        os.close(read_end)


def test_gui_runs_paced_with_the_camera_following(display):
    """The node opens a window, steps 240 times paced, follows the robot, exits 0."""
    env = ros_env(next_domain_id())
    env['DISPLAY'] = display
    result = subprocess.run([sys.executable, '-c', GUI_SCRIPT, env['ROS_DOMAIN_ID']],
                            env=env, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr[-2000:]
    lines = [line for line in result.stdout.splitlines() if line.startswith('REPORT ')]
    assert lines, result.stdout[-2000:] + result.stderr[-2000:]
    report = json.loads(lines[-1][len('REPORT '):])
    assert report['gui'] is True
    assert report['steps'] >= 240
    # Paced at 240 Hz, 240 steps take 1 s (measured 1.0-1.3 s on 2 idle cores).
    # Xvfb renders on the CPU (llvmpipe), so a loaded machine only makes it
    # slower; never faster than real time is what shows the pacing works.
    assert report['elapsed_s'] > 0.95, report
    target, base = report['camera_target'], report['base']
    assert target[0] == pytest.approx(base[0], abs=0.05)
    assert target[1] == pytest.approx(base[1], abs=0.05)
