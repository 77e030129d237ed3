"""
Garbage commands, physics blow-ups, a wrong cmd_vel type and extreme parameters.

All in-process: the simulator and a probe share one isolated context, the test
advances physics step by step, and ``capfd`` reads what the node logged (rcutils
writes to the process's stderr).
"""

import math
from types import SimpleNamespace

from helpers import latest_truth, make_sim, Probe, RATE_HZ, wait_for
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
import pytest
import rclpy
from rclpy.context import Context

from r2d2_sim.model.kinematics import twist_to_wheel_velocities
from r2d2_sim.ros.node import StartupError

NAN, INF = math.nan, math.inf
FIELDS = ('linear_x', 'linear_y', 'linear_z', 'angular_x', 'angular_y', 'angular_z')


def _garbage_cases():
    cases = {}
    for field in FIELDS:
        cases[f'{field}=nan'] = {field: NAN}
        cases[f'{field}=inf'] = {field: INF}
        cases[f'{field}=-inf'] = {field: -INF}
    cases['all nan'] = dict.fromkeys(FIELDS, NAN)
    cases['all inf'] = dict.fromkeys(FIELDS, INF)
    cases['all mixed'] = dict(zip(FIELDS, (NAN, INF, -INF, 1e308, -0.0, NAN)))
    return cases


GARBAGE = _garbage_cases()


def upright_and_grounded(sim, z0):
    """Return why the robot is not standing on the ground near its start height (or None)."""
    problem = sim.simulation.robot.body.state_problem()
    if problem:
        return problem
    base = sim.simulation.robot.body.base_state()
    qx, qy = base.orientation[0], base.orientation[1]
    tilt_cos = 1.0 - 2.0 * (qx * qx + qy * qy)  # body z . world z
    if tilt_cos < math.cos(0.2):
        return f'tilted: cos = {tilt_cos:.3f}'
    if abs(base.position[2] - z0) > 0.05:
        return f'left the ground: z = {base.position[2]:.3f} m (start {z0:.3f} m)'
    return None


def all_finite(messages):
    """Return True if every pose and twist in these Odometry messages is finite."""
    for msg in messages:
        pose, twist = msg.pose.pose, msg.twist.twist
        values = (pose.position.x, pose.position.y, pose.position.z,
                  pose.orientation.x, pose.orientation.y, pose.orientation.z,
                  pose.orientation.w, twist.linear.x, twist.linear.y, twist.linear.z,
                  twist.angular.x, twist.angular.y, twist.angular.z)
        if not all(map(math.isfinite, values)):
            return False
    return True


def log_lines(capfd, fragment):
    """Return the captured stderr lines containing ``fragment``."""
    return [line for line in capfd.readouterr().err.splitlines() if fragment in line]


# -- bad commands -------------------------------------------------------------

@pytest.mark.parametrize('fields', GARBAGE.values(), ids=GARBAGE.keys())
def test_garbage_command_is_refused_and_the_robot_stays_sane(sim, probe, fields):
    """Refuse NaN or infinity anywhere, keep the last valid command, stay upright and finite."""
    z0 = sim.simulation.robot.body.base_state().position[2]
    probe.send(0.3, 0.2)
    sim.advance(24)
    command = sim.simulation.robot.controller.target
    probe.send(**fields)
    sim.advance(24)
    assert sim.commands_rejected == 1
    assert sim.simulation.robot.controller.target == command
    probe.advance_and_collect(RATE_HZ)
    assert upright_and_grounded(sim, z0) is None
    assert all_finite(probe.messages['ground_truth']) and all_finite(probe.messages['odom'])


@pytest.mark.parametrize('sign', [1.0, -1.0])
def test_1e308_in_all_six_fields_is_clamped_not_refused(sim, probe, sign):
    """The largest doubles drive the wheels at their limit; the robot stays on its wheels."""
    z0 = sim.simulation.robot.body.base_state().position[2]
    probe.send(**dict.fromkeys(FIELDS, sign * 1e308))
    sim.advance(1)
    assert sim.commands_rejected == 0
    controller = sim.simulation.robot.controller
    left, right = twist_to_wheel_velocities(controller.geometry, *controller.target)
    assert max(abs(left), abs(right)) == pytest.approx(
        controller.geometry.max_wheel_velocity_rad_s)
    for _ in range(10):  # keep it going for a second
        probe.send(**dict.fromkeys(FIELDS, sign * 1e308))
        sim.advance(RATE_HZ // 10)
    assert upright_and_grounded(sim, z0) is None


def test_negative_zero_is_a_plain_stop(sim, probe, capfd):
    """-0.0 in every field is a valid zero command: accepted, wheels stopped, nothing logged."""
    probe.send(0.3)
    sim.advance(24)
    probe.send(**dict.fromkeys(FIELDS, -0.0))
    sim.advance(1)
    assert sim.commands_rejected == 0
    assert sim.simulation.robot.controller.target == (0.0, 0.0)
    sim.advance(RATE_HZ // 2)  # braking from 0.3 m/s at 1 m/s^2 takes 0.3 s
    assert sim.simulation.robot.controller.wheel_targets == (0.0, 0.0)
    assert log_lines(capfd, 'cmd_vel') == []


def test_one_throttled_warning_per_kind_of_problem(ros, capfd, monkeypatch):
    """Twenty messages of each kind give one warning per kind, then a count of the rest."""
    from r2d2_sim.model import timing
    period_s = 0.5
    # The throttle's wall clock, stopped while the 80 commands go (a loaded machine
    # may take longer than the period to send them), then moved on by the period.
    clock = [1000.0]
    monkeypatch.setattr(timing, 'time', SimpleNamespace(monotonic=lambda: clock[0]))
    sim = make_sim(ros, node_kwargs={'warning_period_s': period_s})
    probe = Probe(ros, sim)
    kinds = {
        'rejected cmd_vel with NaN': {'linear_x': NAN},
        'rejected cmd_vel with infinite value': {'angular_z': -INF},
        'exceeds the speed limits': {'linear_x': 1e308},
        'ignored: a differential drive follows': {'linear_y': 0.2},
    }
    for _ in range(20):
        for fields in kinds.values():
            probe.send(**fields)
    assert sim.commands_rejected == 40

    captured = capfd.readouterr().err
    for fragment in kinds:
        assert captured.count(fragment) == 1, (fragment, captured)
    # Once the throttle period has passed, the next warning counts what it held back.
    clock[0] += period_s
    probe.send(linear_x=NAN)
    assert len(log_lines(capfd, '(19 more since the last one)')) == 1


# -- physics blow-ups ---------------------------------------------------------

BLOW_UPS = {
    'flung off the world': ({'position': (1.0e5, 0.0, 0.5)}, 'left the world'),
    'NaN velocity': ({'linear_velocity': (NAN, 0.0, 0.0)}, 'not finite'),
    'flung at 1e5 m/s': ({'linear_velocity': (1.0e5, 0.0, 0.0)}, 'flung at'),
    'spun at 1e6 rad/s': ({'angular_velocity': (0.0, 0.0, 1.0e6)}, 'spinning at'),
}


@pytest.mark.parametrize('publish_rate', [0.0, 10.0], ids=['publish every step', '10 Hz'])
@pytest.mark.parametrize('state, cause', BLOW_UPS.values(), ids=BLOW_UPS.keys())
def test_blow_up_is_detected_within_one_step_and_the_robot_reset(ros, capfd, publish_rate,
                                                                 state, cause):
    """
    An absurd state is caught in time, named in an error, and never published.

    An absurd velocity (every physics blow-up) is caught at the next step;
    an absurd pose alone, which only a teleport makes, at the next step that
    measures anything (sensors off here: the next publication), before it is read.
    """
    sim = make_sim(ros, publish_rate=publish_rate, scan_rate=0.0, imu_rate=0.0)
    probe = Probe(ros, sim)
    z0 = sim.simulation.robot.body.base_state().position[2]
    probe.send(0.3)
    sim.advance(RATE_HZ // 2)
    assert latest_truth(sim)[0] > 0.05  # it has driven away from the start
    sim.simulation.robot.body.set_base_state(**state)
    if publish_rate != 0.0:
        assert sim.steps_to_next_publish() > 1  # the next step publishes nothing
    sim.advance(1)
    if 'position' in state and publish_rate != 0.0:
        assert sim.blow_ups == 0
        sim.advance(sim.steps_to_next_publish() - 1)
        assert sim.blow_ups == 0  # not yet read, nor published
        sim.advance(1)  # the publication: checked before reading
    assert sim.blow_ups == 1
    errors = log_lines(capfd, 'physics blew up')
    assert cause in errors[0] and 'resetting the robot' in errors[0]
    x, y, yaw = latest_truth(sim)
    assert abs(x) < 1e-3 and abs(y) < 1e-3 and abs(yaw) < 1e-3
    controller = sim.simulation.robot.controller
    assert controller.target == controller.wheel_targets == (0.0, 0.0)  # command dropped
    assert (controller.odometry.x_m, controller.odometry.y_m) == (0.0, 0.0)
    truths = probe.messages['ground_truth']
    if publish_rate == 0.0:  # what was published at that very step is the reset robot
        stamp = divmod(sim.sim_time_ns, 10**9)
        at_step = wait_for(lambda: [m for m in truths
                                    if (m.header.stamp.sec, m.header.stamp.nanosec) == stamp])
        assert at_step and abs(at_step[0].pose.pose.position.x) < 1e-3
        probe.advance_and_collect(RATE_HZ // 4)
    else:
        published = len(truths)
        sim.advance_to_next_publish()
        probe.wait_count('ground_truth', published + 1)
    assert sim.blow_ups == 1
    assert all_finite(truths) and max(abs(m.pose.pose.position.x) for m in truths) < 1.0
    # 1.5 s later it stands where it was put (a NaN broke the ground too: it fell through).
    sim.advance(RATE_HZ * 3 // 2)
    if publish_rate != 0.0:
        sim.advance_to_next_publish()
    assert upright_and_grounded(sim, z0) is None
    stamp = divmod(sim.sim_time_ns, 10**9)
    now = wait_for(lambda: [m for m in truths
                            if (m.header.stamp.sec, m.header.stamp.nanosec) == stamp])
    assert now, 'no ground truth of the last step arrived'
    assert now[0].pose.pose.position.z == pytest.approx(0.47, abs=0.002)
    assert sim.blow_ups == 1
    # A NaN breaks the ground plane too (the others do not spread): it is put back, named.
    broken = [line for line in errors[1:] if 'ground_plane was broken with it' in line]
    assert len(errors) == 1 + len(broken) and len(broken) == (cause == 'not finite')


def test_a_sensor_reading_is_preceded_by_the_whole_check(ros, capfd):
    """With the IMU due every step, a teleport far away is caught at the next step."""
    sim = make_sim(ros, publish_rate=10.0, scan_rate=0.0, imu_rate=240.0)
    sim.advance(RATE_HZ // 2)
    sim.simulation.robot.body.set_base_state(position=(1.0e5, 0.0, 0.5))
    assert sim.steps_to_next_publish() > 1
    sim.advance(1)
    assert sim.blow_ups == 1 and log_lines(capfd, 'left the world')


def test_non_finite_joint_state_is_a_blow_up(sim, probe, capfd):
    """A NaN wheel angle is caught before it is published, naming the joint."""
    wheel = sim.simulation.robot.body.joint('left_front_wheel_joint').index
    sim.world.client.resetJointState(sim.simulation.robot.body.id, wheel, NAN)
    sim.advance(1)
    assert sim.blow_ups == 1
    errors = log_lines(capfd, 'physics blew up')
    assert len(errors) == 1 and 'left_front_wheel_joint' in errors[0]
    probe.wait_count('joint_states', 1)
    assert all(map(math.isfinite, probe.messages['joint_states'][-1].position))


def test_repeated_blow_ups_log_one_error_per_period(sim, capfd):
    """A robot that keeps exploding is reset every time, but the log is throttled."""
    for _ in range(5):
        sim.simulation.robot.body.set_base_state(linear_velocity=(NAN, 0.0, 0.0))
        sim.advance(1)
    assert sim.blow_ups == 5
    assert len(log_lines(capfd, 'physics blew up')) == 1


@pytest.mark.parametrize('outputs_process', [False, True])
def test_a_robot_blown_up_again_and_again_leaves_with_its_topics(ros, capfd, outputs_process):
    """
    Robot a, blown up 10 times in a row, is taken out in one error line; b publishes on.

    Put back after every blow-up, such a robot blew up again, for ever: 240 blow-ups a
    second, a load each (the core's test_fleet_core.py counts them).
    """
    from r2d2_sim.sim.robots.robot import MAX_BLOW_UPS_IN_A_ROW
    sim = make_sim(ros, outputs_process=outputs_process, robots=['a', 'b'], scan_rate=0.0,
                   imu_rate=0.0, **{'b.initial_pose': [0.0, 3.0, 0.0]})
    node = ros.create_node('looker', use_sim_time=False)
    assert wait_for(lambda: node.count_publishers('/a/odom') == 1)
    a = sim.simulation.robots[0]
    for _ in range(MAX_BLOW_UPS_IN_A_ROW):
        a.body.set_base_state(linear_velocity=(NAN, 0.0, 0.0))
        sim.advance(1)
    assert [robot.name for robot in sim.simulation.robots] == ['b']
    heard = []
    node.create_subscription(Odometry, '/b/odom', heard.append, 100)
    assert wait_for(lambda: node.count_publishers('/a/odom') == 0)
    # The simulator's side matched (the outputs process's writer, with it): what is
    # published before it matches never arrives.
    odom = sim.robots[0].outputs.state[2]._publisher
    assert odom.topic_name == '/b/odom'
    assert wait_for(lambda: odom.get_subscription_count() == 1)
    sim.advance(RATE_HZ // 2)
    assert wait_for(lambda: len(heard) > 0) and all_finite(heard)
    lines = log_lines(capfd, 'physics blew up')
    taken_out = [line for line in lines if 'the robot a is taken out of the world' in line]
    assert len(taken_out) == 1 and sim.simulation.blow_ups == 0


# -- a publisher of the wrong type on cmd_vel ---------------------------------

def test_twist_stamped_on_cmd_vel_is_refused_by_ros_and_reported(ros, capfd):
    """A TwistStamped never reaches the node; it says so in a warning and still drives."""
    sim = make_sim(ros, node_kwargs={'graph_check_period_s': 0.1})
    probe = Probe(ros, sim)
    context = Context()
    rclpy.init(context=context, domain_id=ros.domain_id)
    other = rclpy.create_node('stamped_teleop', context=context)
    try:
        publisher = other.create_publisher(TwistStamped, 'cmd_vel', 10)
        stamped = TwistStamped()
        stamped.twist.linear.x = 0.3
        seen = []

        def warned():
            publisher.publish(stamped)
            sim.advance(4)
            seen.extend(log_lines(capfd, 'TwistStamped'))
            return seen
        assert wait_for(warned, 10.0), 'no warning about the TwistStamped publisher'
        assert '/stamped_teleop publishes geometry_msgs/msg/TwistStamped on /cmd_vel' in seen[0]
        assert publisher.get_subscription_count() == 0  # the middleware refused the match
        assert sim.commands_received == 0
        assert abs(latest_truth(sim)[0]) < 0.01
        probe.send(0.3)  # a Twist publisher still works alongside
        sim.advance(RATE_HZ // 2)
        assert latest_truth(sim)[0] > 0.05
    finally:
        other.destroy_node()
        rclpy.try_shutdown(context=context)


# -- parameters at the edge ---------------------------------------------------

@pytest.mark.parametrize('params, fragment', [
    ({'initial_pose': [1.0e5, 0.0, 0.0]}, 'off the ground plane'),
    ({'initial_pose': [1.0e5, 0.0, 0.0], 'ground_plane': False},
     'cannot start there: base left the world'),
    ({'left_wheel_names': [], 'right_wheel_names': []}, 'list them as left and right wheels'),
    ({'gravity': [0.0, 0.0, -1.0e308]}, 'gravity'),
    ({'physics_rate': 1.0e308}, 'physics_rate'),
])
def test_parameters_that_would_break_the_world_refuse_to_start(ros, params, fragment):
    """Values that would make the world absurd from the first step are start-up errors."""
    with pytest.raises(StartupError, match=fragment):
        make_sim(ros, **params)


def test_a_timeout_of_1e308_seconds_never_brakes(ros):
    """cmd_vel_timeout 1e308 (beyond any run) behaves as 0: no overflow, no braking."""
    sim = make_sim(ros, cmd_vel_timeout=1.0e308)
    probe = Probe(ros, sim)
    probe.send(0.3)
    sim.advance(2 * RATE_HZ)
    assert sim.simulation.robot.controller.wheel_targets != (0.0, 0.0)


def test_an_unknown_parameter_is_named_with_a_suggestion(ros, capfd):
    """A misspelt parameter would silently run on the default: the node warns instead."""
    make_sim(ros, physic_rate=100.0)
    warnings = log_lines(capfd, 'ignoring unknown parameter')
    assert len(warnings) == 1 and 'physic_rate (did you mean physics_rate?)' in warnings[0]


def test_qos_overrides_are_named_as_not_taken_typos_too(ros, capfd):
    """ROS users expect qos_overrides.*: each one is named as ignored, not passed over."""
    make_sim(ros, **{'qos_overrides./odom.publisher.reliability': 'best_effort',
                     'qos_overrides./odmo.publisher.depth': 1})
    warnings = log_lines(capfd, 'ignoring qos_overrides.')
    assert len(warnings) == 2, warnings
    assert warnings[0].endswith("ignoring qos_overrides./odmo.publisher.depth: r2d2_sim's "
                                "publishers take no QoS overrides (docs/node.md gives each "
                                "topic's QoS)")
    assert 'qos_overrides./odom.publisher.reliability: ' in warnings[1]


@pytest.mark.parametrize('name, value, line', [
    ('use_sim_time', 1, 'parameter use_sim_time must be true or false, got 1 (an integer)'),
    ('start_type_description_service', 'no',
     'parameter start_type_description_service must be true or false, got no (a string)'),
])
def test_rclpys_own_parameters_of_the_wrong_type_are_one_line(ros, name, value, line):
    """Turn rclpy's refusal of its own parameters, made as it builds the node, into one line."""
    with pytest.raises(StartupError) as raised:
        make_sim(ros, **{name: value})
    assert str(raised.value) == line


def test_rclpys_own_parameters_are_not_called_unknown(ros, capfd):
    """use_sim_time belongs to every rclpy node: no warning, and it takes effect."""
    sim = make_sim(ros, use_sim_time=True)
    assert not log_lines(capfd, 'ignoring unknown parameter')
    assert sim.get_parameter('use_sim_time').value is True
