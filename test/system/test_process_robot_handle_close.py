"""
A SimProcess robot's handle leaves nothing on the probe's node when its robot is deleted.

Issue 39: 300 spawn/delete cycles of a robot in a namespace through
``SimProcess`` grew ``sim_node`` by about 44 kB a cycle, slowed each cycle
and then lost replies. The handle's TF listener (``/tf`` and ``/tf_static``,
``tf_layout`` shared) outlived the robot: the harness's node kept two more
subscriptions a cycle, each of which the simulator's own ``/tf`` writers
served (tracked the reader, sent it every message), for good.
"""

import pytest

from r2d2_sim.ros.standard.server import available

URDF = 'package://r2d2_sim/urdf/r2d2.urdf'


def topics_subscribed(node):
    """Return the sorted topic names of ``node``'s own subscriptions."""
    return sorted(subscription.topic_name for subscription in node.subscriptions)


@pytest.mark.skipif(not available(), reason='simulation_interfaces is needed')
def test_a_process_robot_handle_takes_its_subscriptions_along(r2d2_sim_process):
    """Spawn /c (its handle listens to TF), delete it: the probe's subscriptions are as before."""
    sim = r2d2_sim_process(start_paused=True)
    before = topics_subscribed(sim.probe.node)
    sim.spawn(URDF, name='c', namespace='/c', position=(0.0, 2.0, 0.48))
    assert sim.robot('c')._tf is not None  # listening from the spawn on
    sim.delete_entity('c')
    assert topics_subscribed(sim.probe.node) == before
