"""
``demo``: start the simulator, replay the tutorial's manoeuvre, plot the trajectory.

Runs ``python -m r2d2_sim`` as a child process and, in this process, a
driver node that sends ``cmd_vel``: settle, turn about 90 degrees in place,
drive forward, stop. Everything is timed in simulated seconds, read from the
stamps of ``ground_truth`` (published after every physics step), so the result
does not depend on ``--real-time-factor`` or on how busy the machine is.
At the end it writes odometry against ground truth as a PNG.
"""

import argparse
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time
from typing import List, NamedTuple, Optional, Sequence, Tuple

from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import Image, LaserScan

from r2d2_sim.cli import non_negative_number, non_ros_args
from r2d2_sim.sim_node import raise_if_stopped, stop_on_signals
from r2d2_sim.testing import Pose2D, pose_from_odometry, ros_child_env, spin_until

NODE_NAME = 'r2d2_demo'
# Wall-clock seconds to wait for the simulator's topics after starting it.
STARTUP_TIMEOUT_S = 10.0
# Wall-clock seconds without ground_truth after which the simulator is taken as hung.
STALL_TIMEOUT_S = 10.0
# Wall-clock seconds the simulator gets to exit after SIGINT before it is killed.
STOP_TIMEOUT_S = 5.0
# cmd_vel is re-sent at this rate of simulated time (the simulator brakes after 0.5 s).
COMMAND_RATE_HZ = 20.0
# Lines of the simulator's output shown when it fails.
LOG_TAIL_LINES = 10
EXIT_INTERRUPTED = 130
PLOT_NAME = 'trajectory.png'
# How long to look for another simulator on the domain before starting ours (s).
OTHER_SIMULATOR_WAIT_S = 0.5
# How often to look again while ours runs (wall s): discovery can take longer.
OTHER_SIMULATOR_CHECK_S = 0.1
# The demo's own simulator, named so that any other /clock publisher is told apart.
SIMULATOR_NODE_NAME = f'r2d2_sim_demo_{os.getpid()}'
# What rmw reports as the node of an endpoint whose node it has not yet discovered.
UNKNOWN_NODE_NAME = '_NODE_NAME_UNKNOWN_'
ANOTHER_SIMULATOR = ('another simulator publishes /clock on this ROS domain: stop it, or give '
                     'the demo a domain of its own (--domain-id N)')
# The world the demo drives in: walls and boxes for the laser scan in the plot.
DEMO_WORLD = 'package://r2d2_sim/urdf/room.urdf'
SNAPSHOT_NAME = 'head_camera.png'
# A few head-camera images per simulated second are plenty for the final snapshot.
CAMERA_RATE_HZ = 2.0


class Phase(NamedTuple):
    """One leg of the manoeuvre: a constant twist held for a span of simulated time."""

    name: str
    duration_s: float
    linear_m_s: float
    angular_rad_s: float


# The tutorial's manoeuvre: settle on the wheels, turn ~90 degrees CCW in place,
# drive 0.9 m forward (along world +y after the turn), then stand still.
MANOEUVRE: Tuple[Phase, ...] = (
    Phase('settle', 1.0, 0.0, 0.0),
    Phase('turn', math.pi / 2.0, 0.0, 1.0),
    Phase('forward', 3.0, 0.3, 0.0),
    Phase('stop', 1.0, 0.0, 0.0),
)


def manoeuvre_duration_s(phases: Sequence[Phase] = MANOEUVRE) -> float:
    """Return the total simulated time of a manoeuvre."""
    return sum(phase.duration_s for phase in phases)


def phase_at(t_s: float, phases: Sequence[Phase] = MANOEUVRE) -> Optional[Phase]:
    """Return the phase active at ``t_s`` seconds after the start (None outside)."""
    if t_s < 0.0:
        return None
    end_s = 0.0
    for phase in phases:
        end_s += phase.duration_s
        if t_s < end_s:
            return phase
    return None


def command_at(t_s: float, phases: Sequence[Phase] = MANOEUVRE) -> Tuple[float, float]:
    """Return the (linear.x m/s, angular.z rad/s) command at ``t_s``; zero outside."""
    phase = phase_at(t_s, phases)
    if phase is None:
        return 0.0, 0.0
    return phase.linear_m_s, phase.angular_rad_s


def format_progress(t_s: float, odom: Pose2D, truth: Pose2D) -> str:
    """Return one progress line: time, odometry pose and ground-truth pose."""
    def pose(p: Pose2D) -> str:
        return f'x={p.x_m:+.3f} y={p.y_m:+.3f} yaw={math.degrees(p.yaw_rad):+6.1f} deg'
    return f't={t_s:5.1f} s  odom {pose(odom)} | truth {pose(truth)}'


def scan_points_xy(scan: LaserScan, pose: Pose2D,
                   laser_offset_xy: Tuple[float, float] = (0.0, 0.0)) -> List[Tuple[float, float]]:
    """
    Return a scan's finite returns as world x-y points, seen from ``pose`` (the base's).

    ``laser_offset_xy`` is the laser's position in the base frame. Readings
    of +-inf (REP-117: no return, too close) have no point.
    """
    cos_yaw, sin_yaw = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    origin_x = pose.x_m + cos_yaw * laser_offset_xy[0] - sin_yaw * laser_offset_xy[1]
    origin_y = pose.y_m + sin_yaw * laser_offset_xy[0] + cos_yaw * laser_offset_xy[1]
    points = []
    for i, r in enumerate(scan.ranges):
        if math.isfinite(r):
            angle = pose.yaw_rad + scan.angle_min + i * scan.angle_increment
            points.append((origin_x + r * math.cos(angle), origin_y + r * math.sin(angle)))
    return points


def write_trajectory_plot(path, odom_xy: Sequence[Tuple[float, float]],
                          truth_xy: Sequence[Tuple[float, float]],
                          scan_xy: Sequence[Tuple[float, float]] = ()) -> Path:
    """
    Plot odometry against ground truth in the x-y plane as a PNG; return its path.

    ``scan_xy`` (the last laser scan, in the world frame) is drawn as dots.

    Uses matplotlib's Agg canvas directly (no pyplot), so it needs no display
    and leaves matplotlib's global backend alone.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    path = Path(path)
    figure = Figure(figsize=(6.4, 7.0), dpi=100, layout='constrained')
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    if scan_xy:
        axes.plot([p[0] for p in scan_xy], [p[1] for p in scan_xy], '.', color='tab:green',
                  markersize=3, label='last laser scan')
    for points, label, style, colour in ((truth_xy, 'ground truth (world)', '-', 'tab:blue'),
                                         (odom_xy, 'wheel odometry (odom)', '--', 'tab:orange')):
        if not points:
            continue
        xs = [p[0] for p in points]
        ys = [p[1] for p in points]
        axes.plot(xs, ys, style, color=colour, linewidth=2, label=label)
        axes.plot(xs[:1], ys[:1], 'o', color=colour, markersize=8)
        axes.plot(xs[-1:], ys[-1:], 's', color=colour, markersize=8)
    # Marker legend entries, drawn off-data so they only label the symbols.
    axes.plot([], [], 'o', color='grey', label='start')
    axes.plot([], [], 's', color='grey', label='end')
    axes.set_aspect('equal', adjustable='datalim')
    axes.set_xlabel('x (m)')
    axes.set_ylabel('y (m)')
    axes.set_title('R2D2 demo in the room: wheel odometry vs ground truth')
    axes.grid(True, alpha=0.4)
    axes.legend(loc='upper center', bbox_to_anchor=(0.5, -0.1), ncols=2)
    figure.savefig(path, format='png')
    return path


def write_camera_snapshot(path, image: Image) -> Path:
    """Write an rgb8 sensor_msgs/Image as a PNG and return its path."""
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib import pyplot
    import numpy
    if image.encoding != 'rgb8':
        raise ValueError(f'expected an rgb8 image, got {image.encoding!r}')
    rows = numpy.frombuffer(bytes(image.data), dtype=numpy.uint8)
    pixels = rows.reshape(image.height, image.step)[:, :image.width * 3]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    pyplot.imsave(path, pixels.reshape(image.height, image.width, 3))
    return path


def _ros_double(value: float) -> str:
    """Format a float so a ROS parameter override parses it as a double."""
    text = repr(float(value))
    if '.' not in text and 'e' in text:
        text = text.replace('e', '.0e')
    return text


class Simulator:
    """The simulator as a child process, its output kept in a temporary file."""

    def __init__(self, command: Sequence[str], env: Optional[dict] = None) -> None:
        self.command = list(command)
        self.env = env
        self.process: Optional[subprocess.Popen] = None
        self._log = None

    @classmethod
    def for_real_time_factor(cls, real_time_factor: float, env: dict) -> 'Simulator':
        """Build the command for ``python -m r2d2_sim`` at the given speed."""
        return cls([sys.executable, '-m', 'r2d2_sim', '--ros-args',
                    '-r', f'__node:={SIMULATOR_NODE_NAME}',
                    '-p', f'world:={DEMO_WORLD}',
                    '-p', f'real_time_factor:={_ros_double(real_time_factor)}',
                    '-p', f'camera_rate:={_ros_double(CAMERA_RATE_HZ)}'], env)

    def start(self) -> None:
        """Start the process; stdout and stderr go to a temporary file."""
        self._log = tempfile.TemporaryFile()
        self.process = subprocess.Popen(self.command, env=self.env, stdin=subprocess.DEVNULL,
                                        stdout=self._log, stderr=subprocess.STDOUT)

    def exited(self) -> bool:
        """Return True once the process has ended."""
        return self.process is not None and self.process.poll() is not None

    def log_tail(self, lines: int = LOG_TAIL_LINES) -> List[str]:
        """Return the last non-empty lines of the process's output."""
        if self._log is None:
            return []
        self._log.flush()
        self._log.seek(0)
        text = self._log.read().decode('utf-8', errors='replace')
        return [line for line in text.splitlines() if line.strip()][-lines:]

    def failure_message(self, what: str) -> str:
        """Return a readable error: ``what``, the exit status if any, and the output tail."""
        if self.exited():
            what += f' (the simulator exited with status {self.process.returncode})'
        tail = self.log_tail()
        if tail:
            what += ':\n' + '\n'.join('  simulator: ' + line for line in tail)
        return what

    def stop(self, timeout_s: float = STOP_TIMEOUT_S) -> Optional[int]:
        """SIGINT, wait up to ``timeout_s``, kill as a last resort; return the exit status."""
        process = self.process
        if process is None:
            return None
        try:
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
                try:
                    process.wait(timeout=timeout_s)
                except (subprocess.TimeoutExpired, KeyboardInterrupt):
                    # Hung, or the user pressed Ctrl-C again: do not wait any longer.
                    process.kill()
                    process.wait()
            return process.returncode
        finally:
            if self._log is not None:
                self._log.close()
                self._log = None


class ManoeuvreDriver(Node):
    """
    Sends the manoeuvre on ``cmd_vel``, timed by the stamps of ``ground_truth``.

    Records both trajectories from :meth:`begin` on and prints a progress line
    every simulated second; ``done`` turns True after the last phase.
    """

    def __init__(self, phases: Sequence[Phase] = MANOEUVRE, out=sys.stdout,
                 context=None) -> None:
        super().__init__(NODE_NAME, context=context)
        self.phases = tuple(phases)
        self.total_s = manoeuvre_duration_s(self.phases)
        self._out = out
        self._cmd_pub = self.create_publisher(Twist, 'cmd_vel', 10)
        self.create_subscription(Odometry, 'odom', self._on_odom, 10)
        self.create_subscription(Odometry, 'ground_truth', self._on_truth, 10)
        self.create_subscription(Image, 'camera/image_raw', self._on_image, 2)
        self.create_subscription(LaserScan, 'scan', self._on_scan, 2)
        self.image: Optional[Image] = None
        self.scan_xy: List[Tuple[float, float]] = []
        self.odom: Optional[Pose2D] = None
        self.truth: Optional[Pose2D] = None
        self.odom_xy: List[Tuple[float, float]] = []
        self.truth_xy: List[Tuple[float, float]] = []
        self.last_truth_wall_s = time.monotonic()
        self.done = False
        # (from s, to s) once a ground_truth stamp is older than the one before.
        self.time_went_back: Optional[Tuple[float, float]] = None
        self._recording = False
        self._start_s: Optional[float] = None
        self._phase: Optional[Phase] = None
        self._last_command: Optional[Tuple[float, float]] = None
        self._last_command_s = -math.inf
        self._next_report_s = 0.0

    def connected(self) -> bool:
        """Return True once the simulator publishes both poses and listens to cmd_vel."""
        return (self.odom is not None and self.truth is not None
                and self._cmd_pub.get_subscription_count() > 0)

    def begin(self) -> None:
        """Start the manoeuvre at the stamp of the next ground_truth message."""
        self._recording = True

    @property
    def elapsed_s(self) -> float:
        """Return the simulated seconds since the manoeuvre started (0 before)."""
        if self._start_s is None or self.truth is None:
            return 0.0
        return self.truth.stamp_s - self._start_s

    def _on_image(self, msg: Image) -> None:
        self.image = msg

    def _on_scan(self, msg: LaserScan) -> None:
        # Scans come at 10 Hz, ground truth every step: the latest truth is the
        # pose the scan was taken from, give or take a step.
        if self.truth is not None:
            self.scan_xy = scan_points_xy(msg, self.truth)

    def _on_odom(self, msg: Odometry) -> None:
        self.odom = pose_from_odometry(msg)
        if self._start_s is not None and not self.done:
            self.odom_xy.append((self.odom.x_m, self.odom.y_m))

    def _on_truth(self, msg: Odometry) -> None:
        if self.time_went_back is not None:
            return
        truth = pose_from_odometry(msg)
        if self.truth is not None and truth.stamp_s < self.truth.stamp_s:
            # Two simulators on one domain interleave their stamps; a run timed
            # by them means nothing.
            self.time_went_back = (self.truth.stamp_s, truth.stamp_s)
            return
        self.truth = truth
        self.last_truth_wall_s = time.monotonic()
        if not self._recording or self.done:
            return
        if self._start_s is None:
            self._start_s = self.truth.stamp_s
            if self.odom is not None:
                self.odom_xy.append((self.odom.x_m, self.odom.y_m))
        self.truth_xy.append((self.truth.x_m, self.truth.y_m))
        t_s = self.elapsed_s
        self._report(t_s)
        if t_s >= self.total_s:
            self._send((0.0, 0.0), t_s)
            self._print(format_progress(t_s, self.odom, self.truth))
            self.done = True
            return
        phase = phase_at(t_s, self.phases)
        if phase is not self._phase:
            self._phase = phase
            self._print(f'-- {phase.name}: linear.x {phase.linear_m_s:+.2f} m/s, angular.z '
                        f'{phase.angular_rad_s:+.2f} rad/s for {phase.duration_s:.2f} s')
        self._send((phase.linear_m_s, phase.angular_rad_s), t_s)

    def _report(self, t_s: float) -> None:
        if t_s >= self._next_report_s:
            self._print(format_progress(t_s, self.odom, self.truth))
            self._next_report_s = math.floor(t_s) + 1.0

    def _send(self, command: Tuple[float, float], t_s: float) -> None:
        """Publish on change, and otherwise at COMMAND_RATE_HZ of simulated time."""
        if command == self._last_command and t_s - self._last_command_s < 1.0 / COMMAND_RATE_HZ:
            return
        msg = Twist()
        msg.linear.x, msg.angular.z = command
        self._cmd_pub.publish(msg)
        self._last_command = command
        self._last_command_s = t_s

    def _print(self, line: str) -> None:
        print(line, file=self._out, flush=True)


def _domain_id(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'must be an integer, got {text!r}') from None
    if not 0 <= value <= 232:
        raise argparse.ArgumentTypeError(f'must be in 0..232, got {text!r}')
    return value


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser (ROS arguments are removed before it runs)."""
    parser = argparse.ArgumentParser(
        prog='demo',
        description='Start the R2D2 simulator, turn ~90 degrees, drive forward, stop, and '
                    'plot wheel odometry against ground truth.')
    parser.add_argument('--output-dir', default='demo_output', metavar='DIR',
                        help='where to write the trajectory plot (default ./demo_output)')
    parser.add_argument('--real-time-factor', type=non_negative_number, default=1.0,
                        metavar='X', help='simulated seconds per wall second; 0 runs as '
                                          'fast as possible (default 1)')
    parser.add_argument('--domain-id', type=_domain_id, default=None, metavar='N',
                        help='ROS_DOMAIN_ID for the simulator and the driver '
                             '(default: the environment\'s)')
    return parser


def _error(text: str) -> None:
    print(f'demo: error: {text}', file=sys.stderr, flush=True)


def _interrupt_on_signals() -> None:
    """Make SIGINT and SIGTERM raise KeyboardInterrupt, for code that does not spin."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.default_int_handler)


def _another_simulator_message(node: ManoeuvreDriver) -> str:
    if node.time_went_back is None:
        return ANOTHER_SIMULATOR
    return ('ground_truth went back in time ({:.3f} s -> {:.3f} s): '.format(
        *node.time_went_back) + ANOTHER_SIMULATOR)


def _run(node: ManoeuvreDriver, executor, simulator: Simulator, output_dir: Path,
         stop) -> int:
    def another_simulator() -> bool:
        # A /clock publisher found only now (discovery took longer than
        # OTHER_SIMULATOR_WAIT_S) that is not ours would take our cmd_vel and
        # interleave its poses with ours. An endpoint can be discovered before
        # its node's name (rmw says _NODE_NAME_UNKNOWN_): not counted yet.
        return node.time_went_back is not None or any(
            info.node_name not in (SIMULATOR_NODE_NAME, UNKNOWN_NODE_NAME)
            for info in node.get_publishers_info_by_topic('/clock'))

    started = spin_until(
        executor, node.connected, STARTUP_TIMEOUT_S,
        abort=lambda: stop.is_set() or simulator.exited() or another_simulator())
    raise_if_stopped(stop)
    if another_simulator():
        _error(_another_simulator_message(node))
        return 1
    if not started:
        _error(simulator.failure_message(
            f'no ground_truth/odom from the simulator, or no cmd_vel subscriber, within '
            f'{STARTUP_TIMEOUT_S:g} s'))
        return 1
    node.begin()
    started_s = next_check_s = time.monotonic()
    while not node.done:
        executor.spin_once(timeout_sec=0.1)
        raise_if_stopped(stop)
        if time.monotonic() >= next_check_s:
            next_check_s = time.monotonic() + OTHER_SIMULATOR_CHECK_S
            if another_simulator():
                _error(_another_simulator_message(node))
                return 1
        if simulator.exited():
            _error(simulator.failure_message(
                f'the simulator stopped at t={node.elapsed_s:.1f} s of the manoeuvre'))
            return 1
        if time.monotonic() - node.last_truth_wall_s > STALL_TIMEOUT_S:
            _error(simulator.failure_message(
                f'no ground_truth for {STALL_TIMEOUT_S:g} s: the simulator seems stuck'))
            return 1
    # Done spinning: from here on a signal may interrupt wherever it lands.
    _interrupt_on_signals()
    raise_if_stopped(stop)  # one that came before the switch
    plot = write_trajectory_plot(output_dir.absolute() / PLOT_NAME, node.odom_xy, node.truth_xy,
                                 node.scan_xy)
    print(f'simulated {node.elapsed_s:.1f} s in {time.monotonic() - started_s:.1f} s of wall time')
    print(f'trajectory plot: {plot}', flush=True)
    if node.image is not None:
        snapshot = write_camera_snapshot(output_dir.absolute() / SNAPSHOT_NAME, node.image)
        print(f'head camera snapshot: {snapshot}', flush=True)
    else:
        print('head camera snapshot: none received', flush=True)
    return 0


def main(args: Optional[Sequence[str]] = None) -> int:
    """Run the demo; return 0 on success, 1 if the simulator fails, 130 on Ctrl-C."""
    argv = list(sys.argv if args is None else args)
    options = build_parser().parse_args(non_ros_args(argv, 'demo'))
    output_dir = Path(options.output_dir)
    try:
        output_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _error(f'cannot create the output directory: {exc}')
        return 1
    # Discovery must stay on this host; set before rclpy.init and inherited by the child.
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    if options.domain_id is not None:
        os.environ['ROS_DOMAIN_ID'] = str(options.domain_id)
    # SIGINT and SIGTERM only set this event from here on; the loops check it.
    stop = stop_on_signals()
    try:
        rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # e.g. an invalid ROS_DOMAIN_ID; rclpy raises assorted types
        _error(f'cannot initialise ROS: {exc}')
        return 2
    simulator = Simulator.for_real_time_factor(options.real_time_factor, ros_child_env())
    node = None
    try:
        node = ManoeuvreDriver()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        # Another simulator on this domain would interleave its poses with ours.
        # Discovery takes 5-200 ms here: look for one before starting our own
        # (and again while ours runs, for a machine too busy to discover it in time).
        other_simulator = spin_until(
            executor, lambda: node.count_publishers('/clock') > 0, OTHER_SIMULATOR_WAIT_S,
            abort=stop.is_set)
        raise_if_stopped(stop)
        if other_simulator:
            _error(ANOTHER_SIMULATOR)
            return 1
        simulator.start()
        return _run(node, executor, simulator, output_dir, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        print('demo: interrupted, stopping the simulator', file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        try:
            if node is not None:
                node.destroy_node()
            rclpy.try_shutdown()
        finally:
            # A second Ctrl-C (or SIGTERM) while the simulator stops cuts the wait short.
            _interrupt_on_signals()
            simulator.stop()


if __name__ == '__main__':
    sys.exit(main())
