"""
Clauses of ROS 2's simulation standard that a client saw broken: state, clock, reset scopes.

In process, through the standard's services: each reply and what a node on
simulated time sees on ``/clock`` afterwards.
"""

import pytest
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from simulation_interfaces import msg, srv
from geometry_msgs.msg import Twist

from r2d2_sim.client import stamp_ns, wait_for
from r2d2_sim.model.timing import NS_PER_S

STATE = msg.SimulationState
OK = msg.Result.RESULT_OK
BOX = ('<robot name="box"><link name="box"><inertial><mass value="1"/><inertia ixx="0.01" '
       'iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial><collision><geometry>'
       '<box size="0.2 0.2 0.2"/></geometry></collision></link></robot>')


def set_state(harness, state):
    """Ask for a simulation state; return the reply's result code."""
    request = srv.SetSimulationState.Request()
    request.state.state = state
    return harness.call_service(srv.SetSimulationState, '/set_simulation_state',
                                request).result.result


def get_state(harness):
    """Return the standard's simulation state now."""
    return harness.call_service(srv.GetSimulationState, '/get_simulation_state',
                                srv.GetSimulationState.Request()).state.state


def reset(harness, scope):
    """Reset with ``scope``; return the reply's result code."""
    return harness.call_service(srv.ResetSimulation, '/reset_simulation',
                                srv.ResetSimulation.Request(scope=scope)).result.result


@pytest.fixture
def r2d2_sim_parameters():
    """Start paused, as a simulator the standard starts is: STOPPED."""
    return {'cmd_vel_timeout': 0.0, 'start_paused': True}


@pytest.fixture
def clock(r2d2_sim):
    """Return the /clock messages a node on simulated time receives, in a list."""
    seen = []
    r2d2_sim.create_node('clock_watcher').create_subscription(Clock, '/clock', seen.append, 100)
    return seen


def test_playing_then_pausing_before_a_step_is_paused_not_stopped(r2d2_sim):
    """STOPPED -> PLAYING -> PAUSED with no step between: PAUSED, and PAUSED again is 101."""
    assert get_state(r2d2_sim) == STATE.STATE_STOPPED
    assert set_state(r2d2_sim, STATE.STATE_PLAYING) == OK
    assert set_state(r2d2_sim, STATE.STATE_PAUSED) == OK
    assert r2d2_sim.sim.step_count == 0
    assert get_state(r2d2_sim) == STATE.STATE_PAUSED
    assert set_state(r2d2_sim, STATE.STATE_PAUSED) == \
        srv.SetSimulationState.Response.ALREADY_IN_TARGET_STATE
    assert set_state(r2d2_sim, STATE.STATE_STOPPED) == OK  # a full reset: STOPPED again
    assert get_state(r2d2_sim) == STATE.STATE_STOPPED


@pytest.mark.parametrize('how', ['reset TIME', 'stopped'])
def test_clock_says_time_zero_after_a_reset_while_paused(r2d2_sim, clock, how):
    """A node on simulated time sees 0 on /clock at once, not the old time until physics moves."""
    assert set_state(r2d2_sim, STATE.STATE_PLAYING) == OK
    assert set_state(r2d2_sim, STATE.STATE_PAUSED) == OK
    r2d2_sim.advance(seconds=2.0)
    assert wait_for(lambda: clock and stamp_ns(clock[-1].clock) == 2 * NS_PER_S)
    if how == 'stopped':
        assert set_state(r2d2_sim, STATE.STATE_STOPPED) == OK
    else:
        assert reset(r2d2_sim, srv.ResetSimulation.Request.SCOPE_TIME) == OK
    assert r2d2_sim.sim.sim_time_ns == 0
    assert wait_for(lambda: stamp_ns(clock[-1].clock) == 0), stamp_ns(clock[-1].clock)


@pytest.mark.parametrize('scope', [0, 255], ids=['SCOPE_DEFAULT', 'SCOPE_ALL'])
def test_default_and_all_reset_time_state_and_spawned(r2d2_sim, clock, scope):
    """Scope 0 and 255 are TIME | STATE | SPAWNED: time 0, the robot home, the box gone."""
    r2d2_sim.spawn(BOX, position=(1.5, 0.0, 0.1))
    r2d2_sim.send_cmd_vel(linear=0.3)
    r2d2_sim.advance(seconds=1.0)
    assert r2d2_sim.entity_state('r2d2').position[0] > 0.2
    assert reset(r2d2_sim, scope) == OK
    assert r2d2_sim.sim.step_count == 0 and r2d2_sim.sim.sim_time_ns == 0
    assert wait_for(lambda: stamp_ns(clock[-1].clock) == 0)
    assert r2d2_sim.entities() == ['ground_plane', 'r2d2']
    assert r2d2_sim.entity_state('r2d2').position[0] == pytest.approx(0.0, abs=1e-9)


def test_a_best_effort_cmd_vel_publisher_is_named(ros, capfd):
    """ROS matches no best-effort publisher to the reliable cmd_vel: the simulator says so."""
    from helpers import make_sim
    sim = make_sim(ros, node_kwargs={'graph_check_period_s': 0.05})
    other = ros.create_node('best_effort_teleop', use_sim_time=False)
    publisher = other.create_publisher(
        Twist, 'cmd_vel', QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    seen = []

    def warned():
        publisher.publish(Twist())
        sim.advance(1)
        seen.extend(line for line in capfd.readouterr().err.splitlines()
                    if 'best_effort_teleop publishes' in line)
        return seen
    assert wait_for(warned, 10.0), 'no warning about the best-effort publisher'
    assert '/best_effort_teleop publishes on /cmd_vel best effort' in seen[0]
    assert 'publish cmd_vel reliable' in seen[0]
    assert sim.commands_received == 0
