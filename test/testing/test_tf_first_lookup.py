"""The in-process harness's first lookup_transform, after time has moved: the current state."""

import importlib.util

import pytest


@pytest.mark.skipif(importlib.util.find_spec('tf2_msgs') is None, reason='tf2_msgs is needed')
@pytest.mark.parametrize('robots', [None, {'a': {}}], ids=['one robot', 'a listed robot'])
def test_the_first_lookup_after_advancing_finds_the_current_transform(r2d2_sim_factory, robots):
    """Driven for 1 s, no listen_tf() before: odom -> base_link is the latest publication's."""
    harness = r2d2_sim_factory(cmd_vel_timeout=0.0, **({'robots': robots} if robots else {}))
    robot = harness.robot()
    robot.send_cmd_vel(linear=0.3)
    harness.advance(seconds=1.0)
    prefix = 'a/' if robots else ''
    transform = robot.lookup_transform(prefix + 'odom', prefix + 'base_link')
    assert transform.stamp_ns == harness.last_publication_ns()
    odom = robot.odom().pose.pose.position
    assert transform.transform.translation[0] == pytest.approx(odom.x, abs=1e-6)
    assert odom.x > 0.2
