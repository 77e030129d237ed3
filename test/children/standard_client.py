"""
A client that knows only ROS 2's simulation standard, not r2d2_sim: the issue's whole sequence.

    python standard_client.py OUT_JSON

Runs against whatever simulator serves simulation_interfaces at the root of
its ROS domain (ROS_DOMAIN_ID): features, pause, 240 steps (/clock must move
exactly 1 s), spawn a box ahead of the robot (the scan must see it),
teleport the robot, read every entity's state, reset with each scope,
delete the box, step again. Writes what it saw to OUT_JSON; exit 0. Its calls
go through :class:`~r2d2_sim.testing.StandardClient`, the package's client of
the standard, which knows the standard's names and nothing of r2d2_sim.
"""

import json
import math
import os
import sys

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from simulation_interfaces import msg, srv

from r2d2_sim.client import spin_until
from r2d2_sim.testing import StandardClient

BOX = '''<robot name="box"><link name="box">
  <inertial><mass value="5"/><inertia ixx="0.2" iyy="0.2" izz="0.1" ixy="0" ixz="0" iyz="0"/>
  </inertial>
  <visual><geometry><box size="0.3 0.3 0.6"/></geometry></visual>
  <collision><geometry><box size="0.3 0.3 0.6"/></geometry></collision>
</link></robot>'''
DEADLINE_S = 30.0


class Seen:
    """The latest /clock and scan."""

    def __init__(self, node):
        self.clock_ns, self.scan = None, None
        node.create_subscription(Clock, '/clock', self._on_clock, 100)
        node.create_subscription(LaserScan, 'scan', self._on_scan, 10)

    def _on_clock(self, message):
        self.clock_ns = message.clock.sec * 10**9 + message.clock.nanosec

    def _on_scan(self, message):
        self.scan = message


def main():
    """Run the sequence and write what was seen."""
    out = {}
    context = Context()
    rclpy.init(context=context, domain_id=int(os.environ['ROS_DOMAIN_ID']))
    node = rclpy.create_node('standard_only_client', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    seen = Seen(node)

    def wait(condition, timeout_s=DEADLINE_S):
        return spin_until(executor, condition, timeout_s)

    def until(condition):
        if not wait(condition):
            raise TimeoutError('deadline passed')

    # The standard's services by their usual names at the root: any simulator's.
    c = StandardClient(node, wait, timeout_s=DEADLINE_S)
    features = c.call('get_simulator_features', srv.GetSimulatorFeatures.Request()).features
    out['features'] = list(features.features)
    out['custom_info'] = json.loads(features.custom_info)
    c.set_state(msg.SimulationState.STATE_PAUSED)
    entities = c.entities()

    def now_ns(entity):
        """Return the simulated time, from the stamp of an entity's state."""
        stamp = c.entity_state(entity).header.stamp
        return stamp.sec * 10**9 + stamp.nanosec
    # Simulated time now: an entity state's stamp (/clock messages may still be on their way).
    before = now_ns(entities[0])
    c.step(240)
    until(lambda: seen.clock_ns == before + 10**9)  # /clock: exactly one second on
    out['clock_advance_ns'] = seen.clock_ns - before
    robot = next(name for name in entities
                 if c.entity_info(name).category.category == msg.EntityCategory.CATEGORY_ROBOT)
    out['robot'], out['entities_at_start'] = robot, entities
    out['box'] = c.spawn(resource_string=BOX, name='box', position=(1.5, 0.0, 0.3),
                         allow_renaming=False)
    stepped = seen.clock_ns
    c.step(48)
    until(lambda: seen.scan is not None and seen.scan.header.stamp.sec * 10**9
          + seen.scan.header.stamp.nanosec > stepped)
    scan = seen.scan
    ahead = round((0.0 - scan.angle_min) / scan.angle_increment)
    out['scan_ahead_m'] = scan.ranges[ahead]
    c.set_entity_state(robot, (-1.0, 0.0, 0.471),
                       (0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)))
    c.step(24)
    states = c.call('get_entities_states', srv.GetEntitiesStates.Request())
    out['states'] = {name: [s.pose.position.x, s.pose.position.y, s.pose.position.z,
                            s.header.frame_id]
                     for name, s in zip(states.entities, states.states)}
    out['resets'] = {}
    for scope_name in ('SCOPE_TIME', 'SCOPE_STATE', 'SCOPE_SPAWNED'):
        c.reset(getattr(srv.ResetSimulation.Request, scope_name))
        c.step(1)
        names = c.entities()
        robot_x = c.entity_state(robot).pose.position.x
        until(lambda: seen.clock_ns is not None)
        out['resets'][scope_name] = {'entities': names, 'robot_x': robot_x,
                                     'clock_ns': seen.clock_ns}
    again = c.spawn(resource_string=BOX, name='box', position=(1.5, 0.0, 0.3),
                    allow_renaming=False)
    c.delete(again)
    out['after_delete'] = c.entities()
    feedback = []
    before_ns = seen.clock_ns
    status, result = c.simulate_steps(
        12, feedback=lambda f: feedback.append(f.feedback.completed_steps))
    until(lambda: seen.clock_ns >= before_ns + 12 * 10**9 // 240)  # 12 steps: 50 ms
    out['action'] = {'status': status, 'result': result.result.result, 'feedback': feedback,
                     'clock_advance_ns': seen.clock_ns - before_ns}
    out['final_state'] = c.state()
    with open(sys.argv[1], 'w') as stream:
        json.dump(out, stream)
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    return 0


if __name__ == '__main__':
    sys.exit(main())
