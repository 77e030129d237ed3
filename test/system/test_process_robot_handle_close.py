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
    assert '/c/odom' in topics_subscribed(sim.probe.node)  # its handle listens
    sim.delete_entity('c')
    assert topics_subscribed(sim.probe.node) == before


@pytest.mark.skipif(not available(), reason='simulation_interfaces is needed')
@pytest.mark.parametrize('layout, odom, base', [('shared', 'c/odom', 'c/base_link'),
                                                ('namespaced', 'odom', 'base_link')])
def test_a_process_robot_handle_looks_its_tf_up_then_lets_go(r2d2_sim_process, layout, odom,
                                                             base):
    """A spawned robot's lookup_transform works in both layouts; its delete leaves nothing."""
    pytest.importorskip('tf2_msgs.msg')
    sim = r2d2_sim_process(start_paused=True, tf_layout=layout)
    before = topics_subscribed(sim.probe.node)
    sim.spawn(URDF, name='c', namespace='/c', position=(0.0, 2.0, 0.48))
    # The handle returned once the robot's TF writers matched its reader: a step now is heard.
    assert sim.readers()['/tf' if layout == 'shared' else '/c/tf'] >= 1
    sim.step()
    transform = sim.robot('c').lookup_transform(odom, base)
    assert transform.transform.translation[1] == pytest.approx(2.0, abs=0.01)
    sim.delete_entity('c')
    assert topics_subscribed(sim.probe.node) == before
