"""
LockstepExecutor: rclpy's executor with a kept wait set, and the lockstep guarantees it keeps.

Each test builds its own context on a leased domain (``RosHarness``) or a
whole ``SimHarness``; the README's closed-loop guarantees (every publication
answered before the next step, bit-for-bit runs, callback errors raised) are
in test_testing_api.py and test/examples.
"""

import asyncio

from std_msgs.msg import Int32
from std_srvs.srv import Trigger

from r2d2_sim.testing import CallbackError, RosHarness
from r2d2_sim.testing.lockstep import LockstepExecutor

import pytest


@pytest.fixture
def ros():
    """Provide a context of its own on a leased domain, with the harness's executor."""
    with RosHarness() as harness:
        yield harness


def poll_until_idle(harness):
    """Run callbacks in this thread until a poll finds none (as a lockstep period does)."""
    harness.settle()


def test_the_harness_executor_is_the_lockstep_one(ros):
    """The executor of RosHarness (and so of SimHarness) is a LockstepExecutor."""
    assert isinstance(ros.executor, LockstepExecutor)


def test_a_chain_of_publications_runs_to_its_end_in_one_settle(ros):
    """A -> B -> C through two subscriptions: settle returns once the last has run."""
    node = ros.create_node('chain', use_sim_time=False)
    seen = []
    out = node.create_publisher(Int32, 'b', 10)
    node.create_subscription(Int32, 'a', lambda msg: out.publish(Int32(data=msg.data + 1)), 10)
    node.create_subscription(Int32, 'b', lambda msg: seen.append(msg.data), 10)
    start = node.create_publisher(Int32, 'a', 10)
    assert ros._wait(lambda: start.get_subscription_count() and out.get_subscription_count(),
                     'matched')
    for value in range(5):
        start.publish(Int32(data=value))
        poll_until_idle(ros)
        assert seen[-1] == value + 1  # nothing left for later
    assert seen == [1, 2, 3, 4, 5]


def test_a_service_called_from_a_callback_is_answered_within_the_settle(ros):
    """A client in a callback, its service, its response: all before settle returns."""
    node = ros.create_node('caller', use_sim_time=False)
    answers = []
    node.create_service(Trigger, 'ping', lambda request, response: setattr(
        response, 'message', 'pong') or response)
    client = node.create_client(Trigger, 'ping')
    future_holder = []
    node.create_subscription(Int32, 'go', lambda msg: future_holder.append(
        client.call_async(Trigger.Request())), 10)
    go = node.create_publisher(Int32, 'go', 10)
    assert ros._wait(lambda: client.service_is_ready() and go.get_subscription_count(), 'ready')
    go.publish(Int32(data=1))
    poll_until_idle(ros)
    assert future_holder and future_holder[0].done()
    answers.append(future_holder[0].result().message)
    assert answers == ['pong']


def test_entities_made_and_destroyed_between_polls_are_gathered_anew(ros):
    """A subscription made after a poll gets its message; a destroyed one is never called."""
    node = ros.create_node('changing', use_sim_time=False)
    publisher = node.create_publisher(Int32, 't', 10)
    poll_until_idle(ros)  # a wait set gathered without the subscriptions
    first, second = [], []
    sub1 = node.create_subscription(Int32, 't', first.append, 10)
    node.create_subscription(Int32, 't', second.append, 10)
    assert ros._wait(lambda: publisher.get_subscription_count() == 2, 'matched')
    publisher.publish(Int32(data=1))
    poll_until_idle(ros)
    assert len(first) == 1 and len(second) == 1
    node.destroy_subscription(sub1)
    publisher.publish(Int32(data=2))
    poll_until_idle(ros)
    assert len(first) == 1 and [m.data for m in second] == [1, 2]


def test_a_coroutine_callback_takes_rclpys_path_and_still_runs(ros):
    """An async def callback is run by rclpy's Task machinery, awaited to its end."""
    node = ros.create_node('async_node', use_sim_time=False)
    seen = []

    async def on_message(msg):
        await asyncio.sleep(0)  # a real coroutine, not a plain function
        seen.append(msg.data)
    node.create_subscription(Int32, 'c', on_message, 10)
    publisher = node.create_publisher(Int32, 'c', 10)
    assert ros._wait(lambda: publisher.get_subscription_count(), 'matched')
    publisher.publish(Int32(data=7))
    assert ros._wait(lambda: seen == [7], 'the coroutine ran')


def test_an_error_in_a_direct_callback_is_raised_by_the_next_call(ros):
    """A plain callback run directly keeps its exception for the harness, as a Task does."""
    node = ros.create_node('raiser', use_sim_time=False)

    def fail(msg):
        raise ValueError(f'bad {msg.data}')
    node.create_subscription(Int32, 'r', fail, 10)
    publisher = node.create_publisher(Int32, 'r', 10)
    assert ros._wait(lambda: publisher.get_subscription_count(), 'matched')
    publisher.publish(Int32(data=3))
    with pytest.raises(CallbackError) as raised:
        poll_until_idle(ros)
    assert isinstance(raised.value.__cause__, ValueError) and 'bad 3' in str(raised.value)


def test_a_closed_loop_harness_polls_by_taking_and_a_client_brings_the_wait_back(
        r2d2_sim_factory):
    """The README's controller needs no wait set (sweep); a client in the harness does."""
    import importlib.util
    from pathlib import Path
    example = Path(__file__).parent.parent / 'examples' / 'test_closed_loop.py'
    spec = importlib.util.spec_from_file_location('closed_loop_example', example)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    sim = r2d2_sim_factory()
    controller = sim.add_node(module.DriveToX(context=sim.context))
    sim.advance(seconds=0.1)
    assert sim.executor._gathered.sweepable
    client = controller.create_client(Trigger, '/r2d2_sim/get_status')
    sim.advance(seconds=0.1)
    assert not sim.executor._gathered.sweepable  # its service must be waited on now
    future = client.call_async(Trigger.Request())
    sim.advance()  # answered within the period
    assert future.done() and '"paused"' in future.result().message
    controller.destroy_client(client)
    sim.advance(seconds=0.1)
    assert sim.executor._gathered.sweepable


def test_timers_on_simulated_time_fire_in_the_sweep_at_their_period(r2d2_sim_factory):
    """A 10 Hz timer on /clock ticks exactly 10 times in one simulated second."""
    sim = r2d2_sim_factory()
    node = sim.create_node('ticker')
    ticks = []
    node.create_timer(0.1, lambda: ticks.append(node.get_clock().now().nanoseconds))
    sim.advance(seconds=1.0)
    assert sim.executor._gathered.sweepable
    assert len(ticks) == 10
    assert [b - a for a, b in zip(ticks, ticks[1:])] == pytest.approx([1e8] * 9, abs=5e6)


@pytest.mark.parametrize('path', ['sweep', 'wait set'])
@pytest.mark.parametrize('publish_rate', [0.0, 50.0])
def test_a_simulated_time_nodes_clock_has_moved_before_its_messages_arrive(
        r2d2_sim_factory, path, publish_rate):
    """
    Every odom reaches a node whose clock already shows its stamp (docs/limits.md).

    The node subscribes before ``add_node`` switches it to simulated time (as
    the README's controller does), so rclpy's ``/clock`` subscription is its last.
    """
    from nav_msgs.msg import Odometry
    from rclpy.node import Node

    from r2d2_sim.testing import stamp_ns
    sim = r2d2_sim_factory(publish_rate=publish_rate)
    node = Node('listener', context=sim.context)
    ahead_ns = []
    node.create_subscription(Odometry, 'odom', lambda odom: ahead_ns.append(
        stamp_ns(odom.header.stamp) - node.get_clock().now().nanoseconds), 10)
    if path == 'wait set':  # a client: the harness waits on a wait set instead of sweeping
        node.create_client(Trigger, 'anything')
    sim.add_node(node)
    sim.advance(seconds=0.5)
    assert sim.executor._gathered.sweepable == (path == 'sweep')
    assert len(ahead_ns) == (120 if publish_rate == 0.0 else 25)
    assert set(ahead_ns) == {0}
