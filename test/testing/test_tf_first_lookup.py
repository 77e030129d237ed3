"""The in-process harness's first lookup_transform, after time has moved: the current state."""

import importlib.util

import pytest


@pytest.mark.skipif(importlib.util.find_spec('tf2_msgs') is None, reason='tf2_msgs is needed')
@pytest.mark.parametrize('robots', [None, {'a': {}}], ids=['one robot', 'a listed robot'])
def test_the_first_lookup_after_advancing_finds_the_current_transform(r2d2_sim_factory, robots):
    """Driven for 1 s, no listen_tf() before: odom -> base_link is the latest publication's."""
    harness = r2d2_sim_factory(cmd_vel_timeout=0.0, **({'robots': robots} if robots else {}))
    robot = harness.robot()
    robot.send_cmd_vel(linear=0.3)
    harness.advance(seconds=1.0)
    prefix = 'a/' if robots else ''
    transform = robot.lookup_transform(prefix + 'odom', prefix + 'base_link')
    assert transform.stamp_ns == harness.last_publication_ns()
    odom = robot.odom().pose.pose.position
    assert transform.transform.translation[0] == pytest.approx(odom.x, abs=1e-6)
    assert odom.x > 0.2


@pytest.mark.skipif(importlib.util.find_spec('tf2_msgs') is None, reason='tf2_msgs is needed')
@pytest.mark.parametrize('how', ['reset_world', 'load_world'])
def test_a_lookup_after_time_went_back_is_of_the_new_run_not_the_old(r2d2_sim, how):
    """Driven 2 s, time back to 0, 1 s standing: the TF of the new run, not the old run's."""
    r2d2_sim.lookup_transform('odom', 'base_link')  # listening from the start: the harness,
    r2d2_sim.robot().lookup_transform('odom', 'base_link')  # and the robot's handle
    r2d2_sim.send_cmd_vel(linear=0.5)
    r2d2_sim.advance(seconds=2.0)
    assert r2d2_sim.lookup_transform('odom', 'base_link').transform.translation[0] > 0.5
    r2d2_sim.send_cmd_vel(linear=0.0)
    if how == 'reset_world':
        r2d2_sim.reset_world()
    else:
        r2d2_sim.load_world('empty.world.yaml')
    r2d2_sim.advance(seconds=1.0)
    odom = r2d2_sim.odom().pose.pose.position
    assert abs(odom.x) < 0.05
    for lookup in (r2d2_sim.lookup_transform, r2d2_sim.robot().lookup_transform):
        transform = lookup('odom', 'base_link')
        assert transform.stamp_ns == r2d2_sim.last_publication_ns() < 2_000_000_000
        assert transform.transform.translation[0] == pytest.approx(odom.x, abs=1e-6)


@pytest.mark.skipif(importlib.util.find_spec('tf2_msgs') is None, reason='tf2_msgs is needed')
def test_a_callbacks_error_is_not_swallowed_by_a_lookup(r2d2_sim_factory):
    """A callback raised between harness calls: the next one, a lookup, raises it; once."""
    import threading
    from r2d2_sim.testing import CallbackError
    from std_msgs.msg import Empty
    harness = r2d2_sim_factory()
    harness.advance()
    node = harness.create_node('raiser')
    raised = threading.Event()

    def fails(msg):
        raised.set()
        raise ValueError('mine')
    node.create_subscription(Empty, 'poke', fails, 10)
    node.create_publisher(Empty, 'poke', 10).publish(Empty())
    assert raised.wait(10.0)  # run by the harness's spinning thread, between calls
    with pytest.raises(CallbackError, match='ValueError: mine'):
        harness.lookup_transform('odom', 'base_link')
    assert harness.lookup_transform('odom', 'base_link').stamp_ns > 0  # said once


def test_state_and_calls_after_unload_or_close_are_one_line_at_once(r2d2_sim_factory):
    """No world: the state readers say so at once; a closed harness: lookups and services."""
    import time
    from std_srvs.srv import Trigger
    from r2d2_sim.testing import HarnessError
    harness = r2d2_sim_factory()
    robot = harness.robot()
    harness.unload_world()
    started = time.monotonic()
    for read in (robot.odom, robot.ground_truth):
        with pytest.raises(HarnessError, match=r'^no world is loaded \(unload_world\)'):
            read()
    assert time.monotonic() - started < 5.0  # not the 10 s deadline
    harness.load_world('empty.world.yaml')
    if importlib.util.find_spec('tf2_msgs') is not None:
        harness.lookup_transform('odom', 'base_link')  # a listener made while open
    harness.close()
    for call in (lambda: harness.lookup_transform('odom', 'base_link'),
                 lambda: harness.call_service(Trigger, '/r2d2_sim/get_status',
                                              Trigger.Request())):
        with pytest.raises(HarnessError, match='^the harness is closed'):
            call()
