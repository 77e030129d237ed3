"""
``demo``: start the simulator, replay the tutorial's manoeuvre, plot the trajectory.

Runs ``sim_node`` in a process of its own (through the public testing API,
:class:`~r2d2_sim.testing.SimProcess`) and, in this process, a driver node
that sends ``cmd_vel``: settle, turn about 90 degrees in place, drive forward,
stop. Everything is timed in simulated seconds, read from the stamps of
``ground_truth``. At real time the simulator runs on its own clock, publishing
after every physics step, and the driver follows; with ``--real-time-factor
0`` the demo steps the paused simulator one control period (1/60 s) at a
time and answers each state before the next step (lockstep), so the run is
the same, bit for bit, however busy the machine is. At the end it writes
odometry against ground truth as a PNG, with the last laser scan and a head
camera snapshot, and the simulator records every output of the run into
``run.mcap`` beside it.
"""

import argparse
import math
import os
from pathlib import Path
import signal
import sys
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Sequence, TYPE_CHECKING

from geometry_msgs.msg import Twist
import rclpy
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor

from r2d2_sim.apps.cli import (
    domain_id_arg, EXIT_INTERRUPTED, init_ros, non_negative_number, non_ros_args,
    raise_if_stopped, stop_on_signals)
from r2d2_sim.apps.manoeuvre import (  # noqa: F401 (the model's names, importable from the demo)
    command_at, format_progress, MANOEUVRE, manoeuvre_duration_s, ManoeuvreDriver, Phase,
    phase_at)
from r2d2_sim.apps.plots import write_camera_snapshot, write_trajectory_plot
from r2d2_sim.client import spin_until, UNKNOWN_NODE_NAME
from r2d2_sim.sim.settings.table import REAL_TIME_FACTOR

if TYPE_CHECKING:  # the testing API is imported only when a simulator is started
    from r2d2_sim.testing import SimProcess

# Wall-clock seconds for the simulator to start and for its topics to reach the driver.
STARTUP_TIMEOUT_S = 10.0
# Wall-clock seconds without ground_truth after which the simulator is taken as hung.
STALL_TIMEOUT_S = 10.0
# In lockstep the simulator publishes at this rate (simulated Hz): each period
# is one ~/step call, so phases start on a 1/60 s grid.
LOCKSTEP_PUBLISH_RATE_HZ = 60.0
# In lockstep, wall-clock seconds to wait for a state early in the settle phase,
# which a subscriber matched late never gets.
SETTLE_WAIT_S = 0.2
# Wall-clock seconds the simulator gets to exit after SIGINT before it is killed.
STOP_TIMEOUT_S = 5.0
PLOT_NAME = 'trajectory.png'
# How long to look for another simulator on the domain before starting ours (s).
OTHER_SIMULATOR_WAIT_S = 0.5
# How often to look again while ours runs (wall s): discovery can take longer.
OTHER_SIMULATOR_CHECK_S = 0.1
# The demo's own simulator, named so that any other /clock publisher is told apart.
SIMULATOR_NODE_NAME = f'r2d2_sim_demo_{os.getpid()}'
ANOTHER_SIMULATOR = ('another simulator publishes /clock on this ROS domain: stop it, or give '
                     'the demo a domain of its own (--domain-id N)')
# The world the demo drives in: walls and boxes for the laser scan in the plot.
DEMO_WORLD = 'package://r2d2_sim/urdf/room.urdf'
SNAPSHOT_NAME = 'head_camera.png'
RECORDING_NAME = 'run.mcap'
# A few head-camera images per simulated second are plenty for the final snapshot.
CAMERA_RATE_HZ = 2.0


class DemoError(RuntimeError):
    """The demo cannot go on: the message is its one-line reason (with the simulator's tail)."""


class OtherSimulatorGuard:
    """
    Another simulator on the demo's domain: found in the graph, or by ground_truth going back.

    A /clock publisher that is not ours would take our cmd_vel and interleave
    its poses with ours. An endpoint can be discovered before its node's name
    (rmw says _NODE_NAME_UNKNOWN_): it is not counted until named.
    """

    def __init__(self, driver: ManoeuvreDriver, own_name: str) -> None:
        self._driver = driver
        self._own_name = own_name
        self._next_check_s = 0.0
        self._seen = False

    def found(self) -> bool:
        """Return True once another simulator shows (the graph looked at every 0.1 s at most)."""
        driver = self._driver
        now = time.monotonic()
        if not self._seen and now >= self._next_check_s:
            self._next_check_s = now + OTHER_SIMULATOR_CHECK_S
            self._seen = any(info.node_name not in (self._own_name, UNKNOWN_NODE_NAME)
                             for info in driver.get_publishers_info_by_topic('/clock'))
        return self._seen or driver.time_went_back is not None

    def check(self) -> None:
        """Raise DemoError naming the other simulator when one shows."""
        if self.found():
            went_back = self._driver.time_went_back
            prefix = '' if went_back is None else (
                'ground_truth went back in time ({:.3f} s -> {:.3f} s): '.format(*went_back))
            raise DemoError(prefix + ANOTHER_SIMULATOR)


def real_time_factor_arg(text: str) -> float:
    """Parse --real-time-factor as the simulator's real_time_factor takes it (argparse type)."""
    value = non_negative_number(text)
    bounds = REAL_TIME_FACTOR
    if value != 0.0 and not bounds.low <= value <= bounds.high:
        raise argparse.ArgumentTypeError(
            f'must be 0 ({bounds.zero}) or in [{bounds.low:g}, {bounds.high:g}], got {text!r}')
    return value


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser (ROS arguments are removed before it runs)."""
    parser = argparse.ArgumentParser(
        prog='demo',
        description='Start the R2D2 simulator, turn ~90 degrees, drive forward, stop, and '
                    'plot wheel odometry against ground truth.',
        epilog='The demo takes no --ros-args: it sets its simulator\'s parameters itself. '
               'For your own, run sim_node --ros-args -p NAME:=VALUE ... and send commands '
               'with drive.')
    parser.add_argument('--output-dir', default='demo_output', metavar='DIR',
                        help=f'where to write the plot {PLOT_NAME} and the camera snapshot '
                             f'{SNAPSHOT_NAME} (both replaced) and the recording '
                             f'{RECORDING_NAME} (run-2.mcap, run-3.mcap... if it exists: none '
                             'is overwritten) (default ./demo_output)')
    parser.add_argument('--real-time-factor', type=real_time_factor_arg, default=1.0,
                        metavar='X', help='simulated seconds per wall second, 1e-6 to 1000; '
                                          '0 runs as fast as possible, in lockstep (default 1)')
    parser.add_argument('--domain-id', type=domain_id_arg, default=None, metavar='N',
                        help='ROS_DOMAIN_ID for the simulator and the driver '
                             '(default: the environment\'s)')
    return parser


def _error(text: str) -> None:
    print(f'demo: error: {text}', file=sys.stderr, flush=True)


def _interrupt_on_signals() -> None:
    """Make SIGINT and SIGTERM raise KeyboardInterrupt, for code that does not spin."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.default_int_handler)


def _start_simulator(real_time_factor: float, domain_id: int, recording: Path
                     ) -> 'SimProcess':
    """Start sim_node in the room, recording (paused for lockstep at 0); DemoError if not."""
    from r2d2_sim.testing import HarnessError, SimProcess
    # Lockstep: paused, one ~/step per period of LOCKSTEP_PUBLISH_RATE_HZ, and
    # commands held until the next (sent on change only, so a few round trips).
    lockstep: Dict[str, Any] = {
        'start_paused': True, 'publish_rate': LOCKSTEP_PUBLISH_RATE_HZ,
        'cmd_vel_timeout': 0.0} if real_time_factor == 0.0 else {}
    try:
        return SimProcess(node_name=SIMULATOR_NODE_NAME, domain_id=domain_id, lease=False,
                          timeout_s=STARTUP_TIMEOUT_S, world=DEMO_WORLD,
                          real_time_factor=float(real_time_factor),
                          camera_rate=CAMERA_RATE_HZ, record=str(recording), **lockstep)
    except HarnessError as exc:
        raise DemoError(str(exc)) from None


def _spin_or_fail(executor: Executor, condition: Callable[[], bool], what: str,
                  simulator: 'SimProcess', guard: OtherSimulatorGuard, stop: threading.Event,
                  timeout_s: float) -> None:
    """Spin until ``condition``; DemoError (another simulator, exit, deadline) otherwise."""
    done = spin_until(executor, condition, timeout_s,
                      abort=lambda: stop.is_set() or simulator.process.exited() or guard.found())
    raise_if_stopped(stop)
    guard.check()
    if simulator.process.exited():
        raise DemoError(simulator.process.failure_message(f'the simulator stopped {what}'))
    if not done:
        raise DemoError(simulator.process.failure_message(f'no {what} within {timeout_s:g} s'))


def _run_real_time(driver: ManoeuvreDriver, executor: Executor, simulator: 'SimProcess',
                   guard: OtherSimulatorGuard, stop: threading.Event) -> None:
    """Let the simulator run on its clock; the driver answers each ground_truth."""
    _spin_or_fail(executor, driver.connected, 'ground_truth/odom or cmd_vel subscriber',
                  simulator, guard, stop, STARTUP_TIMEOUT_S)
    driver.begin()
    while not driver.done:
        _spin_or_fail(executor, lambda: driver.done or time.monotonic()
                      - driver.last_truth_wall_s > STALL_TIMEOUT_S,
                      'ground_truth', simulator, guard, stop, 0.1 + STALL_TIMEOUT_S)
        if not driver.done:
            raise DemoError(simulator.process.failure_message(
                f'no ground_truth for {STALL_TIMEOUT_S:g} s: the simulator seems stuck'))


def _run_lockstep(driver: ManoeuvreDriver, executor: Executor, simulator: 'SimProcess',
                  guard: OtherSimulatorGuard, stop: threading.Event,
                  commands: List[Twist]) -> None:
    """
    Step the paused simulator one control period at a time; answer each state before the next.

    The manoeuvre is timed from simulated time 0, so every run starts it at
    the same step. The first states may be published before the simulator
    has matched the driver's subscription (discovery runs in parallel), and
    are then never delivered: during the settle phase, when the driver only
    holds the robot still, a state that does not come is not waited for.
    """
    from r2d2_sim.testing import HarnessError
    settle_ns = round(driver.phases[0].duration_s / 2 * 1e9) if driver.phases else 0
    _spin_or_fail(executor, driver.linked, 'link between the driver and the simulator',
                  simulator, guard, stop, STARTUP_TIMEOUT_S)
    driver.begin(start_s=0.0)
    while not driver.done:
        try:
            wanted = simulator.step()['sim_time_ns']
        except HarnessError as exc:
            raise DemoError(simulator.process.failure_message(str(exc))) from None
        if wanted < settle_ns:
            spin_until(executor, lambda: driver.handled_ns >= wanted, SETTLE_WAIT_S)
        else:
            _spin_or_fail(executor, lambda: driver.handled_ns >= wanted, 'ground_truth/odom',
                          simulator, guard, stop, STALL_TIMEOUT_S)
        while commands:  # what the driver said to that state, taken before the next step
            simulator.send_cmd_vel(twist=commands.pop(0))


def free_recording(output_dir: Path) -> Path:
    """
    Return where this run records: ``run.mcap``, or the first of ``run-2.mcap``... not taken.

    sim_node's ``record`` refuses a file that exists (it could be anyone's),
    and the demo run twice into its default folder must work: each run keeps
    its own recording, and none of them, or anything else there, is replaced.
    """
    stem, suffix = os.path.splitext(RECORDING_NAME)
    path, number = output_dir / RECORDING_NAME, 1
    while os.path.lexists(path):
        number += 1
        path = output_dir / f'{stem}-{number}{suffix}'
    return path


def _write_pictures(driver: ManoeuvreDriver, output_dir: Path) -> None:
    plot = write_trajectory_plot(output_dir.absolute() / PLOT_NAME, driver.odom_xy,
                                 driver.truth_xy, driver.scan_xy)
    print(f'trajectory plot: {plot}', flush=True)
    if driver.image is not None:
        snapshot = write_camera_snapshot(output_dir.absolute() / SNAPSHOT_NAME, driver.image)
        print(f'head camera snapshot: {snapshot}', flush=True)
    else:
        print('head camera snapshot: none received', flush=True)


def _run(options: argparse.Namespace, stop: threading.Event) -> int:
    """Drive the manoeuvre against a simulator of the demo's own; return the exit status."""
    lockstep = options.real_time_factor == 0.0
    commands: List[Twist] = []
    driver = ManoeuvreDriver(send=commands.append, resend_period_s=math.inf) if lockstep \
        else ManoeuvreDriver()
    executor = SingleThreadedExecutor()
    executor.add_node(driver)
    simulator = None
    guard = OtherSimulatorGuard(driver, SIMULATOR_NODE_NAME)
    try:
        # Discovery takes 5-200 ms here: look for another simulator before starting
        # our own (and again while ours runs, for a machine too busy to find it in time).
        found = spin_until(executor, lambda: driver.count_publishers('/clock') > 0,
                           OTHER_SIMULATOR_WAIT_S, abort=stop.is_set)
        raise_if_stopped(stop)
        if found:
            raise DemoError(ANOTHER_SIMULATOR)
        recording = options.recording.absolute()
        simulator = _start_simulator(options.real_time_factor, options.domain_id, recording)
        raise_if_stopped(stop)
        started_s = time.monotonic()
        if lockstep:
            _run_lockstep(driver, executor, simulator, guard, stop, commands)
        else:
            _run_real_time(driver, executor, simulator, guard, stop)
        # Done spinning: from here on a signal may interrupt wherever it lands.
        _interrupt_on_signals()
        raise_if_stopped(stop)  # one that came before the switch
        print(f'simulated {driver.elapsed_s:.1f} s in {time.monotonic() - started_s:.1f} s '
              'of wall time')
        truth = driver.truth
        assert truth is not None  # done: the driver answered a state, the last one here
        print(f'final ground truth: x={truth.x_m!r} y={truth.y_m!r} yaw={truth.yaw_rad!r}')
        try:
            _write_pictures(driver, options.output_dir)
        except OSError as exc:  # a directory in the way, a full disk
            raise DemoError(f'cannot write the pictures: {exc}') from None
        # Finished only once the simulator closes it, after the manoeuvre.
        if simulator.stop(STOP_TIMEOUT_S).returncode == 0:
            print(f'recording: {recording} (replay it: replay {recording}; or open it in '
                  'Foxglove)', flush=True)
        return 0
    except DemoError as exc:
        if stop.is_set():
            # Ctrl-C in a terminal reaches the whole process group: the simulator
            # exits too, often while it starts, and that is the interruption.
            raise KeyboardInterrupt from None
        _error(str(exc))
        return 1
    finally:
        executor.shutdown()
        driver.destroy_node()
        if simulator is not None:
            # A second Ctrl-C (or SIGTERM) while the simulator stops cuts the wait short.
            _interrupt_on_signals()
            simulator.stop(STOP_TIMEOUT_S)


def main(args: Optional[Sequence[str]] = None) -> int:
    """Run the demo; return 0 on success, 1 if the simulator fails, 130 on Ctrl-C."""
    argv = list(sys.argv if args is None else args)
    parser = build_parser()
    own = non_ros_args(argv, 'demo')
    if len(own) != len(argv) - 1:
        # They would configure the driver node, not the simulator, in silence.
        parser.error('the demo takes no ROS arguments (--ros-args ...): it sets its '
                     'simulator\'s parameters itself; run sim_node --ros-args ... for yours')
    options = parser.parse_args(own)
    options.output_dir = Path(options.output_dir)
    try:
        options.output_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _error(f'cannot create the output directory: {exc}')
        return 1
    options.recording = free_recording(options.output_dir)
    # Discovery must stay on this host; set before rclpy.init and inherited by the child.
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    if options.domain_id is not None:
        os.environ['ROS_DOMAIN_ID'] = str(options.domain_id)
    try:
        options.domain_id = int(os.environ.get('ROS_DOMAIN_ID', '').strip() or 0)
    except ValueError:
        _error(f'ROS_DOMAIN_ID must be an integer, got {os.environ["ROS_DOMAIN_ID"]!r}')
        return 2
    # SIGINT and SIGTERM only set this event from here on; the loops check it.
    stop = stop_on_signals()
    if not init_ros(argv, 'demo'):
        return 2
    try:
        return _run(options, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        print('demo: interrupted, stopping the simulator', file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
