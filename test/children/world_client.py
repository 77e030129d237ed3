"""
A client that knows only ROS 2's simulation standard: find a world, load it, use it, unload it.

    python world_client.py OUT_JSON

Against whatever simulator serves simulation_interfaces at the root of its
ROS domain (ROS_DOMAIN_ID): reads the features, lists the worlds tagged
``indoor`` and loads the first, finds its named poses (a goal, a spawn area
with bounds), stands the robot at the goal and a crate in the spawn area,
steps, checks with a box filter that the crate is in the area, then unloads
the world and sees the simulation inactive. Writes what it saw to OUT_JSON.
Its calls go through :class:`~r2d2_sim.testing.StandardClient`, the
package's client of the standard.
"""

import json
import math
import os
import sys

from geometry_msgs.msg import Vector3
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from simulation_interfaces import msg, srv

from r2d2_sim.client import spin_until
from r2d2_sim.testing import StandardClient

CRATE = '''<robot name="crate"><link name="crate">
  <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>
  </inertial><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
</link></robot>'''
DEADLINE_S = 30.0


def main():
    """Run the sequence and write what was seen."""
    out = {}
    context = Context()
    rclpy.init(context=context, domain_id=int(os.environ['ROS_DOMAIN_ID']))
    node = rclpy.create_node('world_only_client', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)

    def wait(condition, timeout_s):
        return spin_until(executor, condition, timeout_s)
    # The standard's services by their usual names at the root: any simulator's.
    c = StandardClient(node, wait, timeout_s=DEADLINE_S)
    out['features'] = c.features()
    worlds = c.available_worlds(tags=['indoor'])
    out['worlds'] = [(w.name, w.world_resource.uri) for w in worlds]
    out['loaded'] = c.load_world(uri=worlds[0].world_resource.uri).world.name
    out['state_after_load'] = c.state()
    goal = c.named_poses(tags=['goal'])[0]
    area = c.named_poses(tags=['spawn', 'area'], match_all=True)[0]
    bounds = c.named_pose_bounds(area.name)
    out['area'] = [area.name, bounds.type, [[p.x, p.y, p.z] for p in bounds.points]]
    robot = next(name for name in c.entities()
                 if c.entity_info(name).category.category == msg.EntityCategory.CATEGORY_ROBOT)
    height = c.entity_state(robot).pose.position.z
    g = goal.pose  # the goal is on the floor: the robot stands there
    c.set_entity_state(robot, (g.position.x, g.position.y, height),
                       (g.orientation.x, g.orientation.y, g.orientation.z, g.orientation.w))
    # A named pose is a frame: the crate 0.3 m above the spawn area's.
    out['crate'] = c.spawn(resource_string=CRATE, name='crate', position=(0.0, 0.0, 0.3),
                           allow_renaming=False, frame_id=area.name)
    c.step(240)
    p = area.pose.position
    upper, lower = bounds.points  # relative to the area's pose (not turned)
    inside = msg.Bounds(type=msg.Bounds.TYPE_BOX, points=[
        Vector3(x=p.x + upper.x, y=p.y + upper.y, z=p.z + upper.z),
        Vector3(x=p.x + lower.x, y=p.y + lower.y, z=p.z + lower.z + 0.01)])  # off the floor
    out['in_area'] = c.entities(bounds=inside)
    at = c.entity_state(robot).pose
    out['robot_at'] = [at.position.x, at.position.y,
                       2 * math.atan2(at.orientation.z, at.orientation.w)]
    out['goal'] = [goal.pose.position.x, goal.pose.position.y]
    c.unload_world()
    out['state_after_unload'] = c.state()
    out['entities_after_unload'] = c.entities()
    out['current_after_unload'] = c.call('get_current_world', srv.GetCurrentWorld.Request(),
                                         check=False).result.result
    out['step_after_unload'] = c.call('step_simulation', srv.StepSimulation.Request(steps=1),
                                      check=False).result.result
    with open(sys.argv[1], 'w') as stream:
        json.dump(out, stream)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    return 0


if __name__ == '__main__':
    sys.exit(main())
