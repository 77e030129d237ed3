"""
cmd_vel_timeout through the whole node: the brake lands on the step the parameter says.

A command is taken before the first step after it arrives; with a timeout of T s
at 240 Hz the controller follows it for ceil(240 T) steps and brakes before the next.
"""

import pytest

from helpers import make_sim, Probe
from r2d2_sim.model.drive_controller import STOP


@pytest.mark.parametrize('timeout_s, steps', [(0.5, 120), (0.25, 60), (1.0 / 3.0, 80)])
def test_the_brake_lands_on_the_step_the_timeout_gives(ros, timeout_s, steps):
    """Followed for exactly ceil(240 * timeout) steps, then STOP (the ramp starts braking)."""
    sim = make_sim(ros, cmd_vel_timeout=timeout_s)
    probe = Probe(ros, sim)
    controller = sim.simulation.robot.controller
    probe.send(0.3)
    sim.advance(steps)
    assert controller.target != STOP and controller.target.linear_m_s == pytest.approx(0.3)
    sim.advance(1)
    assert controller.target == STOP


def test_a_new_command_restarts_the_timeout(ros):
    """Each command counts anew: 100 steps, a new command, 120 more steps, still driving."""
    sim = make_sim(ros, cmd_vel_timeout=0.5)
    probe = Probe(ros, sim)
    controller = sim.simulation.robot.controller
    probe.send(0.3)
    sim.advance(100)
    probe.send(0.2)
    sim.advance(120)
    assert controller.target.linear_m_s == pytest.approx(0.2)
    sim.advance(1)
    assert controller.target == STOP
