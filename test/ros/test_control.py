"""
Simulation control: ~/pause, ~/step, ~/reset, start_paused, and bit-for-bit determinism.

In this process; the same determinism schedule stepped across processes is
system/test_control_system.py's.
"""

from fractions import Fraction
import json
import math
import threading
import time

from helpers import _run_schedule_in_process, latest_truth, make_sim, Probe, wait_for
import pytest
from sensor_msgs.msg import LaserScan
from std_srvs.srv import SetBool, Trigger

from r2d2_sim.apps.sim_node import run_paced


def pause(probe, value):
    """Call ~/pause and return the response."""
    request = SetBool.Request()
    request.data = value
    return probe.call(SetBool, '/r2d2_sim/pause', request)


def trigger(probe, name):
    """Call a Trigger service of the simulator."""
    return probe.call(Trigger, f'/r2d2_sim/{name}', Trigger.Request())


def test_pause_is_idempotent_and_reports_state(sim, probe):
    """Pausing twice stays paused; false resumes; each reply names the new state."""
    first = pause(probe, True)
    second = pause(probe, True)
    assert first.success and second.success
    assert json.loads(first.message)['paused'] and json.loads(second.message)['paused']
    assert sim.paused
    resumed = pause(probe, False)
    assert json.loads(resumed.message)['paused'] is False and not sim.paused


def test_get_readers_counts_the_readers_each_writer_matched(sim, probe):
    """~/get_readers: 0 on a topic nobody takes; one more once the writer matched a new reader."""
    def readers():
        return json.loads(trigger(probe, 'get_readers').message)
    before = readers()
    assert before['/scan'] == 0 and before['/odom'] >= 1  # the probe takes odom
    probe.node.create_subscription(LaserScan, '/scan', lambda msg: None, 10)
    assert wait_for(lambda: readers()['/scan'] == 1)
    assert readers()['/odom'] == before['/odom']


def test_step_fails_while_running(sim, probe):
    """~/step refuses while physics runs, with a message saying how to pause."""
    response = trigger(probe, 'step')
    assert not response.success
    reply = json.loads(response.message)
    assert 'pause' in reply['error'] and reply['steps'] == 0
    assert sim.step_count == 0


def test_step_advances_one_publish_period(ros):
    """While paused, ~/step advances exactly one control period and publishes its state."""
    sim = make_sim(ros, publish_rate=60.0, start_paused=True)
    probe = Probe(ros, sim)
    assert sim.paused
    response = trigger(probe, 'step')
    assert response.success
    assert sim.step_count == 4  # 240 Hz / 60 Hz
    # /clock goes out at each step that publishes something (step 3's too: a sensor): the
    # last is the period's end, 4 / 240 s floored to ns; wait for it, not for the first.
    clocks = probe.messages['clock']
    assert wait_for(lambda: clocks and (clocks[-1].clock.sec, clocks[-1].clock.nanosec)
                    == (0, 16666666)), [(c.clock.sec, c.clock.nanosec) for c in clocks]
    assert max(c.clock.nanosec for c in clocks) == 16666666  # and nothing past it
    trigger(probe, 'step')
    assert sim.step_count == 8


@pytest.mark.parametrize('publish_rate', [20.0, 50.0])
def test_pause_lands_on_a_publication(ros, publish_rate):
    """
    Pausing between publications stops after the step that publishes, never before.

    At publish_rate 20 (12 steps a period) a pause requested at step 125
    (t = 0.5208 s, 5 steps after the last publication at 0.5 s) runs on to
    step 132 (0.55 s) and publishes it: the reply's time is the last /clock,
    and each ~/step then advances exactly one period. At 50 Hz the periods
    are 4 or 5 steps (the first step after each 1/50 s).
    """
    # The n-th publication is at the first step at or after n / publish_rate s.
    steps_per_publication = Fraction(240) / Fraction(publish_rate)
    publications = [math.ceil(n * steps_per_publication) for n in range(1, 60)]
    sim = make_sim(ros, publish_rate=publish_rate)
    probe = Probe(ros, sim)
    sim.advance(121)
    facts = json.loads(pause(probe, True).message)
    assert facts['paused']
    assert facts['step'] == min(p for p in publications if p >= 121) == sim.step_count
    assert wait_for(lambda: probe.messages['clock']
                    and _ns(probe.messages['clock'][-1].clock) == facts['sim_time_ns'])
    assert facts['sim_time_ns'] == facts['step'] * 10**9 // 240
    for _ in range(3):
        before = sim.step_count
        step = json.loads(trigger(probe, 'step').message)
        following = publications[publications.index(before) + 1]
        assert step['steps'] == following - before == sim.step_count - before
        assert wait_for(lambda: _ns(probe.messages['clock'][-1].clock) == step['sim_time_ns'])


def _ns(stamp):
    return stamp.sec * 10**9 + stamp.nanosec


def test_paused_node_does_not_advance_in_the_paced_loop(ros):
    """run_paced leaves a paused simulation alone; unpausing lets it run."""
    sim = make_sim(ros, start_paused=True, real_time_factor=0.0)
    stop = threading.Event()
    runner = threading.Thread(target=run_paced, args=(sim, stop), daemon=True)
    runner.start()
    try:
        assert not wait_for(lambda: sim.step_count > 0, 0.3)
        sim._paused = False  # what ~/pause false does
        assert wait_for(lambda: sim.step_count > 100, 10.0)
    finally:
        stop.set()
        runner.join(5.0)
    assert not runner.is_alive()


def test_timeout_does_not_fire_while_paused(ros):
    """Wall time spent paused is not simulated time: the command survives a pause."""
    sim = make_sim(ros, start_paused=True, real_time_factor=1.0)
    probe = Probe(ros, sim)
    probe.send(0.3)
    trigger(probe, 'step')
    controller = sim.simulation.robot.controller
    command = controller.target
    assert command != (0.0, 0.0)
    # The paced loop runs, as in sim_node, for more wall time than the 0.5 s timeout.
    stop = threading.Event()
    runner = threading.Thread(target=run_paced, args=(sim, stop), daemon=True)
    started = time.monotonic()
    runner.start()
    try:
        assert not wait_for(lambda: controller.target != command or sim.step_count != 1, 0.7)
        assert time.monotonic() - started > 0.5
    finally:
        stop.set()
        runner.join(5.0)
    sim.advance(60)
    assert controller.target == command  # 61 steps < 120 steps of timeout


def test_pause_reply_time_is_where_physics_stopped(ros):
    """Pausing a node that runs flat out: no step follows the reply, whose time is final."""
    sim = make_sim(ros, real_time_factor=0.0)
    probe = Probe(ros, sim)
    stop = threading.Event()
    runner = threading.Thread(target=run_paced, args=(sim, stop), daemon=True)
    runner.start()
    try:
        for _ in range(10):
            assert wait_for(lambda: sim.step_count > 0, 10.0)
            reply = pause(probe, True)
            facts = json.loads(reply.message)
            steps = sim.step_count
            assert facts['step'] == steps and facts['sim_time_ns'] == steps * 10**9 // 240
            assert not wait_for(lambda: sim.step_count != steps, 0.05)
            pause(probe, False)
    finally:
        stop.set()
        runner.join(5.0)
    assert not runner.is_alive()


@pytest.mark.parametrize('paused', [False, True])
def test_reset_restores_robot_keeps_clock(ros, paused):
    """~/reset puts the robot back and clears odometry and command; the clock moves on."""
    sim = make_sim(ros, start_paused=paused)
    probe = Probe(ros, sim)
    probe.drive(0.3, 0.3, 1.0)
    before_x = latest_truth(sim)[0]
    assert before_x > 0.1
    step_before = sim.step_count
    response = trigger(probe, 'reset')
    assert response.success
    facts = json.loads(response.message)
    assert facts['step'] == step_before
    assert facts['sim_time'] == pytest.approx(step_before / 240, abs=1e-9)
    x, y, yaw = latest_truth(sim)
    assert abs(x) < 1e-6 and abs(y) < 1e-6 and abs(yaw) < 1e-6
    controller = sim.simulation.robot.controller
    assert controller.odometry.x_m == 0.0 and controller.odometry.yaw_rad == 0.0
    assert controller.wheel_targets == (0.0, 0.0)
    body = sim.simulation.robot.body
    states = body.joint_states([j.index for j in body.movable_joints()])
    assert max(abs(p) for p in states.positions) < 1e-9
    assert max(abs(v) for v in states.velocities) < 1e-9
    sim.advance(10)
    assert sim.step_count == step_before + 10
    reset_ns = facts['sim_time_ns']
    truths = probe.messages['ground_truth']
    assert wait_for(lambda: truths and truths[-1].header.stamp.sec * 10**9
                    + truths[-1].header.stamp.nanosec > reset_ns)
    after = [m for m in truths if m.header.stamp.sec * 10**9 + m.header.stamp.nanosec > reset_ns]
    assert abs(after[0].pose.pose.position.x) < 1e-3  # the next publication: reset
    # One state per stamp: nothing was published twice at the reset's step.
    for topic in ('clock', 'ground_truth', 'odom', 'joint_states'):
        stamps = [m.clock if topic == 'clock' else m.header.stamp for m in probe.messages[topic]]
        ns = [s.sec * 10**9 + s.nanosec for s in stamps]
        assert all(b > a for a, b in zip(ns, ns[1:])), topic


def test_in_process_runs_are_bit_identical():
    """The same command schedule at the same steps gives identical states, twice."""
    from r2d2_sim.testing import RosHarness
    runs = []
    for _ in range(2):
        harness = RosHarness()
        try:
            runs.append(_run_schedule_in_process(harness))
        finally:
            harness.close()
    assert runs[0] == runs[1]
    assert runs[0][-1][2] != runs[0][0][2]  # and the robot did move


def test_start_paused_parameter_holds_time(ros):
    """start_paused: no step is taken until asked."""
    sim = make_sim(ros, start_paused=True)
    assert sim.paused and sim.step_count == 0
    assert sim.get_parameter('start_paused').value is True
