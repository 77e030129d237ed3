"""The harness's run watch: what a test of a stopper asks of a run, through the public API."""

import pytest

from r2d2_sim.model.regions import circle_region
from r2d2_sim.testing import box_urdf


@pytest.fixture
def r2d2_sim_parameters():
    """Commands hold; no acceleration limit, so times are distance over speed."""
    return {'cmd_vel_timeout': 0.0, 'max_linear_acceleration': 0.0}


def test_a_robot_that_does_not_stop_touches_the_wall(r2d2_sim):
    """0.3 m/s at a wall 1.115 m ahead: it touches after about 2 s; the goal is never reached."""
    r2d2_sim.spawn(box_urdf((0.2, 2.0, 1.0)), name='wall', position=(1.215, 0.0, 0.5))
    with r2d2_sim.watch(regions={'goal': circle_region(3.0, 0.0, 0.2)}) as run:
        r2d2_sim.send_cmd_vel(linear=0.3)
        r2d2_sim.advance(seconds=3.0)
    assert run.touched() == ['wall']
    assert run.contacts[0].start_ns / 1e9 == pytest.approx(2.0, abs=0.1)
    assert run.clearance.distance_m <= 0.0 and 'goal' not in run.reached


def test_a_robot_that_stops_in_time_keeps_its_clearance(r2d2_sim):
    """Stopped after 1 s at 0.3 m/s: about 0.3 m from the wall, no contact."""
    r2d2_sim.spawn(box_urdf((0.2, 2.0, 1.0)), name='wall', position=(1.215, 0.0, 0.5))
    with r2d2_sim.watch() as run:
        r2d2_sim.send_cmd_vel(linear=0.3)
        r2d2_sim.advance(seconds=1.0)
        r2d2_sim.send_cmd_vel(linear=0.0)
        r2d2_sim.advance(seconds=1.0)
    assert run.contacts == []
    assert run.clearance.other == 'wall'
    assert run.clearance.distance_m == pytest.approx(1.115 - 0.515 - 0.3, abs=0.03)
