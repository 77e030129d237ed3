"""
A fixed suite of closed-loop scenario tests, for bench/lockstep.py's scaling rows.

Sixteen scenarios of the kind a user's suite holds: the README's 20 Hz
P-controller (test/examples/test_closed_loop.py) driving to goals at four
distances and four publish rates, 5 simulated seconds each, in lockstep.
Run with ``pytest -n 1`` and ``-n 2`` by the bench; not part of the test suite.
"""

import importlib.util
import os

import pytest

pytest_plugins = ['r2d2_sim.pytest_plugin']

_EXAMPLE = os.path.join(os.path.dirname(__file__), '..', '..', 'test', 'examples',
                        'test_closed_loop.py')
_spec = importlib.util.spec_from_file_location('closed_loop_example', _EXAMPLE)
_example = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_example)


@pytest.mark.parametrize('publish_rate', [0.0, 120.0, 60.0, 50.0])
@pytest.mark.parametrize('goal_m', [0.5, 1.0, 1.5, 2.0])
def test_drive_to_goal(r2d2_sim_factory, goal_m, publish_rate):
    """The P-controller reaches its goal within 5 simulated seconds."""
    sim = r2d2_sim_factory(cmd_vel_timeout=0.0, publish_rate=publish_rate)
    sim.add_node(_example.DriveToX(goal_m=goal_m, context=sim.context))
    sim.advance(seconds=5.0)
    assert sim.ground_truth().pose.pose.position.x == pytest.approx(goal_m, abs=0.05)
