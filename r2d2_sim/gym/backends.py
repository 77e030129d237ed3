"""
Where an environment's world runs: the ROS-free core in this process, or the simulator node.

No ROS here: the ``ros`` backend lives in :mod:`r2d2_sim.gym.ros_backend`,
imported only when asked for (:func:`make_backend`), so that an ``inproc``
environment never loads rclpy. Both hold an
:class:`~r2d2_sim.gym.arena.Arena` on a
:class:`~r2d2_sim.sim.simulation.Simulation` in this process and give the
same readings for the same commands, bit for bit: the ``ros`` backend's
come over the robot's topics.
"""

from contextlib import nullcontext
from typing import Any, Callable, ContextManager, List, Optional, Protocol, Sequence

from r2d2_sim.errors import SetupError, StartupError
from r2d2_sim.gym.arena import Arena, Episode, reading_of
from r2d2_sim.gym.settings import GymError, NavSettings
from r2d2_sim.gym.task import Command, Outcome, Reading
from r2d2_sim.sim.settings.robots import parse_world
from r2d2_sim.sim.simulation import Simulation

__all__ = ['Backend', 'InprocBackend', 'make_backend']


class Backend(Protocol):
    """What an environment needs of where its world runs."""

    simulation: Simulation

    def core(self) -> ContextManager[Any]:
        """Return what to hold while touching the core directly (the node's lock)."""

    def start(self, episode: Episode) -> List[Reading]:
        """Begin an episode; return each robot's first reading."""

    def act(self, commands: Sequence[Command]) -> List[Reading]:
        """Give each robot its command, run one control period; return each robot's reading."""

    def outcomes(self) -> List[Outcome]:
        """Return what each robot's watch saw this episode: the goal, a contact, a fall."""

    def close(self) -> None:
        """Free everything; safe to call twice."""


class InprocBackend:
    """
    The world in this process, on the ROS-free core: the fastest way to train.

    A control period is the robots' commands handed to their drive
    controllers, then :meth:`Simulation.step` as often as the period has
    physics steps; the last step measures each robot's state and scan.
    """

    def __init__(self, settings: NavSettings) -> None:
        config, robots = parse_world(settings.sim_parameters_for())
        self.simulation = Simulation(config, robots)
        try:
            self.arena = Arena(self.simulation, settings.pool, settings.box_size,
                               settings.tip_angle_rad)
        except BaseException:
            self.simulation.close()
            raise
        self._steps = settings.steps_per_period

    def core(self) -> ContextManager[Any]:
        """Return nothing to hold: this thread is the only one in the core."""
        return nullcontext()

    def start(self, episode: Episode) -> List[Reading]:
        """Begin an episode (see :meth:`Arena.start`)."""
        return self.arena.start(episode)

    def act(self, commands: Sequence[Command]) -> List[Reading]:
        """Command each robot, run one control period; return each robot's reading."""
        simulation = self.simulation
        for robot, (linear, angular) in zip(simulation.robots, commands):
            robot.command(linear, angular)
        step = simulation.step
        result = None
        for _ in range(self._steps):
            result = step()
        if result is None:
            raise RuntimeError('the control period ended without a measurement')
        return [reading_of(measurement) for measurement in result.measurements]

    def outcomes(self) -> List[Outcome]:
        """Return what each robot's watch saw this episode (see :meth:`Arena.outcomes`)."""
        return self.arena.outcomes()

    def close(self) -> None:
        """Free the saved state and disconnect the physics; safe to call twice."""
        self.arena.close()
        self.simulation.close()


def make_backend(settings: NavSettings, ros_nodes: Optional[Callable[[Any], Any]] = None,
                 topics: Optional[dict] = None) -> Backend:
    """
    Return the backend ``settings.backend`` names (the ``ros`` one imports rclpy here).

    What the simulator refuses while it is built (a URDF it cannot load,
    wheels the URDF lacks, a window without a display) is a GymError in
    one line in both backends, the simulator's error its ``__cause__``.
    """
    try:
        if settings.backend == 'inproc':
            if ros_nodes is not None or topics:
                raise GymError('ros_nodes and topics are for backend=\'ros\'')
            return InprocBackend(settings)
        if ros_nodes is not None and not callable(ros_nodes):  # called once the node runs
            raise GymError(f'ros_nodes must be a function of the harness, ros_nodes(harness), '
                           f'got {type(ros_nodes).__name__} {ros_nodes!r:.40}')
        from r2d2_sim.gym.ros_backend import RosBackend
        return RosBackend(settings, ros_nodes=ros_nodes, topics=topics)
    except (SetupError, StartupError) as exc:  # inproc: the core's; ros: the node's
        raise GymError(f'sim_parameters: {" ".join(str(exc).split())}') from exc
