"""The ``demo`` and ``drive`` executables as real processes (their pure helpers: apps/)."""

import math
import os
from pathlib import Path
import select
import signal
import subprocess
import sys
import time

from helpers import (
    next_domain_id, RemoteProbe, ros_env, simulators_in_domain, start_sim_process,
    stop_process, wait_for)
import pytest

from common import PNG_SIGNATURE, PROGRESS, REPO
from r2d2_sim.apps.demo import ANOTHER_SIMULATOR, manoeuvre_duration_s

REPO_ROOT = Path(REPO)


@pytest.fixture
def domain_id():
    """Return a ROS domain id leased for this test (within R2D2_SIM_DOMAIN_IDS)."""
    return next_domain_id()


def demo_command(output_dir, domain_id, real_time_factor):
    return [sys.executable, '-m', 'r2d2_sim.apps.demo',
            '--real-time-factor', str(real_time_factor),
            '--output-dir', str(output_dir), '--domain-id', str(domain_id)]


# --------------------------------------------------------------------------- demo, end to end


def test_demo_refuses_a_domain_another_simulator_publishes_on(tmp_path, domain_id):
    """With sim_node already running on its domain, the demo says so in one line."""
    from rosgraph_msgs.msg import Clock
    other = subprocess.Popen([sys.executable, '-m', 'r2d2_sim'], env=ros_env(domain_id),
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    probe = RemoteProbe(domain_id, 'other_sim_probe')
    try:
        clocks = []
        probe.node.create_subscription(Clock, '/clock', clocks.append, 10)
        assert probe.spin_until(lambda: clocks, 30.0), 'the other simulator did not start'
        # At real time: with both cores busy, finding a running simulator took 0.9-2.5 s
        # in 6 of 15 tries, so the demo may find it only during its 6.6 s run.
        result = subprocess.run(demo_command(tmp_path, domain_id, 1), env=ros_env(domain_id),
                                cwd=REPO_ROOT, capture_output=True, text=True, timeout=60)
    finally:
        probe.close()
        other.send_signal(signal.SIGINT)
        other.wait(timeout=10)
    assert result.returncode == 1, result.stdout + result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith('demo: error')]
    assert len(errors) == 1 and 'another simulator' in errors[0], result.stderr
    assert 'Traceback' not in result.stderr
    assert simulators_in_domain(domain_id) == [], 'the demo left its simulator running'


def test_demo_turns_then_drives_and_writes_a_plot(tmp_path, domain_id):
    (tmp_path / 'run.mcap').write_text('a recording of mine\n')  # kept: this run's is run-2
    started = time.monotonic()
    result = subprocess.run(demo_command(tmp_path, domain_id, 0), env=ros_env(domain_id),
                            cwd=REPO_ROOT, capture_output=True, text=True, timeout=60)
    wall_s = time.monotonic() - started
    report = f'exit {result.returncode}\nstdout:\n{result.stdout}\nstderr:\n{result.stderr}'
    assert result.returncode == 0, report
    progress = [m for m in map(PROGRESS.match, result.stdout.splitlines()) if m]
    assert len(progress) >= 4, report
    final = progress[-1]
    assert float(final['t']) >= manoeuvre_duration_s() - 0.05, report
    assert 60.0 < float(final['tyaw']) < 120.0, report
    # After a +90 degree turn, forward is world +y.
    assert float(final['ty']) > 0.5, report
    assert abs(float(final['tx'])) < 0.3, report
    # Odometry agrees with the truth to within the skid-steering error.
    assert float(final['oy']) == pytest.approx(float(final['ty']), abs=0.2), report
    plot = tmp_path / 'trajectory.png'
    assert f'trajectory plot: {plot}' in result.stdout, report
    assert plot.read_bytes()[:8] == PNG_SIGNATURE
    snapshot = tmp_path / 'head_camera.png'
    assert f'head camera snapshot: {snapshot}' in result.stdout, report
    assert (tmp_path / 'run.mcap').read_text() == 'a recording of mine\n'
    recording = tmp_path / 'run-2.mcap'
    assert f'recording: {recording}' in result.stdout, report
    from mcap.reader import make_reader
    with open(recording, 'rb') as stream:  # closed, with its summary
        counts = make_reader(stream).get_summary().statistics.channel_message_counts
    assert sum(counts.values()) > 1000
    _assert_camera_picture(snapshot)
    assert simulators_in_domain(domain_id) == [], 'the demo left its simulator running'
    print(f'demo at real_time_factor 0 took {wall_s:.1f} s of wall time')


def test_demo_in_lockstep_repeats_bit_for_bit_on_a_busy_machine(tmp_path, domain_id):
    """At factor 0 the demo steps the simulator in lockstep: the same final pose, every bit."""
    hog = subprocess.Popen([sys.executable, '-c', 'while True: pass'])  # one busy core
    try:
        finals = []
        for run in range(2):
            result = subprocess.run(demo_command(tmp_path / str(run), domain_id, 0),
                                    env=ros_env(domain_id), cwd=REPO_ROOT, capture_output=True,
                                    text=True, timeout=120)
            assert result.returncode == 0, result.stdout + result.stderr
            finals += [line for line in result.stdout.splitlines()
                       if line.startswith('final ground truth: ')]
    finally:
        hog.kill()
        hog.wait()
    assert len(finals) == 2 and finals[0] == finals[1], finals
    yaw_deg = math.degrees(float(finals[0].rsplit('yaw=', 1)[1]))
    assert 85.0 < yaw_deg < 100.0, finals[0]


def _wait_until_under_way(demo: subprocess.Popen, line: bytes = b't=  1.0 s',
                          timeout_s: float = 30.0) -> bool:
    """Read the demo's stdout until ``line`` (default: t = 1 s of the manoeuvre); False if none."""
    output = b''
    deadline = time.monotonic() + timeout_s
    while line not in output and time.monotonic() < deadline:
        readable, _, _ = select.select([demo.stdout], [], [], 0.1)
        if readable:
            chunk = os.read(demo.stdout.fileno(), 4096)
            if not chunk:
                break
            output += chunk
    return line in output


def test_demo_stops_itself_and_the_simulator_on_sigint(tmp_path, domain_id):
    demo = subprocess.Popen(demo_command(tmp_path, domain_id, 1), env=ros_env(domain_id),
                            cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        under_way = _wait_until_under_way(demo)
        running = simulators_in_domain(domain_id)
    finally:
        _, _, stderr = stop_process(demo, timeout_s=15.0)
    assert under_way, stderr
    assert running, 'no simulator found while the demo runs'
    assert demo.returncode == 130, stderr
    assert 'interrupted' in stderr
    assert 'Traceback' not in stderr, stderr
    assert wait_for(lambda: simulators_in_domain(domain_id) == [], 5.0, interval_s=0.05)


def test_demo_ctrl_c_from_a_terminal_while_its_simulator_starts_exits_130(tmp_path, domain_id):
    """
    Ctrl-C in a terminal signals the whole process group, the simulator too.

    The simulator then exits 0 while the demo waits for it to start (3-5 s
    here): that is the interruption, not "sim_node exited ... while starting".
    """
    demo = subprocess.Popen(demo_command(tmp_path, domain_id, 1), env=ros_env(domain_id),
                            cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)  # a group of its own
    try:
        starting = wait_for(lambda: simulators_in_domain(domain_id), 30.0, interval_s=0.02)
        os.killpg(demo.pid, signal.SIGINT)
        stdout, stderr = demo.communicate(timeout=30.0)
    finally:
        if demo.poll() is None:
            os.killpg(demo.pid, signal.SIGKILL)
            demo.communicate()
    assert starting, 'the demo started no simulator'
    assert 't=  0.0 s' not in stdout, 'the signal came after the start: ' + stdout
    assert demo.returncode == 130, stderr
    assert stderr.splitlines() == ['demo: interrupted, stopping the simulator'], stderr
    assert wait_for(lambda: simulators_in_domain(domain_id) == [], 5.0, interval_s=0.05)


def test_demo_ctrl_c_after_the_manoeuvre_still_exits_130(tmp_path, domain_id):
    """Ctrl-C while the plot is written (no spinning then) interrupts it too."""
    demo = subprocess.Popen(demo_command(tmp_path, domain_id, 0), env=ros_env(domain_id),
                            cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        finished = _wait_until_under_way(demo, f't={manoeuvre_duration_s():5.1f} s'.encode())
    finally:
        _, stdout, stderr = stop_process(demo, timeout_s=15.0)
    assert finished, stderr
    assert demo.returncode == 130, stdout + stderr
    assert 'interrupted' in stderr and 'Traceback' not in stderr, stderr
    assert wait_for(lambda: simulators_in_domain(domain_id) == [], 5.0, interval_s=0.05)


def test_demo_stops_when_another_clock_publisher_appears_mid_run(tmp_path, domain_id):
    """A /clock publisher of another node, found late (slow discovery), still ends the demo."""
    from rosgraph_msgs.msg import Clock

    demo = subprocess.Popen(demo_command(tmp_path, domain_id, 1), env=ros_env(domain_id),
                            cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        under_way = _wait_until_under_way(demo)
        if under_way:
            # A node that only offers /clock: the graph shows it within milliseconds,
            # where a whole second simulator took 0.8-2.2 s to start and be found.
            with RemoteProbe(domain_id, 'other_clock') as other:
                other.node.create_publisher(Clock, '/clock', 10)
                other.spin_until(lambda: demo.poll() is not None, 30.0)
    finally:
        _, _, stderr = stop_process(demo, timeout_s=15.0)
    assert under_way, stderr
    assert demo.returncode == 1, stderr
    assert stderr.splitlines() == ['demo: error: ' + ANOTHER_SIMULATOR]
    assert wait_for(lambda: simulators_in_domain(domain_id) == [], 5.0, interval_s=0.05)


# --------------------------------------------------------------------------- drive


@pytest.mark.parametrize('args, complaint', [
    (['--duration', '-1'], "argument --duration: must be in [0, 1e+09] s, got '-1'"),
    (['--linear', 'nan'], 'argument --linear: must be a finite number'),
    (['--rate', '0'], "argument --rate: must be in [0.001, 10000] Hz, got '0'"),
    # Each of these passed, then crashed in rclpy with a traceback.
    (['--duration', '1e10'], "argument --duration: must be in [0, 1e+09] s, got '1e10'"),
    (['--rate', '1e-10'], "argument --rate: must be in [0.001, 10000] Hz, got '1e-10'"),
    (['--topic', ''], "argument --topic: '' is not a ROS topic name: topic name must not be "
                      "empty string"),
    (['--topic', 'cmd vel'], "argument --topic: 'cmd vel' is not a ROS topic name: topic name "
                             "must not contain characters other than alphanumerics"),
    (['--topic', '/a//b'], "argument --topic: '/a//b' is not a ROS topic name: topic name must "
                           "not contain repeated '/'"),
])
def test_drive_rejects_bad_arguments_with_a_usage_error(domain_id, args, complaint):
    """Refuse before ROS starts (on a leased domain all the same, should it start)."""
    result = subprocess.run([sys.executable, '-m', 'r2d2_sim.apps.drive'] + args,
                            env=ros_env(domain_id), cwd=REPO_ROOT, capture_output=True,
                            text=True, timeout=30)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert lines[0].startswith('usage: drive') and 'Traceback' not in result.stderr
    assert lines[-1].startswith('drive: error: ' + complaint), result.stderr


@pytest.mark.parametrize('args, complaint', [
    (['--real-time-factor', '5000'], 'argument --real-time-factor: must be 0 (as fast as '
                                     'possible) or in [1e-06, 1000]'),
    (['--real-time-factor', '1e-300'], 'argument --real-time-factor: must be 0'),
    (['--real-time-factor', '-1'], 'argument --real-time-factor: must be >= 0'),
    # They configured the driver node, not the simulator, in silence.
    (['--ros-args', '-p', 'real_time_factor:=0.0'], 'the demo takes no ROS arguments'),
])
def test_demo_rejects_bad_arguments_before_anything_starts(tmp_path, domain_id, args, complaint):
    """A value the simulator would refuse is a usage error: exit 2, no simulator started."""
    result = subprocess.run(demo_command(tmp_path, domain_id, 1) + args, env=ros_env(domain_id),
                            cwd=REPO_ROOT, capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stdout + result.stderr
    lines = result.stderr.strip().splitlines()
    assert lines[0].startswith('usage: demo') and len(lines) == 2, result.stderr
    assert lines[-1].startswith('demo: error: ' + complaint), result.stderr
    assert not (tmp_path / 'run.mcap').exists()


def test_a_run_records_beside_what_is_there_and_replaces_none_of_it(tmp_path):
    """run.mcap taken (a file, or a directory): run-2.mcap; then run-3.mcap. Nothing replaced."""
    from r2d2_sim.apps.demo import free_recording
    assert free_recording(tmp_path) == tmp_path / 'run.mcap'
    (tmp_path / 'run.mcap').mkdir()
    assert free_recording(tmp_path) == tmp_path / 'run-2.mcap'
    (tmp_path / 'run-2.mcap').write_text('a recording of mine\n')
    (tmp_path / 'run-3.mcap').symlink_to(tmp_path / 'nowhere')  # a dangling link is taken too
    assert free_recording(tmp_path) == tmp_path / 'run-4.mcap'


@pytest.mark.parametrize('module', ['r2d2_sim.apps.drive', 'r2d2_sim.apps.demo'])
def test_malformed_ros_args_are_a_one_line_error(module):
    result = subprocess.run([sys.executable, '-m', module, '--ros-args', '-p'],
                            cwd=REPO_ROOT, capture_output=True, text=True, timeout=30)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and 'error: bad ROS arguments' in lines[0], result.stderr


def test_drive_with_rclpys_own_parameter_of_the_wrong_type_is_one_line(domain_id):
    """use_sim_time:=1 (an integer, a common slip): one line and exit 2, not a traceback."""
    result = subprocess.run([sys.executable, '-m', 'r2d2_sim.apps.drive', '--ros-args', '-p',
                             'use_sim_time:=1'], env=ros_env(domain_id), cwd=REPO_ROOT,
                            capture_output=True, text=True, timeout=30)
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip().splitlines() == [
        'drive: error: parameter use_sim_time must be true or false, got 1 (an integer)']


def test_drive_without_a_subscriber_fails_with_one_line(domain_id):
    result = subprocess.run([sys.executable, '-m', 'r2d2_sim.apps.drive', '--linear', '0.3'],
                            env=ros_env(domain_id), cwd=REPO_ROOT, capture_output=True,
                            text=True, timeout=30)
    assert result.returncode == 1
    assert result.stderr.strip().splitlines() == [
        'drive: error: nothing subscribed to /cmd_vel within 5 s: is the simulator running '
        '(same ROS_DOMAIN_ID)?']


@pytest.fixture
def simulator_process(domain_id):
    """Run the simulator at real time in this test's domain."""
    process = start_sim_process(domain_id, '-p', 'real_time_factor:=1.0')
    try:
        yield process
    finally:
        stop_process(process)


@pytest.fixture
def ros_probe(domain_id):
    """Yield (node, executor) on a private rclpy context in this test's domain."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = executor = None
    try:
        node = rclpy.create_node('drive_test_probe', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        yield node, executor
    finally:
        if executor is not None:
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_drive_moves_the_simulated_robot_forward(simulator_process, ros_probe, domain_id):
    from nav_msgs.msg import Odometry

    from r2d2_sim.client import pose_from_odometry, spin_until

    node, executor = ros_probe
    poses = []
    node.create_subscription(Odometry, 'ground_truth',
                             lambda msg: poses.append(pose_from_odometry(msg)), 10)
    if not spin_until(executor, lambda: poses, 20.0):
        pytest.fail('no ground_truth from the simulator: '
                    + stop_process(simulator_process)[2])
    start_x_m = poses[-1].x_m
    drive = subprocess.Popen(
        [sys.executable, '-m', 'r2d2_sim.apps.drive', '--linear', '0.3', '--duration', '1.0'],
        env=ros_env(domain_id), cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True)
    try:
        moved = spin_until(executor, lambda: poses[-1].x_m - start_x_m > 0.15, 20.0)
        # Moving is not enough: drive must also finish on its own.
        spin_until(executor, lambda: drive.poll() is not None, 10.0)
    finally:
        status, _, stderr = stop_process(drive)
    assert status == 0, stderr
    assert moved, f'x moved only {poses[-1].x_m - start_x_m:.3f} m'


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_drive_stops_the_robot_when_interrupted(ros_probe, domain_id, sig):
    """Ctrl-C or SIGTERM mid-command: one zero Twist goes out, exit 130, no traceback."""
    from geometry_msgs.msg import Twist

    from r2d2_sim.client import spin_until

    node, executor = ros_probe
    received = []
    node.create_subscription(Twist, 'cmd_vel', lambda msg: received.append(msg.linear.x), 10)
    drive = subprocess.Popen(
        [sys.executable, '-m', 'r2d2_sim.apps.drive', '--linear', '0.3', '--duration', '100'],
        env=ros_env(domain_id), cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True)
    try:
        assert spin_until(executor, lambda: 0.3 in received, 20.0), 'drive never published'
        drive.send_signal(sig)
        stopped = spin_until(executor, lambda: received[-1] == 0.0, 10.0)
        spin_until(executor, lambda: drive.poll() is not None, 10.0)
    finally:
        status, _, stderr = stop_process(drive)
    assert stopped, f'no zero Twist after the signal; last linear.x {received[-1]}'
    assert status == 130, stderr
    assert stderr == ''


def _assert_camera_picture(path):
    """Check a head-camera PNG shows more than one colour (ground below, sky above)."""
    from matplotlib import pyplot
    pixels = pyplot.imread(path)
    assert pixels.shape[:2] == (240, 320)
    top, bottom = pixels[:40].mean(axis=(0, 1)), pixels[-40:].mean(axis=(0, 1))
    assert abs(top - bottom).sum() > 0.05


# --------------------------------------------------------------------------- drive --stamped

def run_drive(domain_id, *args):
    """Start ``drive`` with ``args`` in the test's domain; return its Popen."""
    drive = subprocess.Popen([sys.executable, '-m', 'r2d2_sim.apps.drive', *args],
                             env=ros_env(domain_id), cwd=REPO_ROOT, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    return drive


@pytest.mark.parametrize('stamped', [False, True], ids=['Twist', '--stamped'])
def test_drive_names_the_type_a_subscriber_of_the_other_type_wants(
        ros_probe, domain_id, stamped):
    """A simulator with enable_stamped_cmd_vel (or without): the line says what to change."""
    from geometry_msgs.msg import Twist, TwistStamped

    from r2d2_sim.client import spin_until

    node, executor = ros_probe
    node.create_subscription(Twist if stamped else TwistStamped, 'cmd_vel', lambda m: None, 10)
    drive = run_drive(domain_id, '--linear', '0.3', *(['--stamped'] if stamped else []))
    try:
        spin_until(executor, lambda: drive.poll() is not None, 20.0)  # answer discovery
    finally:
        status, _, stderr = stop_process(drive)
    mine, theirs = ('TwistStamped', 'Twist') if stamped else ('Twist', 'TwistStamped')
    assert status == 1
    assert stderr.strip().splitlines() == [
        f'drive: error: nothing subscribed to /cmd_vel as geometry_msgs/msg/{mine} within 5 s, '
        f'but /drive_test_probe subscribes to it as geometry_msgs/msg/{theirs}: '
        + ('drop --stamped' if stamped else 'use --stamped')]


def test_drive_stamped_publishes_twist_stamped_stamped_now(ros_probe, domain_id):
    """--stamped: TwistStamped commands stamped on drive's clock, then a zero one."""
    from geometry_msgs.msg import TwistStamped

    from r2d2_sim.client import spin_until

    node, executor = ros_probe
    received = []
    node.create_subscription(TwistStamped, 'cmd_vel', received.append, 10)
    before_ns = time.time_ns()
    drive = run_drive(domain_id, '--linear', '0.3', '--duration', '0.5', '--stamped')
    try:
        finished = spin_until(executor, lambda: drive.poll() is not None, 20.0)
        spin_until(executor, lambda: received and received[-1].twist.linear.x == 0.0, 5.0)
    finally:
        status, _, stderr = stop_process(drive)
    assert finished and status == 0, stderr
    assert [m.twist.linear.x for m in received][:1] == [0.3]
    assert received[-1].twist.linear.x == 0.0
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in received]
    assert before_ns <= stamps[0] <= stamps[-1] <= time.time_ns()
