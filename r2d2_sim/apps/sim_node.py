"""
The ``sim_node`` executable: signal handling first, then the paced simulator.

Importing rclpy and PyBullet takes about a quarter of a second. A signal in that
window used to end the process with a ``KeyboardInterrupt`` traceback (SIGINT)
or status -15 (SIGTERM). This module imports only the standard library at the
top, so its handlers are in place from the first line the package runs: during
the heavy imports a signal ends the process at once with status 0, after them
it only sets an event, which the paced loop sees and exits with status 0.
"""

import os
import signal
import sys
import threading
import time
import traceback
from types import FrameType
from typing import Callable, List, Optional, Sequence, TYPE_CHECKING

from r2d2_sim.apps.cli import ros_start_problem, SignalledEvent, stop_on_signals
from r2d2_sim.memory import keep_large_blocks_mapped

if TYPE_CHECKING:  # only the standard library is imported here (see the module)
    from rclpy.executors import Executor
    from r2d2_sim.model.timing import DeadlinePacer
    from r2d2_sim.ros.node import SimNode

# The executor thread checks for a stop request at least this often (s).
SPIN_POLL_S = 0.1


# A paced loop that does not sleep lets go of the interpreter lock between two advances,
# at most this often (wall s).
YIELD_EVERY_S = 0.002


def yield_interpreter() -> None:
    """Let go of the interpreter lock once, so that the node's other threads can take it."""
    time.sleep(0.0)


def run_paced(node: 'SimNode', stop: threading.Event, pacer: Optional['DeadlinePacer'] = None,
              advance: Optional[Callable[[Optional[int]], bool]] = None,
              yield_: Callable[[], None] = yield_interpreter,
              clock: Callable[[], float] = time.monotonic) -> None:
    """
    Step a :class:`~r2d2_sim.ros.node.SimNode` against the wall clock until ``stop`` is set.

    Real time (``real_time_factor`` > 0): one physics step per absolute
    deadline, or with a GUI one batch of steps per frame. As fast as
    possible: whole control periods back to back. A loop that does not sleep
    (as fast as possible, or behind its deadlines because the world is too
    big for real time) yields the interpreter lock once every
    :data:`YIELD_EVERY_S` between two advances: PyBullet holds that lock
    through every call, and the ROS executors' threads, which need it for
    each part of serving a request, were starved (``~/get_status``
    unanswered for over 60 s with 24 robots at real time, 0.2-1.3 s with one
    robot as fast as possible). A yield per advance would cost one robot as
    fast as possible half its rate (each hand-over of the lock waits for a
    thread to wake). ``pacer`` (a :class:`~r2d2_sim.model.timing.DeadlinePacer`;
    made from the rate when None), ``advance`` (default
    ``node.advance_if_running``), ``yield_`` and ``clock`` are seams for
    measuring the loop.
    """
    from r2d2_sim.model.timing import DeadlinePacer
    config = node.config
    rate = config.physics_rate_hz * config.real_time_factor
    # With a window, PyBullet renders whenever the client is idle and makes the
    # next call wait for that frame (measured under Xvfb: 6 s for 240 paced
    # steps). Stepping in batches, one per GUI frame, keeps real time.
    batch = node.simulation.steps_per_gui_frame if config.gui else 1
    if pacer is None and rate > 0.0:
        # Sleeping on the stop event: a signal ends the wait for the next step at once
        # (at real_time_factor 0.0001 a step is 42 s of wall time away).
        pacer = DeadlinePacer(batch / rate, sleep=stop.wait)
    advance = advance or node.advance_if_running
    yielded = clock()
    while not stop.is_set():
        if not advance(None if pacer is None else batch):
            stop.wait(0.005)
            if pacer is not None:
                pacer.reanchor()
            yielded = clock()
        elif pacer is not None and pacer.wait():
            yielded = clock()  # it slept: the other threads had the lock meanwhile
        elif clock() - yielded >= YIELD_EVERY_S:
            yield_()
            yielded = clock()


HELP_FLAGS = ('-h', '--help')


def wants_help(argv: Sequence[str]) -> bool:
    """
    Return True if ``-h`` or ``--help`` is among the arguments, wherever it is.

    Also after ``--ros-args``, where rcl would refuse it as an unknown ROS
    argument; a parameter value or a file name is never one of them on its own
    (``-p name:=--help`` is one argument).
    """
    return any(arg in HELP_FLAGS for arg in argv[1:])


def usage(argv0: str) -> str:
    """Return the ``--help`` text: usage, what the node does, and every parameter."""
    from r2d2_sim.sim.settings.reference import parameter_help  # standard library only
    prog = 'python -m r2d2_sim' if argv0.endswith('__main__.py') else os.path.basename(argv0)
    return (f'usage: {prog} [-h] [--ros-args [-p NAME:=VALUE]... [--params-file FILE]]\n\n'
            'Run the ROS 2 node r2d2_sim, R2D2 simulated in PyBullet, until SIGINT or\n'
            'SIGTERM. Parameters, parameter files and remaps (-r FROM:=TO) go after\n'
            '--ros-args; all parameters are read-only once the node runs. A bad value\n'
            'stops it with one error line and exit status 2.\n\n'
            f'example: {prog} --ros-args -p real_time_factor:=0.0 -p scan_rate:=0.0\n'
            f'two robots: {prog} --ros-args -p robots:="[a, b]" \\\n'
            '              -p b.initial_pose:="[2.0, 0.0, 3.1416]"\n\n'
            'parameters ("per robot": each robot of robots may set its own, NAME.parameter):\n'
            + parameter_help())


def main(args: Optional[Sequence[str]] = None, stop: Optional[threading.Event] = None) -> int:
    """
    Run the simulator node until SIGINT or SIGTERM, or until ``stop`` is set.

    With ``R2D2_SIM_PARENT_PID`` set (``ChildProcess`` sets it), it also
    stops when that process ends (:func:`r2d2_sim.client.end_with_parent`).
    Returns the exit status: 0 after a stop request or ``--help``, 2 when the
    node cannot start. ``args`` defaults to ``sys.argv``; ``stop`` to a new
    event set by SIGINT and SIGTERM (installed before rclpy and PyBullet are
    imported).
    """
    argv = sys.argv if args is None else list(args)
    if wants_help(argv):
        return _print_usage(argv)
    # Before PyBullet and Fast DDS allocate: spawns and deletes for hours must not
    # fragment the arenas with worlds built again (r2d2_sim/memory.py).
    keep_large_blocks_mapped()
    if stop is None:
        stop = _import_stopping_at_once()
    # A process of our own: trimesh's parsers without scipy, whose import stalls /clock.
    from r2d2_sim.sim.sdf.meshes import lean_mesh_imports
    lean_mesh_imports()
    import rclpy
    from r2d2_sim.client import end_with_parent
    from r2d2_sim.ros.node import NODE_NAME, StartupError
    try:
        # Started by a harness (ChildProcess): end with it, even if it is killed.
        end_with_parent()
    except StartupError as exc:
        print(f'{NODE_NAME}: error: {exc}', file=sys.stderr)
        return 2
    status = _init_ros(argv)
    if status is not None:
        return status
    try:
        if not stop.is_set():  # stopped while PyBullet was still loading
            return _run_node(stop)
        return 0
    except StartupError as exc:
        print(f'{NODE_NAME}: error: {exc}', file=sys.stderr)
        return 2
    finally:
        rclpy.try_shutdown()


def _print_usage(argv: Sequence[str]) -> int:
    try:
        sys.stdout.write(usage(argv[0] if argv else 'sim_node'))
        sys.stdout.flush()
    except BrokenPipeError:  # sim_node --help | head
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


def _import_stopping_at_once() -> threading.Event:
    """
    Import rclpy and PyBullet; a signal meanwhile ends the process at once (status 0).

    The imports take 0.25 s, seconds on a loaded machine, and a stop request
    would otherwise wait for them. Returns the event the signals set from then on.
    """
    stop = SignalledEvent()

    def exit_at_once(signum: int, frame: Optional[FrameType]) -> None:
        # Nothing is built yet: the process ends here. A SystemExit raised instead could
        # land in importlib's own callbacks, which print it as "Exception ignored" with
        # a traceback and go on (seen under load, 0.3 s after start).
        stop.set()
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # noqa: B902 (closed, or the signal came mid-write: reentrant)
                pass
        os._exit(0)
    signal.signal(signal.SIGINT, exit_at_once)
    signal.signal(signal.SIGTERM, exit_at_once)
    try:
        import rclpy  # noqa: F401
        import r2d2_sim.ros.node  # noqa: F401
    finally:
        stop_on_signals(stop)
    return stop


def _run_node(stop: threading.Event) -> int:
    """
    Build the node, serve it from threads and pace it here until ``stop`` is set.

    Return the exit status: 1 when a callback raised (the simulator stops: a
    node whose services or subscriptions died would go on with a clock and
    nothing else), else 0.
    """
    from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
    from r2d2_sim.ros.node import SimNode
    node = None
    executors: List[Executor] = []
    spinners: List[threading.Thread] = []
    failures: List[BaseException] = []
    try:
        node = SimNode(on_quit=stop.set)
        executors.append(SingleThreadedExecutor())
        executors[0].add_node(node)
        # Several robots: each robot's node, from start-up or spawned later, is
        # served beside the simulator's (whose lock guards them all).
        node.watch_robot_nodes(executors[0].add_node, executors[0].remove_node)
        if node.standard is not None:
            # Two threads: a long step_simulation (its own callback group) leaves
            # the standard's other services and cancel requests answered.
            executors.append(MultiThreadedExecutor(num_threads=2))
            executors[1].add_node(node.standard.node)
        # Logged before any request can start a step: rclpy's logger looks its
        # caller up through inspect (hundreds of file-system calls), which a
        # step holding the GIL in PyBullet would stretch to seconds.
        robots = node.robots
        what = (robots[0].robot.source if len(robots) == 1 else
                f'{len(robots)} robots ({", ".join(r.namespace for r in robots)})')
        node.get_logger().info(
            f'simulating {what} at {node.config.physics_rate_hz:g} Hz, real time factor '
            f'{node.config.real_time_factor:g}' + (', paused' if node.paused else ''))
        for executor in executors:
            spinners.append(threading.Thread(target=_spin, args=(executor, stop, failures),
                                             daemon=True))
            spinners[-1].start()
        run_paced(node, stop)
    finally:
        stop.set()
        if node is not None and node.standard is not None:
            # A step_simulation under way ends at its next chunk, before physics
            # is closed under it (rclpy's Executor.shutdown does not wait for it).
            node.standard.stop()
        for spinner in spinners:
            spinner.join(timeout=1.0)
        # Only now, with no thread spinning: shutting an executor down under a
        # spinning thread races in rclpy 7.1 (a callback handler made during
        # shutdown fails with AttributeError on the destroyed guard condition).
        for executor in executors:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
    return 1 if failures else 0


def _init_ros(argv: List[str]) -> Optional[int]:
    """Initialise rclpy without its signal handlers; an exit status (2) on a one-line error."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions
    from rclpy.utilities import remove_ros_args
    from r2d2_sim.ros.node import NODE_NAME
    problem = ros_start_problem(argv)
    if problem is not None:
        print(f'{NODE_NAME}: error: {problem}', file=sys.stderr)
        return 2
    try:
        rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
        # sim_node takes only ROS arguments: '-p x:=1' without --ros-args
        # would otherwise be ignored and the node run on its defaults.
        unexpected = remove_ros_args(argv)[1:]
    except Exception as exc:  # rclpy reports bad --ros-args as assorted errors
        print(f'{NODE_NAME}: error: cannot initialise ROS: {exc}', file=sys.stderr)
        return 2
    if unexpected:
        print(f'{NODE_NAME}: error: unexpected arguments {" ".join(unexpected)}: parameters '
              'and remaps go after --ros-args (sim_node --ros-args -p name:=value)',
              file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    return None


def _spin(executor: 'Executor', stop: threading.Event, failures: List[BaseException]) -> None:
    """
    Serve callbacks until ``stop`` is set (checked at least every SPIN_POLL_S).

    A callback that raises stops the simulator: its traceback (a fault of
    the simulator's own) and one line saying so, the exception in ``failures``.
    """
    from rclpy.executors import ExternalShutdownException
    from r2d2_sim.ros.node import NODE_NAME
    try:
        while not stop.is_set():
            executor.spin_once(timeout_sec=SPIN_POLL_S)
    except ExternalShutdownException:
        pass
    except Exception as exc:  # noqa: B902 (any fault of a callback ends the node, said once)
        failures.append(exc)
        traceback.print_exc()
        print(f'{NODE_NAME}: error: a callback raised {type(exc).__name__}: {exc}; stopping',
              file=sys.stderr)
    finally:
        stop.set()


if __name__ == '__main__':
    sys.exit(main())
