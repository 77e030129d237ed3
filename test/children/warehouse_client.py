"""
A client written for other simulators: the shape of RobotecAI's warehouse example.

    python warehouse_client.py OUT_JSON [--prefix /gz_server] [--table URI] [--blue-cube URI]
        [--red-cube URI] [--cardboard URI] [--arm URI] [--robot-uri URI] [--robot-name NAME]
        [--world URI]

RobotecAI/simulation_interfaces_examples' ``warehouse_simulation_script.py``
drives Isaac Sim, O3DE and Gazebo with one script where only the service
prefix and the asset names change. This is its sequence, written the same
way (services by their standard names under the prefix, the flat ``req.uri``,
``spin_until_future_complete``, root ``/cmd_vel``): load a world if the
simulator can; spawn and delete a table; spawn the scene before playing;
play, pause; ResetSimulation(SCOPE_STATE) while paused, then SetEntityState
on two spawned cubes; StepSimulation(2) fifteen times; play, spawn obstacle
boxes, place the robot and drive it with ``/cmd_vel`` until it reaches its
target. Where the example sleeps, this waits for ``/clock`` (by deadline).
The UR10 joint moves are left out: they are not the standard's. Writes what
it saw to OUT_JSON; exit 0.
"""

import argparse
import json
import math
import time

from geometry_msgs.msg import Point, PoseStamped, Quaternion, Twist
import rclpy
from rosgraph_msgs.msg import Clock
from simulation_interfaces.msg import EntityState, Result, SimulationState, SimulatorFeatures
from simulation_interfaces.srv import (
    DeleteEntity, GetEntityState, GetSimulatorFeatures, LoadWorld, ResetSimulation,
    SetEntityState, SetSimulationState, SpawnEntity, StepSimulation, UnloadWorld)

DEADLINE_S = 60.0


def yaw_to_quaternion(yaw):
    """Return the Quaternion of a turn by ``yaw`` about z."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0))


class Warehouse:
    """The example's calls, each recorded as (what, ok)."""

    def __init__(self, node, prefix):
        self.node, self.prefix = node, prefix.rstrip('/')
        self.calls = []
        self.clock_ns = None
        node.create_subscription(Clock, '/clock', self._on_clock, 10)
        self.cmd_vel = node.create_publisher(Twist, '/cmd_vel', 10)

    def _on_clock(self, msg):
        self.clock_ns = msg.clock.sec * 10**9 + msg.clock.nanosec

    def call(self, srv_type, name, request, what):
        """Call ``<prefix>/<name>``, as the example does; record whether the result was OK."""
        client = self.node.create_client(srv_type, f'{self.prefix}/{name}')
        if not client.wait_for_service(timeout_sec=DEADLINE_S):
            raise RuntimeError(f'{self.prefix}/{name} is not there')
        future = client.call_async(request)
        rclpy.spin_until_future_complete(self.node, future, timeout_sec=DEADLINE_S)
        response = future.result()
        ok = response is not None and (not hasattr(response, 'result')
                                       or response.result.result == Result.RESULT_OK)
        self.calls.append((what, ok))
        self.node.destroy_client(client)
        return response

    def spawn(self, uri, name, pose):
        request = SpawnEntity.Request(name=name, uri=uri, allow_renaming=True)
        request.initial_pose = pose
        return self.call(SpawnEntity, 'spawn_entity', request, f'spawn {name}').entity_name

    def set_state(self, state):
        request = SetSimulationState.Request()
        request.state.state = state
        self.call(SetSimulationState, 'set_simulation_state', request, f'state {state}')

    def set_entity_state(self, name, pose):
        request = SetEntityState.Request(entity=name)
        state = EntityState()
        state.pose = pose.pose
        request.state = state
        self.call(SetEntityState, 'set_entity_state', request, f'place {name}')

    def entity_position(self, name):
        state = self.call(GetEntityState, 'get_entity_state',
                          GetEntityState.Request(entity=name), f'read {name}').state
        return state.pose.position

    def entity_stamp_ns(self, name):
        stamp = self.call(GetEntityState, 'get_entity_state',
                          GetEntityState.Request(entity=name), f'read {name}').state.header.stamp
        return stamp.sec * 10**9 + stamp.nanosec

    def wait_clock(self, advance_ns):
        """Let simulated time run ``advance_ns`` (the example sleeps here)."""
        deadline = time.monotonic() + DEADLINE_S
        while self.clock_ns is None and time.monotonic() < deadline:
            rclpy.spin_once(self.node, timeout_sec=0.05)
        start = self.clock_ns
        while self.clock_ns - start < advance_ns and time.monotonic() < deadline:
            rclpy.spin_once(self.node, timeout_sec=0.05)


def pose_stamped(x, y, z, yaw=0.0):
    """Return a PoseStamped in the world frame."""
    pose = PoseStamped()
    pose.pose.position = Point(x=float(x), y=float(y), z=float(z))
    pose.pose.orientation = yaw_to_quaternion(yaw)
    return pose


def main():
    """Run the sequence; write what it saw."""
    parser = argparse.ArgumentParser()
    parser.add_argument('out')
    parser.add_argument('--prefix', default='')
    parser.add_argument('--table', default='thor_table')
    parser.add_argument('--blue-cube', default='blue_block')
    parser.add_argument('--red-cube', default='red_block')
    parser.add_argument('--cardboard', default='cardboard_box')
    parser.add_argument('--arm', default='ur10')
    parser.add_argument('--robot-uri', default='dingo_d', help='empty: the robot is there')
    parser.add_argument('--robot-name', default='Dingo')
    parser.add_argument('--world', default='')
    args = parser.parse_args()
    rclpy.init()
    node = rclpy.create_node('simulation_interfaces_demo')
    w = Warehouse(node, args.prefix)
    seen = {}

    # 1. Features; 1.1 load the world if the simulator can.
    features = w.call(GetSimulatorFeatures, 'get_simulator_features',
                      GetSimulatorFeatures.Request(), 'features').features
    seen['features'] = list(features.features)
    loads_worlds = SimulatorFeatures.WORLD_LOADING in features.features and args.world
    if loads_worlds:
        w.call(LoadWorld, 'load_world', LoadWorld.Request(uri=args.world), 'load world')

    # 1.2 Spawn and delete a table.
    table = w.spawn(args.table, 'Table', pose_stamped(0.0, 0.0, 1.19))
    w.call(DeleteEntity, 'delete_entity', DeleteEntity.Request(entity=table), 'delete table')

    # 1.3 The scene: a table, the robot, an arm, seven cubes on the table, before playing.
    w.spawn(args.table, 'Table', pose_stamped(-1.0, -1.5, 1.19, 1.5708))
    if args.robot_uri:
        w.spawn(args.robot_uri, args.robot_name, pose_stamped(-4.0, -3.0, 0.0))
    w.spawn(args.arm, 'UR10', pose_stamped(-1.0, -2.14, 1.19, 1.5708))
    table = (-1.0, -1.5, 1.19)
    cubes = [((0.2, 0.2), 'blue'), ((-0.2, 0.2), 'red'), ((0.2, -0.2), 'red'),
             ((-0.2, -0.2), 'blue'), ((0.0, 0.0), 'blue'), ((0.1, 0.0), 'red'),
             ((-0.1, 0.0), 'red')]
    for i, ((dx, dy), color) in enumerate(cubes):
        uri = args.blue_cube if color == 'blue' else args.red_cube
        pose = pose_stamped(table[0] + dx, table[1] + dy, table[2] + 0.15)
        w.spawn(uri, f'{color}_cube_{i}', pose)
    cmd_vel = Twist()
    cmd_vel.linear.x = 1.0
    for _ in range(30):
        w.cmd_vel.publish(cmd_vel)

    # 2.1 Play, then pause.
    w.set_state(SimulationState.STATE_PLAYING)
    w.wait_clock(10**9)
    w.set_state(SimulationState.STATE_PAUSED)

    # 2.3 Reset the state while paused; lift two of the spawned cubes 30 cm.
    w.call(ResetSimulation, 'reset_simulation',
           ResetSimulation.Request(scope=ResetSimulation.Request.SCOPE_STATE), 'reset state')
    w.set_entity_state('blue_cube_0', pose_stamped(-0.8, -1.3, 1.59))
    w.set_entity_state('red_cube_1', pose_stamped(-1.2, -1.3, 1.59))
    lifted = (w.entity_position('blue_cube_0'), w.entity_position('red_cube_1'))
    seen['lifted'] = [[p.x, p.y, p.z] for p in lifted]

    # 2.2 Step 15 times 2 steps (the stamps of a state say how much time that was).
    before = w.entity_stamp_ns('blue_cube_0')
    for _ in range(15):
        w.call(StepSimulation, 'step_simulation', StepSimulation.Request(steps=2), 'step 2')
    seen['steps_stamps_ns'] = [before, w.entity_stamp_ns('blue_cube_0')]

    # 3. Play; obstacle boxes; place the robot and drive it to its target.
    w.set_state(SimulationState.STATE_PLAYING)
    for i, (x, y, yaw) in enumerate([(-2.5, -3.5, 0.0), (-0.5, -3.5, 1.5708),
                                     (-1.8, -3.3, 0.7854)]):
        w.spawn(args.cardboard, f'obstacle_box_0_{i}', pose_stamped(x, y, 0.0, yaw))
    w.set_entity_state(args.robot_name, pose_stamped(-4.0, -2.5, 0.0, 0.0))
    target = (-2.5, -2.5)
    cmd_vel.linear.x = 0.5
    reached, deadline = False, time.monotonic() + DEADLINE_S
    while not reached and time.monotonic() < deadline:
        position = w.entity_position(args.robot_name)
        if math.hypot(target[0] - position.x, target[1] - position.y) < 0.5:
            reached = True
        else:
            w.cmd_vel.publish(cmd_vel)
            rclpy.spin_once(node, timeout_sec=0.02)
    seen['robot_reached_target'] = reached
    seen['robot_at'] = [position.x, position.y, position.z]
    if loads_worlds:
        w.call(UnloadWorld, 'unload_world', UnloadWorld.Request(), 'unload world')
    seen['calls'] = w.calls
    with open(args.out, 'w', encoding='utf-8') as handle:
        json.dump(seen, handle)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == '__main__':
    main()
