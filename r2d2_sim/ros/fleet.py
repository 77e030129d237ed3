"""
Every robot's ROS side, in the simulation's order: added, spawned, taken down on delete.

:class:`Fleet` keeps one :class:`~r2d2_sim.ros.robot_interfaces.RobotInterfaces`
per robot of the :class:`~r2d2_sim.sim.simulation.Simulation`, in the same order
(each step's measurements come in it), decides where each robot's interfaces
live (the simulator's node for a robot in its namespace, a
:class:`~r2d2_sim.ros.robot_interfaces.RobotNode` otherwise), checks namespaces,
and tells whoever spins the simulator (``sim_node``'s executor, a test
harness's) when a robot's own node comes or goes.
"""

from typing import Callable, Iterator, List, Optional, Sequence, Tuple

from rclpy.node import Node

from r2d2_sim.sim.entities import EntityError
from r2d2_sim.ros.mirror import MirroringNode
from r2d2_sim.sim.parameter_readers import ConfigError, namespace as read_namespace
from r2d2_sim.sim.robot_parameters import resolve_namespace, RobotSpec
from r2d2_sim.sim.robot import Robot
from r2d2_sim.ros.robot_interfaces import RobotInterfaces, RobotNode

__all__ = ['Fleet']

NodeWatcher = Tuple[Callable[[Node], None], Callable[[Node], None]]


class Fleet:
    """
    The robots' interfaces on ``simulator`` (a SimNode), one per robot, in the core's order.

    ``make(node, robot, own_node)`` builds a robot's interfaces on a node.
    Iterating gives them in order; :attr:`received` and :attr:`rejected`
    count ``cmd_vel`` messages of every robot, deleted ones included.
    """

    def __init__(self, simulator: MirroringNode,
                 make: Callable[[MirroringNode, Robot, bool], RobotInterfaces]) -> None:
        self._simulator = simulator
        self._make = make
        self._interfaces: List[RobotInterfaces] = []
        self._watchers: List[NodeWatcher] = []
        self._removed = [0, 0]  # cmd_vel received, rejected by robots deleted since

    def __iter__(self) -> Iterator[RobotInterfaces]:
        return iter(self._interfaces)

    def __len__(self) -> int:
        return len(self._interfaces)

    def __getitem__(self, index: int) -> RobotInterfaces:
        return self._interfaces[index]

    @property
    def received(self) -> int:
        """Return the cmd_vel messages every robot took, refused ones included."""
        return sum(i.cmd_vel.received for i in self._interfaces) + self._removed[0]

    @property
    def rejected(self) -> int:
        """Return the cmd_vel messages every robot refused (NaN, stale stamp...)."""
        return sum(i.cmd_vel.rejected for i in self._interfaces) + self._removed[1]

    def resolve(self, namespace: str) -> str:
        """Return ``namespace`` absolute: a relative one is under the simulator's namespace."""
        return resolve_namespace(self._simulator.get_namespace(), namespace)

    def start_namespaces(self, specs: Sequence[RobotSpec]) -> List[Optional[str]]:
        """Return each listed robot's namespace, resolved (None: the one default robot)."""
        if not specs:
            return [None]
        namespaces = [self.resolve(spec.namespace) for spec in specs]
        for i, namespace in enumerate(namespaces):
            if namespace in namespaces[:i]:
                other = specs[namespaces.index(namespace)].name
                raise ConfigError(f'robots {other} and {specs[i].name} both have the namespace '
                                  f'{namespace}: each robot needs one of its own')
        return namespaces

    def free_namespace(self, namespace: str) -> str:
        """Return a spawned robot's namespace, resolved; EntityError NAMESPACE_INVALID if taken."""
        try:
            resolved = self.resolve(read_namespace('entity_namespace', namespace))
        except ConfigError as exc:
            raise EntityError('NAMESPACE_INVALID', str(exc)) from None
        if resolved == self._simulator.get_namespace():
            raise EntityError('NAMESPACE_INVALID', f'{resolved} is the simulator\'s own '
                                                   'namespace: give the robot one of its own')
        for interfaces in self._interfaces:
            if interfaces.namespace == resolved:
                raise EntityError('NAMESPACE_INVALID', f'robot {interfaces.name} has the '
                                                       f'namespace {resolved} already')
        return resolved

    def add(self, robot: Robot, namespace: Optional[str]) -> RobotInterfaces:
        """
        Give ``robot`` its interfaces: on the simulator in its namespace, else its own node.

        ConfigError (one line) when ROS refuses a name there (rclpy's own
        checks: a namespace or a topic too long for the middleware...).
        """
        simulator = self._simulator
        own = namespace is not None and namespace != simulator.get_namespace()
        node = None
        try:
            node = RobotNode(simulator, namespace) if own else simulator
            interfaces = self._make(node, robot, own)
        except Exception as exc:
            if own and node is not None:
                node.destroy_node()
            if isinstance(exc, ConfigError):
                raise
            reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise ConfigError(f'robot {robot.name} cannot have its interfaces in '
                              f'{namespace or simulator.get_namespace()}: {reason}') from None
        self._interfaces.append(interfaces)
        if own:
            for added, _ in self._watchers:
                added(node)
        return interfaces

    def sync(self, robots: Sequence[Robot]) -> None:
        """Take down the interfaces of robots not in ``robots`` (the core's); keep its order."""
        live = {id(robot) for robot in robots}
        for interfaces in [i for i in self._interfaces if id(i.robot) not in live]:
            self._interfaces.remove(interfaces)
            self._removed[0] += interfaces.cmd_vel.received
            self._removed[1] += interfaces.cmd_vel.rejected
            if interfaces.own_node:
                for _, removed in self._watchers:
                    removed(interfaces.node)
            interfaces.close()
        by_robot = {id(i.robot): i for i in self._interfaces}
        self._interfaces = [by_robot[id(robot)] for robot in robots]

    def watch(self, added: Callable[[Node], None], removed: Callable[[Node], None]) -> None:
        """Call ``added`` for each robot's own node, now and later; ``removed`` for leavers."""
        self._watchers.append((added, removed))
        for interfaces in self._interfaces:
            if interfaces.own_node:
                added(interfaces.node)

    def named(self, name: Optional[str] = None) -> RobotInterfaces:
        """Return a robot's interfaces by name (default: the first robot); KeyError if none."""
        for interfaces in self._interfaces:
            if name is None or interfaces.name == name:
                return interfaces
        raise KeyError(f'no robot named {name!r}; the robots are: '
                       f'{", ".join(i.name for i in self._interfaces)}')

    def close(self) -> None:
        """Take every robot's interfaces down, telling no watcher (they are shutting down too)."""
        for interfaces in reversed(self._interfaces):
            interfaces.close()
        self._interfaces.clear()
