"""
Several robots in one world, across processes: a third spawned through the standard.

Robot a stands at the origin facing +x, robot b 2 m ahead facing it (``FACING``,
in helpers.py); the same world in process is ros/test_fleet.py's.
"""

from helpers import FACING, needs_standard, x_of
import pytest

from r2d2_sim.testing import RefusedError
from r2d2_sim.testing.tf import TF_STATIC_QOS


@needs_standard
def test_a_third_robot_spawned_through_the_standard_drives_and_leaves_nothing(
        r2d2_sim_process):
    """Across processes: spawn_entity with a namespace, drive, delete: topics, TF, body gone."""
    from tf2_msgs.msg import TFMessage
    sim = r2d2_sim_process(robots=FACING, start_paused=True, publish_rate=20.0,
                           cmd_vel_timeout=0.0)
    assert sim.robot_names == ['a', 'b']
    name = sim.spawn('package://r2d2_sim/urdf/r2d2.urdf', name='c', namespace='/c',
                     position=(0.0, 2.0, 0.48))
    assert name == 'c' and sim.robot_names == ['a', 'b', 'c']
    with pytest.raises(RefusedError) as raised:  # refused in one line; the simulator runs on
        sim.spawn('package://r2d2_sim/urdf/r2d2.urdf', name='d', namespace='/' + 'd' * 300,
                  position=(0.0, 4.0, 0.48))
    assert raised.value.code == 'NAMESPACE_INVALID' and not sim.process.exited()
    c = sim.robot('c')
    c.send_cmd_vel(linear=0.3)
    sim.step(20)  # 1 s
    assert x_of(c.ground_truth()) > 0.2 and x_of(c.odom()) > 0.2
    assert abs(x_of(sim.robot('a').ground_truth())) < 0.01
    assert sim.joint_info('c')['urdf'] == 'package://r2d2_sim/urdf/r2d2.urdf'
    frames = set()
    sim.probe.node.create_subscription(
        TFMessage, '/tf', lambda msg: frames.update(t.child_frame_id for t in msg.transforms), 100)
    sim.step(2)
    assert 'c/base_footprint' in frames
    sim.delete_entity('c')
    assert sim.entities() == ['ground_plane', 'a', 'b'] and sim.robot_names == ['a', 'b']
    node = sim.probe.node
    assert sim.probe.spin_until(lambda: not [
        t for t, _ in node.get_topic_names_and_types()
        if t.startswith('/c/') and node.count_publishers(t)], 10.0)
    assert '/c' not in [ns for _, ns in node.get_node_names_and_namespaces()]
    frames.clear()
    sim.step(2)
    assert frames and not [f for f in frames if f.startswith('c/')]
    late = set()
    node.create_subscription(
        TFMessage, '/tf_static', lambda msg: late.update(t.child_frame_id for t in msg.transforms),
        TF_STATIC_QOS)
    assert sim.probe.spin_until(lambda: 'a/base_link' in late and 'b/base_link' in late, 10.0)
    assert not [f for f in late if f.startswith('c/')]
