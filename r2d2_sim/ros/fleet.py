"""
Every robot's ROS side, following the core's robots: added, spawned, taken down on delete.

:class:`Fleet` keeps one :class:`~r2d2_sim.ros.robot_interfaces.RobotInterfaces`
per robot of the :class:`~r2d2_sim.sim.simulation.Simulation`, in the same
order (each step's measurements come in it). The core tells it the robots
after every change (:meth:`Fleet.follow`); it builds the interfaces of a new
robot where they live (the simulator's node for a robot in its namespace, a
:class:`~r2d2_sim.ros.robot_interfaces.RobotNode` otherwise), takes down
those of a robot gone, and tells whoever spins the simulator (``sim_node``'s
executor, a test harness's) when a robot's own node comes or goes.
"""

import threading
from typing import Callable, Iterator, List, Optional, Sequence, Tuple

from rclpy.node import Node

from r2d2_sim.ros.mirror import MirroringNode
from r2d2_sim.ros.robot_interfaces import RobotInterfaces, RobotNode
from r2d2_sim.sim.settings.readers import ConfigError
from r2d2_sim.sim.robots.robot import Robot

__all__ = ['Fleet']

NodeWatcher = Tuple[Callable[[Node], object], Callable[[Node], object]]


class Fleet:
    """
    The robots' interfaces on ``simulator`` (a SimNode), one per robot, in the core's order.

    ``lock`` is the simulator's, ``now_ns`` gives the simulated time,
    ``published_ns`` the time of the latest state publication (a new robot's
    ``/tf_static`` stamp: see :meth:`_add`), and the periods are how often a
    robot's warnings may repeat and its graph be checked (see
    :class:`~r2d2_sim.ros.robot_interfaces.RobotInterfaces`).
    Iterating gives the interfaces in order; :attr:`received` and
    :attr:`rejected` count ``cmd_vel`` messages of every robot, deleted ones
    included.
    """

    def __init__(self, simulator: MirroringNode, lock: threading.RLock, *,
                 now_ns: Callable[[], int], published_ns: Callable[[], int],
                 warning_period_s: float, graph_check_period_s: float) -> None:
        self._simulator = simulator
        self._lock = lock
        self._now_ns = now_ns
        self._published_ns = published_ns
        self._warning_period_s = warning_period_s
        self._graph_check_period_s = graph_check_period_s
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

    def follow(self, robots: Sequence[Robot]) -> None:
        """
        Match the core's ``robots``: interfaces for new ones, none for those gone, in their order.

        ConfigError (one line) when ROS refuses a new robot's names (rclpy's
        own checks: a namespace or a topic too long for the middleware...);
        that robot then has no interfaces, and the core undoes its spawn.
        """
        live = {id(robot) for robot in robots}
        for interfaces in [i for i in self._interfaces if id(i.robot) not in live]:
            self._remove(interfaces)
        known = {id(i.robot) for i in self._interfaces}
        for robot in robots:
            if id(robot) not in known:
                self._interfaces.append(self._add(robot))
        by_robot = {id(i.robot): i for i in self._interfaces}
        self._interfaces = [by_robot[id(robot)] for robot in robots]

    def _add(self, robot: Robot) -> RobotInterfaces:
        """
        Build ``robot``'s interfaces: on the simulator in its namespace, else its own node.

        Its ``/tf_static`` is stamped with the latest state publication's time,
        never later than the last ``/clock``: a robot spawned between two
        publications (a StepSimulation that stopped mid-period) is not stamped
        ahead of the clock, which moves on only at steps that publish.
        """
        simulator = self._simulator
        own = robot.namespace != simulator.get_namespace()
        node: Optional[MirroringNode] = None
        try:
            node = RobotNode(simulator, robot.namespace) if own else simulator
            interfaces = RobotInterfaces(
                node, robot, self._lock, now_ns=self._now_ns, time_ns=self._published_ns(),
                warning_period_s=self._warning_period_s,
                graph_check_period_s=self._graph_check_period_s, own_node=own)
        except Exception as exc:
            if own and node is not None:
                node.destroy_node()
            if isinstance(exc, ConfigError):
                if not own or str(exc).startswith(f'robot {robot.name}'):
                    raise
                raise ConfigError(f'robot {robot.name}: {exc}') from None  # which robot's
            reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise ConfigError(f'robot {robot.name} cannot have its interfaces in '
                              f'{robot.namespace}: {reason}') from None
        if own:
            for added, _ in self._watchers:
                added(node)
        return interfaces

    def _remove(self, interfaces: RobotInterfaces) -> None:
        self._interfaces.remove(interfaces)
        self._removed[0] += interfaces.cmd_vel.received
        self._removed[1] += interfaces.cmd_vel.rejected
        if interfaces.own_node:
            for _, removed in self._watchers:
                removed(interfaces.node)
        interfaces.close()

    def watch(self, added: Callable[[Node], object], removed: Callable[[Node], object]) -> None:
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
