"""CmdVelInput without ROS: when a command counts as received, and the throttled log."""

from types import SimpleNamespace

from geometry_msgs.msg import Twist, TwistStamped

from r2d2_sim.ros.cmd_vel import CmdVelInput, ThrottledLog


class FakeNode:
    """Just what CmdVelInput asks of a node; records the warnings."""

    def __init__(self):
        self.warnings = []

    def create_subscription(self, *args):
        return None

    def create_timer(self, *args, **kwargs):
        return None

    def get_logger(self):
        return SimpleNamespace(warning=self.warnings.append)


class RecordingRobot:
    """Answers every command with ``verdict`` and notes what ``received`` read meanwhile."""

    time_ns = 10**9

    def __init__(self, verdict):
        self.verdict = verdict
        self.input = None
        self.received_during_command = []

    def command(self, *args, **kwargs):
        self.received_during_command.append(self.input.received)
        return self.verdict


def make_input(verdict, stamped=False):
    node, simulation = FakeNode(), RecordingRobot(verdict)
    config = SimpleNamespace(enable_stamped_cmd_vel=stamped, cmd_vel_timeout_s=0.5)
    simulation.input = CmdVelInput(node, config, simulation, ThrottledLog(),
                                   lambda: simulation.time_ns)
    return node, simulation, simulation.input


def test_a_command_counts_as_received_only_once_the_simulation_holds_it():
    """A test that waits for the count and then steps must step with the command."""
    refused = SimpleNamespace(problem='NaN', ignored_axes=(), clamped=False, accepted=None)
    node, simulation, cmd_vel = make_input(refused)
    seen_in_warning = []
    node.get_logger = lambda: SimpleNamespace(
        warning=lambda text: seen_in_warning.append(cmd_vel.received))
    cmd_vel.on_twist(Twist())
    assert simulation.received_during_command == [0] and seen_in_warning == [0]
    assert (cmd_vel.received, cmd_vel.rejected) == (1, 1)


def test_a_stale_stamped_command_is_counted_after_its_warning():
    node, simulation, cmd_vel = make_input(None, stamped=True)
    seen_in_warning = []
    node.get_logger = lambda: SimpleNamespace(
        warning=lambda text: seen_in_warning.append((cmd_vel.received, text)))
    msg = TwistStamped()
    msg.header.stamp.nanosec = 1  # 1 s - 1 ns old at t = 1 s, timeout 0.5 s
    cmd_vel.on_twist_stamped(msg)
    assert simulation.received_during_command == []  # never reaches the simulation
    assert len(seen_in_warning) == 1 and seen_in_warning[0][0] == 0
    assert 'rejected cmd_vel stamped 0.000 s' in seen_in_warning[0][1]
    assert (cmd_vel.received, cmd_vel.rejected) == (1, 1)


def test_throttled_log_holds_back_repeats_and_counts_them():
    lines, throttled = [], ThrottledLog()
    for _ in range(3):
        throttled('a', lines.append, 'first kind')
    throttled('b', lines.append, 'second kind')
    assert lines == ['first kind', 'second kind']
    throttled.period_s = 0.0
    throttled('a', lines.append, 'first kind')
    assert lines[-1] == 'first kind (2 more since the last one)'
