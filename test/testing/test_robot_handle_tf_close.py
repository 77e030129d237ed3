"""
A SimHarness robot's handle leaves nothing on the harness's node when its robot is deleted.

Issue 39: the handle's TF listener, started by its first ``lookup_transform``,
outlived the robot: two subscriptions on ``/tf`` and ``/tf_static`` a
spawn/delete cycle, for good (``test/system/test_process_robot_handle_close.py`` has
the process harness's side and the numbers).
"""

import pytest

URDF = 'package://r2d2_sim/urdf/r2d2.urdf'


def topics_subscribed(node):
    """Return the sorted topic names of ``node``'s own subscriptions."""
    return sorted(subscription.topic_name for subscription in node.subscriptions)


def test_a_harness_robot_handle_takes_its_subscriptions_along(r2d2_sim_factory):
    """Spawn /c, look its TF up (its handle listens), delete it: the subscriptions as before."""
    pytest.importorskip('tf2_msgs.msg')
    sim = r2d2_sim_factory()
    before = topics_subscribed(sim._link)
    sim.spawn(URDF, name='c', namespace='/c', position=(0.0, 2.0, 0.48))
    sim.advance()
    sim.robot('c').lookup_transform('c/odom', 'c/base_link')
    sim.delete_entity('c')
    assert topics_subscribed(sim._link) == before
