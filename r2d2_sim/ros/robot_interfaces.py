"""
One robot's ROS side: ``cmd_vel`` in, its outputs, ``robot_description``, joint info.

Every robot in the world has the same interfaces, in its own namespace: the
one robot of a default simulator on the simulator's node itself (so its names
are the simulator's: ``/cmd_vel``, ``/r2d2_sim/get_joint_info``), each robot
of several on a :class:`RobotNode` of its own (``/robot_a/cmd_vel``,
``/robot_a/r2d2_sim/get_joint_info``). rclpy has no sub-nodes: a node per
namespace is how one process serves several (they share one DDS participant).
"""

import threading
from typing import Callable, Iterator, List, Tuple

from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from std_srvs.srv import Trigger

from r2d2_sim.ros.cmd_vel import CmdVelInput, ThrottledLog
from r2d2_sim.ros.joint_info import joint_info_json
from r2d2_sim.ros.mirror import MirroringNode
from r2d2_sim.ros.outputs import RobotOutputs
from r2d2_sim.ros.quiet_node import NO_TYPE_DESCRIPTION_SERVICE
from r2d2_sim.sim.robots.robot import Measurement, Robot
from r2d2_sim.ros.tf_outputs import tf_topics

__all__ = ['RobotInterfaces', 'RobotNode', 'DESCRIPTION_QOS']

# robot_description as robot_state_publisher offers it: latched for late joiners.
DESCRIPTION_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
# What a robot may make on a node it shares, and how each is taken down again.
ENTITY_KINDS = (('publishers', 'destroy_publisher'), ('relayed_publishers', 'destroy_publisher'),
                ('subscriptions', 'destroy_subscription'),
                ('services', 'destroy_service'), ('clients', 'destroy_client'),
                ('timers', 'destroy_timer'))


def _entities(node: MirroringNode) -> List[Tuple[str, object]]:
    """Return every entity of ``node`` (publishers, subscriptions...) with its destroy method."""
    return [(destroy, entity) for kind, destroy in ENTITY_KINDS
            for entity in getattr(node, kind)]


class RobotNode(MirroringNode):
    """
    The node of one robot of several: named as the simulator, in the robot's namespace.

    Its name and namespace are node-local remaps, which win over the
    process's global ``-r __node:=`` and ``-r __ns:=`` (those place the
    simulator; the robot's namespace is already resolved under it). Other
    global remaps (``-r /tf:=tf``) apply, as to every node. No parameter
    services: the robots' parameters are the simulator's (``robot_a.initial_pose``).
    No ``~/get_type_description`` either: rclpy 7.1's ``destroy_node`` never
    finalizes that service, so every deleted robot left its DDS reader and
    writer (about 100 kB) in the process and the graph for good, and each
    later delete got slower (issue 30, U3-2; docs/limits.md). The simulator's
    node, which lives as long as the process, still serves it.
    """

    def __init__(self, simulator: MirroringNode, namespace: str) -> None:
        name = simulator.get_name()
        super().__init__(name, context=simulator.context, namespace=namespace,
                         start_parameter_services=False,
                         parameter_overrides=[NO_TYPE_DESCRIPTION_SERVICE],
                         cli_args=['--ros-args', '-r', f'__node:={name}',
                                   '-r', f'__ns:={namespace}'])
        self.sink = simulator.sink
        self.relay = simulator.relay
        self._simulator_time_ns = simulator.sink_time_ns
        self._destroyed = False

    def sink_time_ns(self) -> int:
        """Return the simulator's time: the robot's mirrored messages are logged at it."""
        return self._simulator_time_ns()

    def destroy_node(self) -> None:
        """Destroy the node once (the simulator and a harness may both ask), sink first."""
        if not self._destroyed:
            self._destroyed = True
            self.release_mirrors()
            self.destroy_relayed()
            super().destroy_node()


class RobotInterfaces:
    """
    Everything one robot has in ROS, on ``node``: outputs, ``cmd_vel``, description, joint info.

    ``lock`` is the simulator's (PyBullet is single-threaded); ``now_ns``
    gives the simulated time (a TwistStamped's age is judged by it),
    ``time_ns`` the time of the first static transforms. ``own_node``: the
    node is this robot's alone, destroyed by :meth:`close`; otherwise (the
    one robot in the simulator's namespace) :meth:`close` destroys what the
    robot made on it.
    """

    def __init__(self, node: MirroringNode, robot: Robot, lock: threading.RLock, *,
                 now_ns: Callable[[], int], time_ns: int, warning_period_s: float,
                 graph_check_period_s: float, own_node: bool) -> None:
        self.node = node
        self.robot = robot
        self.own_node = own_node
        self._lock = lock
        before = set(map(id, (entity for _, entity in _entities(node))))
        self.outputs = RobotOutputs(node, robot.config, robot, time_ns)
        self._description = node.create_publisher(String, 'robot_description', DESCRIPTION_QOS)
        self._description.publish(String(data=robot.description))
        self.cmd_vel = CmdVelInput(node, robot.config, robot, ThrottledLog(warning_period_s),
                                   now_ns, graph_check_period_s=graph_check_period_s)
        self._joint_info = node.create_service(Trigger, '~/get_joint_info',
                                               self._on_get_joint_info)
        # Where its transforms go (resolved): /tf and /tf_static, or its namespace's.
        tf, tf_static = tf_topics(robot.config)
        self.tf_topics = (node.resolve_topic_name(tf), node.resolve_topic_name(tf_static))
        self._made = [] if own_node else [(destroy, entity) for destroy, entity in _entities(node)
                                          if id(entity) not in before]

    @property
    def name(self) -> str:
        """Return what the robot is called: its entity name."""
        return self.robot.name

    @property
    def namespace(self) -> str:
        """Return the namespace of the robot's topics."""
        return self.node.get_namespace()

    @property
    def publishers(self) -> Iterator[Publisher]:
        """Return every publisher of the robot's node (the simulator's, for the default robot)."""
        return iter(self.node.all_publishers())  # relayed ones too (outputs_process)

    def publish(self, measurement: Measurement) -> None:
        """Publish what the robot measured at one step."""
        self.outputs.publish(measurement)

    def _on_get_joint_info(self, request: Trigger.Request,
                           response: Trigger.Response) -> Trigger.Response:
        with self._lock:
            response.message = joint_info_json(self.robot.body, self.robot.source)
        response.success = True
        return response

    def close(self) -> None:
        """Take the robot's interfaces down: its node, or what it made on the simulator's."""
        if self.own_node:
            self.node.destroy_node()
        for destroy, entity in reversed(self._made):
            getattr(self.node, destroy)(entity)
        self._made.clear()
