"""
A robot spawned in a namespace and deleted again leaves nothing behind: not in ROS, not here.

Issue 30, U3-2: spawn/delete cycles grew the simulator by about 130 kB each and
made every delete slower. The cause was rclpy 7.1's ``~/get_type_description``
service, which ``Node.destroy_node`` never finalizes: each deleted robot's node
left that service's DDS reader and writer in the process, and in the graph, for
good. Robot nodes no longer start it (docs/limits.md has the numbers).
"""

import gc
import weakref

from r2d2_sim.testing import wait_for

URDF = 'package://r2d2_sim/urdf/r2d2.urdf'


def spawn_c(sim):
    """Spawn our R2D2 as robot c in namespace /c beside the default robot; return its name."""
    name = sim.spawn(URDF, name='c', namespace='/c', position=(0.0, 2.0, 0.48))
    sim.advance()  # one control period: c publishes
    return name


def endpoints_under(sim, prefix):
    """Return the services, and the topics with a publisher or subscriber, named under prefix."""
    link = sim._link
    services = [name for name, _ in link.get_service_names_and_types()
                if name.startswith(prefix)]
    topics = [name for name, _ in link.get_topic_names_and_types()
              if name.startswith(prefix)
              and (link.count_publishers(name) or link.count_subscribers(name))]
    return services + topics


def test_a_deleted_robot_leaves_no_service_or_topic_in_the_graph(r2d2_sim_factory):
    """Every endpoint of /c goes with c, ~/get_type_description included (rclpy kept it)."""
    sim = r2d2_sim_factory()
    spawn_c(sim)
    assert wait_for(lambda: '/c/r2d2_sim/get_joint_info' in endpoints_under(sim, '/c/'), 10.0)
    sim.delete_entity('c')
    # The graph forgets endpoints asynchronously: wait for it by deadline.
    assert wait_for(lambda: not endpoints_under(sim, '/c/'), 10.0), endpoints_under(sim, '/c/')


def test_a_deleted_robot_leaves_no_object_and_no_bookkeeping(r2d2_sim_factory):
    """After delete, c's node, interfaces and robot are collected; every list is as before."""
    sim = r2d2_sim_factory()
    node = sim.sim

    def sizes():
        return (len(node.fleet), len(node.fleet._watchers), len(sim.executor.get_nodes()),
                len(sim.nodes), len(node.simulation.robots), len(node.world.bodies),
                len(node.world._free_ray_groups), sim.robot_names)
    before = sizes()
    spawn_c(sim)
    interfaces = node.robot('c')
    alive = [weakref.ref(thing) for thing in (interfaces, interfaces.node, interfaces.robot,
                                              interfaces.outputs, interfaces.cmd_vel)]
    assert sizes() != before
    del interfaces
    sim.delete_entity('c')

    def survivors():
        gc.collect()
        return [type(ref()).__name__ for ref in alive if ref() is not None]
    # The spinning thread may still hold the node in the wait it was in: by deadline.
    wait_for(lambda: not survivors(), 10.0, interval_s=0.05)
    assert survivors() == []
    assert sizes() == before
