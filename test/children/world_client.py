"""
A client that knows only ROS 2's simulation standard: find a world, load it, use it, unload it.

    python world_client.py OUT_JSON

Against whatever simulator serves simulation_interfaces at the root of its
ROS domain (ROS_DOMAIN_ID): reads the features, lists the worlds tagged
``indoor`` and loads the first, finds its named poses (a goal, a spawn area
with bounds), stands the robot at the goal and a crate in the spawn area,
steps, checks with a box filter that the crate is in the area, then unloads
the world and sees the simulation inactive. Writes what it saw to OUT_JSON.
"""

import json
import math
import os
import sys
import time

from geometry_msgs.msg import Vector3
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from simulation_interfaces import msg, srv

CRATE = '''<robot name="crate"><link name="crate">
  <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>
  </inertial><collision><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
</link></robot>'''


class Client:
    """Services by name, each call waited for by deadline."""

    def __init__(self, node, executor):
        self.node, self.executor = node, executor

    def spin_until(self, condition, timeout_s=30.0):
        deadline = time.monotonic() + timeout_s
        while not condition():
            if time.monotonic() > deadline:
                raise TimeoutError('deadline passed')
            self.executor.spin_once(timeout_sec=0.05)

    def call(self, srv_type, name, request, ok=True):
        client = self.node.create_client(srv_type, name)
        self.spin_until(client.service_is_ready)
        future = client.call_async(request)
        self.spin_until(future.done)
        response = future.result()
        if ok and hasattr(response, 'result'):
            assert response.result.result == msg.Result.RESULT_OK, (name, response.result)
        return response

    def state(self):
        return self.call(srv.GetSimulationState, '/get_simulation_state',
                         srv.GetSimulationState.Request()).state.state


def main():
    """Run the sequence and write what was seen."""
    out = {}
    context = Context()
    rclpy.init(context=context, domain_id=int(os.environ['ROS_DOMAIN_ID']))
    node = rclpy.create_node('world_only_client', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    c = Client(node, executor)
    out['features'] = list(c.call(srv.GetSimulatorFeatures, '/get_simulator_features',
                                  srv.GetSimulatorFeatures.Request()).features.features)
    listing = srv.GetAvailableWorlds.Request()
    listing.filter.tags = ['indoor']
    worlds = c.call(srv.GetAvailableWorlds, '/get_available_worlds', listing).worlds
    out['worlds'] = [(w.name, w.world_resource.uri) for w in worlds]
    loaded = c.call(srv.LoadWorld, '/load_world',
                    srv.LoadWorld.Request(uri=worlds[0].world_resource.uri)).world
    out['loaded'] = loaded.name
    out['state_after_load'] = c.state()
    goals = srv.GetNamedPoses.Request()
    goals.tags.tags = ['goal']
    goal = c.call(srv.GetNamedPoses, '/get_named_poses', goals).poses[0]
    spawns = srv.GetNamedPoses.Request()
    spawns.tags.tags = ['spawn', 'area']
    spawns.tags.filter_mode = msg.TagsFilter.FILTER_MODE_ALL
    area = c.call(srv.GetNamedPoses, '/get_named_poses', spawns).poses[0]
    bounds = c.call(srv.GetNamedPoseBounds, '/get_named_pose_bounds',
                    srv.GetNamedPoseBounds.Request(name=area.name)).bounds
    out['area'] = [area.name, bounds.type, [[p.x, p.y, p.z] for p in bounds.points]]
    robot = next(name for name in c.call(srv.GetEntities, '/get_entities',
                                         srv.GetEntities.Request()).entities
                 if c.call(srv.GetEntityInfo, '/get_entity_info', srv.GetEntityInfo.Request(
                     entity=name)).info.category.category == msg.EntityCategory.CATEGORY_ROBOT)
    height = c.call(srv.GetEntityState, '/get_entity_state',
                    srv.GetEntityState.Request(entity=robot)).state.pose.position.z
    stand = srv.SetEntityState.Request(entity=robot)
    stand.state.pose = goal.pose
    stand.state.pose.position.z = height  # the goal is on the floor: the robot stands there
    c.call(srv.SetEntityState, '/set_entity_state', stand)
    crate = srv.SpawnEntity.Request(name='crate', resource_string=CRATE)
    crate.initial_pose.header.frame_id = area.name  # a named pose is a frame
    crate.initial_pose.pose.position.z = 0.3
    crate.initial_pose.pose.orientation.w = 1.0
    out['crate'] = c.call(srv.SpawnEntity, '/spawn_entity', crate).entity_name
    c.call(srv.StepSimulation, '/step_simulation', srv.StepSimulation.Request(steps=240))
    p = area.pose.position
    upper, lower = bounds.points  # relative to the area's pose (not turned)
    inside = srv.GetEntities.Request()
    inside.filters.bounds = msg.Bounds(type=msg.Bounds.TYPE_BOX, points=[
        Vector3(x=p.x + upper.x, y=p.y + upper.y, z=p.z + upper.z),
        Vector3(x=p.x + lower.x, y=p.y + lower.y, z=p.z + lower.z + 0.01)])  # off the floor
    out['in_area'] = list(c.call(srv.GetEntities, '/get_entities', inside).entities)
    at = c.call(srv.GetEntityState, '/get_entity_state',
                srv.GetEntityState.Request(entity=robot)).state.pose
    out['robot_at'] = [at.position.x, at.position.y,
                       2 * math.atan2(at.orientation.z, at.orientation.w)]
    out['goal'] = [goal.pose.position.x, goal.pose.position.y]
    c.call(srv.UnloadWorld, '/unload_world', srv.UnloadWorld.Request())
    out['state_after_unload'] = c.state()
    out['entities_after_unload'] = list(c.call(srv.GetEntities, '/get_entities',
                                               srv.GetEntities.Request()).entities)
    out['current_after_unload'] = c.call(srv.GetCurrentWorld, '/get_current_world',
                                         srv.GetCurrentWorld.Request(), ok=False).result.result
    out['step_after_unload'] = c.call(srv.StepSimulation, '/step_simulation',
                                      srv.StepSimulation.Request(steps=1), ok=False
                                      ).result.result
    with open(sys.argv[1], 'w') as stream:
        json.dump(out, stream)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    return 0


if __name__ == '__main__':
    sys.exit(main())
