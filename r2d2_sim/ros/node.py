"""
The ``r2d2_sim`` ROS 2 node: translation between ROS and the simulation core.

The node owns a :class:`~r2d2_sim.sim.simulation.Simulation` and advances it only
when asked (:meth:`SimNode.advance`); it has no timers of its own for physics.
:func:`r2d2_sim.apps.sim_node.main` paces it against the wall clock while an executor
serves topics and services in another thread; tests drive it step by step.
Everything here is ROS plumbing: parameters in, messages out, services.
"""

import threading
import time
from typing import Any, Callable, Optional, Union

from rclpy.exceptions import ParameterException
from rclpy.node import Node

from r2d2_sim.errors import RefusedError, SetupError, StartupError
from r2d2_sim.physics.world import SimWorld
from r2d2_sim.recording.sink import FoxgloveSink, SinkError
from r2d2_sim.ros.cmd_vel import CmdVelInput, GRAPH_CHECK_PERIOD_S, ThrottledLog, \
    WARNING_PERIOD_S
from r2d2_sim.ros.control_services import ControlServices
from r2d2_sim.ros.fleet import Fleet
from r2d2_sim.ros.mirror import MirroringNode, say_sink, sink_spec, start_sink
from r2d2_sim.ros.notices import warn_once
from r2d2_sim.ros.outputs import ClockOutput
from r2d2_sim.ros.parameters import (
    declare_parameters, rclpy_parameter_problem, with_ray_threads)
from r2d2_sim.ros.relay import OutputRelay, RelayError
from r2d2_sim.ros.robot_interfaces import RobotInterfaces
from r2d2_sim.ros.standard import server as standard
from r2d2_sim.ros.standard.server import SimulationInterfaces
from r2d2_sim.sim.simulation import Simulation, StepResult
from r2d2_sim.sim.worlds import LoadOptions, World

NODE_NAME = 'r2d2_sim'
# A LoadWorld builds the new world for at most this long (one body at least)
# before the physics takes a step of the old one: well within a 240 Hz step.
BUILD_CHUNK_S = 0.002
# And waits at most this long between two chunks for the paced loop's step (a
# 240 Hz step at real time is due within 4.2 ms).
BUILD_WAIT_S = 0.005
__all__ = ['SimNode', 'StartupError', 'NODE_NAME']


class SimNode(MirroringNode):
    """
    Simulates R2D2 in PyBullet and exposes it through standard ROS interfaces.

    Each robot publishes ``joint_states``, ``odom`` (wheel odometry),
    ``ground_truth``, TF, ``scan``, ``imu``, the latched ``robot_description``
    and, with ``camera_rate``, ``camera/image_raw`` and ``camera/camera_info``
    (and ``camera/depth/*``); subscribes ``cmd_vel``; serves
    ``~/get_joint_info``. One robot (the default) does so on this node, in its
    namespace; several (the ``robots`` parameter, or spawned with a namespace
    through the standard) each on a :class:`~r2d2_sim.ros.robot_interfaces.RobotNode`
    in its own. This node publishes ``/clock`` (one per world) and serves
    ``~/get_status``, ``~/pause``, ``~/step`` and ``~/reset``.
    Takes rclpy's Node keywords (``context``, ``namespace``,
    ``parameter_overrides``...), and how often (wall seconds) a kind of
    warning may repeat (``warning_period_s``) and the graph is checked for
    ``cmd_vel`` publishers of the wrong type (``graph_check_period_s``).
    With simulation_interfaces installed it also serves ROS 2's simulation
    standard (:mod:`r2d2_sim.ros.standard.server`); ``on_quit`` is what a request
    for the QUITTING state calls (``sim_node`` stops itself; without it
    QUITTING is unsupported). Raises :class:`StartupError` when its
    parameters or URDF are unusable.
    """

    def __init__(self, node_name: str = NODE_NAME, *,
                 warning_period_s: float = WARNING_PERIOD_S,
                 graph_check_period_s: float = GRAPH_CHECK_PERIOD_S,
                 on_quit: Optional[Callable[[], None]] = None, **node_kwargs: Any) -> None:
        self.sink: Optional[FoxgloveSink] = None  # before rclpy makes its own publishers
        self.relay: Optional[OutputRelay] = None
        self._in_loop = False  # advancing for the real-time loop: no wait for the relay
        try:
            super().__init__(node_name, **node_kwargs)
        except ParameterException as exc:  # rclpy's own, such as use_sim_time:=1
            raise StartupError(rclpy_parameter_problem(exc)) from exc
        self.lock = threading.RLock()  # one thread in PyBullet at a time (public: the services')
        self._throttled = ThrottledLog(warning_period_s)
        self.standard: Optional[SimulationInterfaces] = None
        # One per robot, in the order of simulation.robots (their measurements').
        self.fleet = Fleet(self, self.lock, now_ns=lambda: self.simulation.time_ns,
                           published_ns=lambda: self.last_publication_ns,
                           warning_period_s=warning_period_s,
                           graph_check_period_s=graph_check_period_s)
        # Built in a local: self.simulation is set once the simulation exists, and
        # nothing reads it before (the fleet's clock and the mirrored publishers
        # first run from watch_robots on), so it is never None.
        simulation: Optional[Simulation] = None
        # The simulated time last logged at, and what time resets added before it.
        self._sink_seen_ns = self._sink_offset_ns = 0
        try:
            config, specs = declare_parameters(self)
            self.config = with_ray_threads(config)
            if self.config.outputs_process:
                # The live view and the recording go with the publishing (relay.py).
                sink = sink_spec(self.config, self.get_name())
                self.relay = OutputRelay(self.context.get_domain_id(),
                                         f'{self.get_name()}_outputs', self.get_namespace(),
                                         self.get_logger().error, sink=sink,
                                         time_ns=self.sink_time_ns if sink else None)
                say_sink(self.config, self.relay.sink_url, self.get_logger())
            else:
                self.sink = start_sink(self.config, self.get_name(), self.get_logger())
            simulation = Simulation(self.config, specs, warn=self.get_logger().warning,
                                    error=self._log_blow_up, namespace=self.get_namespace())
            self.simulation: Simulation = simulation
            self._clock_output = ClockOutput(self)
            simulation.watch_robots(self.fleet.follow)
        except (SetupError, SinkError, RelayError) as exc:
            self._close(simulation)
            raise StartupError(str(exc)) from exc
        except BaseException:  # nothing left running: the sink, the outputs process
            self._close(simulation)
            raise
        self._paused = self.config.start_paused
        # A node that starts playing has started its clock: paused at 0 later, it is PAUSED.
        simulation.unrun_since_launch = self._paused
        self.control = ControlServices(self, self, self.fleet)
        if standard.available():
            self.standard = SimulationInterfaces(self, simulation.entities, simulation,
                                                 simulation.worlds, self, self, on_quit)
        else:
            warn_once(self.get_logger(),
                      'simulation_interfaces is not installed: its services (spawn_entity, '
                      'step_simulation...) are off (a pip-only venv gets it from '
                      'tools/build_interfaces.sh VENV); everything else works')
        self._publish(self.simulation.read_states())

    def sink_time_ns(self) -> int:
        """
        Return the time mirrored messages are logged at: simulated time, on across resets.

        A time reset (``~/reset`` with time, the standard's ResetSimulation,
        STOPPED) sets the simulated time back to 0 while the recording goes on:
        its log times then count on from the last time logged before it, so
        that readers ordering by log time (``ros2 bag play``, Foxglove) keep the
        episodes apart. The messages' own stamps start from 0 again.
        """
        now = self.simulation.time_ns
        if now < self._sink_seen_ns:
            self._sink_offset_ns += self._sink_seen_ns
        self._sink_seen_ns = now
        return now + self._sink_offset_ns

    # -- robots and their interfaces ---------------------------------------------------

    @property
    def robots(self) -> Fleet:
        """Return every robot's interfaces, in the simulation's order (iterable, indexable)."""
        return self.fleet

    def watch_robot_nodes(self, added: Callable[[Node], object],
                          removed: Callable[[Node], object]) -> None:
        """
        Follow the robots' own nodes: ``added`` for each, now and later; ``removed`` for leavers.

        Whoever spins this node spins the robots' nodes too (``sim_node``'s
        executor, a test harness's); ``removed`` must take the node out of
        the executor before it is destroyed.
        """
        self.fleet.watch(added, removed)

    def robot(self, name: Optional[str] = None) -> RobotInterfaces:
        """Return a robot's interfaces by name (default: the first robot); KeyError if none."""
        return self.fleet.named(name)

    @property
    def world(self) -> SimWorld:
        """Return the PyBullet world, for tests and advanced use."""
        return self.simulation.world

    @property
    def step_count(self) -> int:
        """Return the number of physics steps taken since start."""
        return self.simulation.step_count

    @property
    def reset_count(self) -> int:
        """Return how often the world was reset, restored, loaded or unloaded since start."""
        return self.simulation.reset_count

    @property
    def sim_time_ns(self) -> int:
        """Return simulated time in integer nanoseconds (exact, no drift)."""
        return self.simulation.time_ns

    @property
    def last_publication_ns(self) -> int:
        """Return the simulated time (ns) of the latest state publication (its stamps)."""
        simulation = self.simulation
        return simulation.clock.time_ns(simulation.last_frame_step)

    @property
    def paused(self) -> bool:
        """Return True while physics is stopped."""
        return self._paused

    @property
    def unrun_since_launch(self) -> bool:
        """Return True while nothing ran since start-up, a full reset or a world load."""
        return self.simulation.unrun_since_launch

    @property
    def world_is_loaded(self) -> bool:
        """Return False after UnloadWorld until a world is loaded: nothing may step then."""
        return self.simulation.worlds.is_loaded

    # -- the world around the robots (WorldChanges; its reads are simulation.worlds) ------

    def load_world(self, world: Union[str, World], resource_string: str = '',
                   options: LoadOptions = LoadOptions()) -> World:
        """
        Load a world in place of the current one; return it. Stopped: paused, at time 0.

        ``world`` is a URI, or a world read beforehand (``simulation.worlds.read``,
        without the lock: the physics keeps its rate while the files are
        read). A refusal (RefusedError) leaves everything as it was, paused or
        not. ``/clock`` says 0 at once; the robots are published at the next step.
        """
        if isinstance(world, str):
            world = self.simulation.worlds.read(world, resource_string, options)
        # Built beside the old world, a few bodies at a time with the lock held, and
        # swapped in at once: the physics steps on between (one step each time).
        steps = self.simulation.loading_world(world)
        try:
            while True:
                with self.lock:
                    if not self.simulation.world.connected:  # the node is being destroyed
                        raise RefusedError('OPERATION_FAILED', 'the simulator is shutting down')
                    chunk_end = time.monotonic() + BUILD_CHUNK_S
                    try:
                        while True:
                            next(steps)
                            if time.monotonic() >= chunk_end:
                                break
                    except StopIteration as stop:
                        self._stopped_at_zero()
                        return stop.value
                    running, before = not self._paused, self.simulation.step_count
                if running:
                    self._wait_for_a_step(before)
        finally:
            steps.close()  # a build not taken leaves nothing behind (its client, its robots)

    def _wait_for_a_step(self, before: int) -> None:
        """Wait until the physics stepped on from ``before``: two step periods, 5 ms at most."""
        config = self.config
        if config.real_time_factor <= 0.0:
            time.sleep(0)  # as fast as possible: the loop takes the lock when it is free
            return
        # In slow motion a step is seldom due: the build does not wait a period for it.
        wait_s = min(2.0 / (config.physics_rate_hz * config.real_time_factor), BUILD_WAIT_S)
        deadline = time.monotonic() + wait_s
        while self.simulation.step_count == before and time.monotonic() < deadline:
            time.sleep(0.0005)

    def unload_world(self) -> None:
        """Unload the world: paused, time 0, and nothing steps until a world is loaded."""
        with self.lock:
            self.simulation.unload_world()
            self._stopped_at_zero()

    def _stopped_at_zero(self) -> None:
        self._paused = True
        self._clock_output.publish(self.simulation.time_ns)
        self._tell_time(self.simulation.time_ns)

    @property
    def blow_ups(self) -> int:
        """Return how often the physics blew up and a robot was reset."""
        return self.simulation.blow_ups

    @property
    def cmd_vel(self) -> CmdVelInput:
        """Return the first robot's ``cmd_vel`` input (the one robot's, by default)."""
        return self.robots[0].cmd_vel

    @property
    def commands_received(self) -> int:
        """Return the number of cmd_vel messages taken by every robot, refused ones included."""
        return self.fleet.received

    @property
    def commands_rejected(self) -> int:
        """Return the number of cmd_vel messages refused (NaN, stale stamp...), all robots'."""
        return self.fleet.rejected

    @property
    def has_wheels(self) -> bool:
        """Return True when cmd_vel drives the first robot's wheels."""
        return self.simulation.robot.controller is not None

    def steps_to_next_publish(self) -> int:
        """Return the number of physics steps until the next state publication."""
        return self.simulation.steps_to_next_publish()

    def advance(self, steps: int = 1) -> None:
        """
        Step the physics ``steps`` times, applying commands and publishing on schedule.

        This is the in-process API for tests: it ignores pause and pacing, so a
        test can advance simulated time deterministically between its own spins.
        With ``outputs_process`` it returns once the outputs process has
        published every message of these steps, unless :meth:`advance_if_running`
        (the real-time loop) called it: the physics goes on meanwhile.
        """
        with self.lock:
            step, publish = self.simulation.step, self._publish
            for _ in range(steps):
                result = step()
                if result is not None:
                    publish(result)
            if self.relay is not None and not self._in_loop:
                self.relay.wait()

    def advance_to_next_publish(self) -> int:
        """Advance one control period: to and including the next publication."""
        steps = self.steps_to_next_publish()
        self.advance(steps)
        return steps

    def advance_if_running(self, steps: Optional[int] = None) -> bool:
        """
        Advance ``steps`` (default: one control period) unless paused; return whether it did.

        The check and the steps hold the lock that ``~/pause`` takes, so once a
        pause is answered no further step runs and the reply's time is final.
        The real-time loop's (``sim_node``): it never waits for an outputs process.
        """
        with self.lock:
            if self._paused:
                return False
            self._in_loop = True  # advance itself is a seam (tests wrap it): told, not passed
            try:
                self.advance(self.steps_to_next_publish() if steps is None else steps)
            finally:
                self._in_loop = False
            return True

    def _publish(self, result: StepResult) -> None:
        """Translate one step's measurements into messages: /clock first, then each robot's."""
        relay = self.relay
        if relay is not None:
            relay.begin()  # one frame to the outputs process a step
            try:
                self._publish_messages(result)
            finally:
                relay.end()
        else:
            self._publish_messages(result)

    def _publish_messages(self, result: StepResult) -> None:
        # /clock at every step that publishes anything, before it: a node on simulated
        # time never receives a message stamped later than its clock (an IMU at 100 Hz
        # with publish_rate 50 was up to a publication period ahead of it).
        self._clock_output.publish(result.time_ns)
        self._tell_time(result.time_ns)
        for interfaces, measurement in zip(self.robots, result.measurements):
            if measurement is not None:
                interfaces.publish(measurement)

    def _tell_time(self, time_ns: int) -> None:
        """Give the live view the simulated time: this process's sink, or the child's."""
        if self.sink is not None:
            self.sink.set_time(time_ns)
        elif self.relay is not None:
            self.relay.set_time(time_ns)

    def status(self, **facts: Any) -> str:
        """Return the simulation's state as the control services' JSON (see ControlServices)."""
        return self.control.status(**facts)

    def _log_blow_up(self, text: str) -> None:
        # Throttled per robot (the line ends "resetting the robot NAME to ...") and per
        # other body a blow-up broke (the line names it, and nothing else changes).
        at = text.rfind(' the robot ')
        self._throttled('blow-up ' + (text[at:] if at >= 0 else text), self.get_logger().error,
                        text)

    def set_paused(self, paused: bool) -> None:
        """
        Pause (stopping on a publication) or resume physics, under the lock.

        Pause lands where a client sees the state: physics finishes the
        control period up to the step that publishes, so the time is the
        last /clock and every ~/step after it is one whole period.
        RefusedError INCORRECT_STATE for resuming with no world loaded.
        """
        with self.lock:  # no step runs between the change and the caller's reply
            if not paused and not self.simulation.worlds.is_loaded:
                raise RefusedError('INCORRECT_STATE', 'no world is loaded (UnloadWorld): load '
                                                      'one (LoadWorld) to run the simulation')
            if paused and not self._paused:
                if self.step_count != self.simulation.last_frame_step:
                    self.advance_to_next_publish()
            if bool(paused) != self._paused:
                # Played or paused, it ran: no longer 'stopped' at 0 (the standard's
                # STOPPED is reached only by a stop, a full reset or a world loaded).
                self.simulation.unrun_since_launch = False
            self._paused = bool(paused)

    def reset_simulation(self, *, time: bool = False, state: bool = True,
                         spawned: bool = False) -> None:
        """
        Reset what is asked (see :meth:`Simulation.reset`); with time, ``/clock`` says so now.

        A node on simulated time must not go on seeing the old time while the
        simulation waits, paused, at 0. The robots' states are not published
        now: this step's state is out already, and a second odom ->
        base_footprint at one stamp is one tf2 drops (TF_REPEATED_DATA); the
        next publication carries the reset robots.
        """
        with self.lock:
            self.simulation.reset(time=time, state=state, spawned=spawned)
            if time:
                self._clock_output.publish(self.simulation.time_ns)
                self._tell_time(self.simulation.time_ns)

    def _close(self, simulation: Optional[Simulation]) -> None:
        """Close the robots' interfaces, ``simulation`` (None: not built), the sink, the relay."""
        self.fleet.close()
        if simulation is not None:
            simulation.close()
        if self.sink is not None:
            self.sink.close()  # an MCAP file is readable only once closed
        if self.relay is not None:
            self.destroy_relayed()
            self.relay.close()  # the child publishes what it has, then ends

    def destroy_node(self) -> None:
        """Take the standard's services down, disconnect physics, end the recording, destroy."""
        if self.standard is not None:
            self.standard.close()
        with self.lock:
            self._close(self.simulation)
        super().destroy_node()
