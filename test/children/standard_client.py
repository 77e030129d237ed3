"""
A client that knows only ROS 2's simulation standard, not r2d2_sim: the issue's whole sequence.

    python standard_client.py OUT_JSON

Runs against whatever simulator serves simulation_interfaces at the root of
its ROS domain (ROS_DOMAIN_ID): features, pause, 240 steps (/clock must move
exactly 1 s), spawn a box ahead of the robot (the scan must see it),
teleport the robot, read every entity's state, reset with each scope,
delete the box, step again. Writes what it saw to OUT_JSON; exit 0.
"""

import json
import math
import os
import sys
import time

import rclpy
from rclpy.action import ActionClient
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from simulation_interfaces import msg, srv
from simulation_interfaces.action import SimulateSteps

BOX = '''<robot name="box"><link name="box">
  <inertial><mass value="5"/><inertia ixx="0.2" iyy="0.2" izz="0.1" ixy="0" ixz="0" iyz="0"/>
  </inertial>
  <visual><geometry><box size="0.3 0.3 0.6"/></geometry></visual>
  <collision><geometry><box size="0.3 0.3 0.6"/></geometry></collision>
</link></robot>'''


class Client:
    """Services by name, waited for by deadline; the latest /clock and scan."""

    def __init__(self, node, executor):
        self.node, self.executor = node, executor
        self.clock_ns, self.scan = None, None
        node.create_subscription(Clock, '/clock', self._on_clock, 100)
        node.create_subscription(LaserScan, 'scan', self._on_scan, 10)

    def _on_clock(self, message):
        self.clock_ns = message.clock.sec * 10**9 + message.clock.nanosec

    def _on_scan(self, message):
        self.scan = message

    def spin_until(self, condition, timeout_s=30.0):
        deadline = time.monotonic() + timeout_s
        while not condition():
            if time.monotonic() > deadline:
                raise TimeoutError('deadline passed')
            self.executor.spin_once(timeout_sec=0.05)

    def now_ns(self, entity):
        """Return the simulated time, from the stamp of an entity's state."""
        stamp = self.call(srv.GetEntityState, '/get_entity_state',
                          srv.GetEntityState.Request(entity=entity)).state.header.stamp
        return stamp.sec * 10**9 + stamp.nanosec

    def call(self, srv_type, name, request, ok=True):
        client = self.node.create_client(srv_type, name)
        self.spin_until(client.service_is_ready)
        future = client.call_async(request)
        self.spin_until(future.done)
        response = future.result()
        if ok and hasattr(response, 'result'):
            assert response.result.result == msg.Result.RESULT_OK, (name, response.result)
        return response


def main():
    """Run the sequence and write what was seen."""
    out = {}
    context = Context()
    rclpy.init(context=context, domain_id=int(os.environ['ROS_DOMAIN_ID']))
    node = rclpy.create_node('standard_only_client', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    c = Client(node, executor)
    features = c.call(srv.GetSimulatorFeatures, '/get_simulator_features',
                      srv.GetSimulatorFeatures.Request()).features
    out['features'] = list(features.features)
    out['custom_info'] = json.loads(features.custom_info)
    c.call(srv.SetSimulationState, '/set_simulation_state',
           srv.SetSimulationState.Request(state=msg.SimulationState(
               state=msg.SimulationState.STATE_PAUSED)))
    entities = list(c.call(srv.GetEntities, '/get_entities', srv.GetEntities.Request()).entities)
    # Simulated time now: an entity state's stamp (/clock messages may still be on their way).
    before = c.now_ns(entities[0])
    c.call(srv.StepSimulation, '/step_simulation', srv.StepSimulation.Request(steps=240))
    c.spin_until(lambda: c.clock_ns == before + 10**9)  # /clock: exactly one second on
    out['clock_advance_ns'] = c.clock_ns - before
    robot = next(name for name in entities if c.call(
        srv.GetEntityInfo, '/get_entity_info', srv.GetEntityInfo.Request(entity=name)
    ).info.category.category == msg.EntityCategory.CATEGORY_ROBOT)
    out['robot'], out['entities_at_start'] = robot, entities
    spawn = srv.SpawnEntity.Request(name='box', resource_string=BOX)
    spawn.initial_pose.pose.position.x, spawn.initial_pose.pose.position.z = 1.5, 0.3
    spawn.initial_pose.pose.orientation.w = 1.0
    out['box'] = c.call(srv.SpawnEntity, '/spawn_entity', spawn).entity_name
    stepped = c.clock_ns
    c.call(srv.StepSimulation, '/step_simulation', srv.StepSimulation.Request(steps=48))
    c.spin_until(lambda: c.scan is not None and c.scan.header.stamp.sec * 10**9
                 + c.scan.header.stamp.nanosec > stepped)
    ahead = round((0.0 - c.scan.angle_min) / c.scan.angle_increment)
    out['scan_ahead_m'] = c.scan.ranges[ahead]
    teleport = srv.SetEntityState.Request(entity=robot)
    teleport.state.pose.position.x, teleport.state.pose.position.z = -1.0, 0.471
    teleport.state.pose.orientation.z = math.sin(math.pi / 4)
    teleport.state.pose.orientation.w = math.cos(math.pi / 4)
    c.call(srv.SetEntityState, '/set_entity_state', teleport)
    c.call(srv.StepSimulation, '/step_simulation', srv.StepSimulation.Request(steps=24))
    states = c.call(srv.GetEntitiesStates, '/get_entities_states',
                    srv.GetEntitiesStates.Request())
    out['states'] = {name: [s.pose.position.x, s.pose.position.y, s.pose.position.z,
                            s.header.frame_id]
                     for name, s in zip(states.entities, states.states)}
    out['resets'] = {}
    for scope_name in ('SCOPE_TIME', 'SCOPE_STATE', 'SCOPE_SPAWNED'):
        scope = getattr(srv.ResetSimulation.Request, scope_name)
        c.call(srv.ResetSimulation, '/reset_simulation', srv.ResetSimulation.Request(scope=scope))
        c.call(srv.StepSimulation, '/step_simulation', srv.StepSimulation.Request(steps=1))
        names = list(c.call(srv.GetEntities, '/get_entities', srv.GetEntities.Request()).entities)
        robot_x = c.call(srv.GetEntityState, '/get_entity_state', srv.GetEntityState.Request(
            entity=robot)).state.pose.position.x
        c.spin_until(lambda: c.clock_ns is not None)
        out['resets'][scope_name] = {'entities': names, 'robot_x': robot_x,
                                     'clock_ns': c.clock_ns}
    again = c.call(srv.SpawnEntity, '/spawn_entity', spawn).entity_name
    c.call(srv.DeleteEntity, '/delete_entity', srv.DeleteEntity.Request(entity=again))
    out['after_delete'] = list(c.call(srv.GetEntities, '/get_entities',
                                      srv.GetEntities.Request()).entities)
    steps = ActionClient(node, SimulateSteps, '/simulate_steps')
    c.spin_until(steps.server_is_ready)
    feedback = []
    before_ns = c.clock_ns
    goal = steps.send_goal_async(SimulateSteps.Goal(steps=12),
                                 feedback_callback=lambda f: feedback.append(
                                     f.feedback.completed_steps))
    c.spin_until(goal.done)
    result = goal.result().get_result_async()
    c.spin_until(result.done)
    c.spin_until(lambda: c.clock_ns >= before_ns + 12 * 10**9 // 240)  # 12 steps: 50 ms
    out['action'] = {'status': result.result().status,
                     'result': result.result().result.result.result, 'feedback': feedback,
                     'clock_advance_ns': c.clock_ns - before_ns}
    state = c.call(srv.GetSimulationState, '/get_simulation_state',
                   srv.GetSimulationState.Request()).state.state
    out['final_state'] = state
    with open(sys.argv[1], 'w') as stream:
        json.dump(out, stream)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    return 0


if __name__ == '__main__':
    sys.exit(main())
