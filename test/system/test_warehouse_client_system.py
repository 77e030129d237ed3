"""
A client written for Isaac Sim, O3DE and Gazebo runs against sim_node, only its names changed.

``test/children/warehouse_client.py`` has the shape of RobotecAI's warehouse
example (docs/conformance.md shows it): spawn before playing, play, pause,
ResetSimulation(SCOPE_STATE) while paused, SetEntityState on spawned cubes,
StepSimulation(2) fifteen times, the flat ``uri``, the root ``/cmd_vel``.
Here it runs against ``sim_node`` with the prefix and the asset names of
r2d2_sim (pybullet_data's table, cubes and arm; the robot already there),
exactly as ``ASSETS`` in docs/conformance.md lists them.
"""

import json
import math
import subprocess
import sys

import pytest

from common import REPO, TEST_DIR
from r2d2_sim.client import ros_child_env

CLIENT = f'{TEST_DIR}/children/warehouse_client.py'
# What changes from one simulator to the next: the prefix and the asset names.
R2D2_SIM = ['--prefix', '', '--table', 'table/table.urdf', '--blue-cube', 'cube_small.urdf',
            '--red-cube', 'cube_small.urdf', '--cardboard', 'cube_small.urdf',
            '--arm', 'kuka_iiwa/model.urdf', '--robot-uri', '', '--robot-name', 'r2d2']


def test_the_warehouse_example_runs_against_sim_node(r2d2_sim_process, tmp_path):
    """Every call answers OK, the lifted cubes are where set, 15 x 2 steps are 30, it drives."""
    # Stopped at start, as Isaac Sim and O3DE start; four times real time to drive faster.
    sim = r2d2_sim_process(start_paused=True, real_time_factor=4.0)
    out = tmp_path / 'seen.json'
    result = subprocess.run([sys.executable, CLIENT, str(out)] + R2D2_SIM,
                            env=ros_child_env(sim.domain_id), cwd=REPO, capture_output=True,
                            text=True, timeout=240)
    assert result.returncode == 0, result.stderr[-3000:]
    seen = json.loads(out.read_text())
    failed = [what for what, ok in seen['calls'] if not ok]
    assert not failed, failed
    assert len(seen['calls']) > 40
    # The cubes spawned before the state reset are still there, and where they were set.
    assert seen['lifted'] == [[pytest.approx(-0.8, abs=1e-6), pytest.approx(-1.3, abs=1e-6),
                               pytest.approx(1.59, abs=1e-6)],
                              [pytest.approx(-1.2, abs=1e-6), pytest.approx(-1.3, abs=1e-6),
                               pytest.approx(1.59, abs=1e-6)]]
    before, after = seen['steps_stamps_ns']
    assert after - before == round(30 * 1e9 / 240)  # StepSimulation(2) x 15, 240 Hz physics
    assert seen['robot_reached_target'], seen['robot_at']
    assert math.hypot(seen['robot_at'][0] + 2.5, seen['robot_at'][1] + 2.5) < 0.5
