"""
SimProcess's readers when someone else moves the simulator, and TF from the first lookup.

A paused simulator stepped by another client (here the standard's
``step_simulation``, as a second tool would) has published newer states than
this harness's last reply: the readers ask the node for its latest
publication each time instead of waiting for an old one. The TF listener runs
from the harness's start, so a first lookup after a step already finds it.
"""

import pytest

from r2d2_sim.client import stamp_ns
from r2d2_sim.model.timing import NS_PER_S
from r2d2_sim.ros.standard.server import available

needs_standard = pytest.mark.skipif(not available(), reason='simulation_interfaces is needed')


@needs_standard
def test_readers_follow_steps_another_client_took(r2d2_sim_process):
    """step() by the harness, then 48 physics steps by the standard: the readers see t=0.25 s."""
    sim = r2d2_sim_process(start_paused=True, timeout_s=10.0)
    sim.step()  # one control period: t = 1/240 s, what the harness's last reply says
    sim.standard.step(59)  # another client: t = 60/240 s, published on each step
    assert stamp_ns(sim.ground_truth().header.stamp) == NS_PER_S // 4
    assert stamp_ns(sim.odom().header.stamp) == NS_PER_S // 4
    assert stamp_ns(sim.robot().joint_states().header.stamp) == NS_PER_S // 4


def test_the_first_lookup_finds_what_was_published_before_it(r2d2_sim_process):
    """Paused, stepped once, then the first lookup_transform: odom -> base_link is there."""
    sim = r2d2_sim_process(start_paused=True, timeout_s=10.0)
    sim.send_cmd_vel(linear=0.3)
    sim.step(24)
    transform = sim.lookup_transform('odom', 'base_link')
    truth = sim.ground_truth().pose.pose.position
    assert transform.stamp_ns == sim.status()['published_ns']
    assert transform.transform.translation[0] == pytest.approx(truth.x, abs=0.02)
