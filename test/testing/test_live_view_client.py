"""
The public LiveViewClient against a simulator's live view, as a user's CI check would use it.

The simulator runs in the test's process (``SimHarness``, moved step by
step); the client is the one :mod:`r2d2_sim.testing` exports.
"""

import socket
import threading

from nav_msgs.msg import Odometry
import pytest
from rclpy.serialization import deserialize_message

from r2d2_sim.client import stamp_ns
from r2d2_sim.recording.sink import FoxgloveSink
from r2d2_sim.testing import LiveMessage, LiveViewClient, LiveViewError, SimHarness
from sample_messages import TOPICS


def free_port():
    """Return a TCP port nothing listens on now."""
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def test_a_ci_check_lists_channels_and_reads_a_topic_with_its_log_times():
    """Channels with ROS types; /odom's bytes decode, logged at their stamps; time is sim time."""
    port = free_port()
    with SimHarness(foxglove_port=port) as harness, LiveViewClient(port) as view:
        channels = view.wait_for_channels(['/odom', '/clock', '/robot_description'])
        assert channels['/odom']['schemaName'] == 'nav_msgs/msg/Odometry'
        assert channels['/odom']['encoding'] == 'cdr'
        assert view.server_info['name'] == 'r2d2_sim'
        view.subscribe(['/odom'])
        for _ in range(50):  # until the subscription is served and 3 arrived
            harness.advance(steps=24)
            if view.pump(lambda: len(view.messages['/odom']) >= 3, timeout_s=0.2):
                break
        odom = view.wait_for_messages('/odom', count=3)
        assert all(isinstance(m, LiveMessage) for m in odom)
        for log_time_ns, data in odom:
            assert stamp_ns(deserialize_message(data, Odometry).header.stamp) == log_time_ns
        for _ in range(50):  # time goes out at most 30 times a wall second: step on till it does
            harness.advance(steps=24)
            if view.pump(lambda: view.times, timeout_s=0.1):
                break
        assert view.times and max(view.times) <= harness.sim.sim_time_ns
        latched = view.wait_for_messages('/robot_description')  # latched: arrives at once
        assert b'r2d2' in latched[0].data


def test_unsubscribed_and_unadvertised_topics_stop_arriving():
    """After unsubscribe nothing more is kept; a closed channel leaves ``channels``."""
    type_name, qos = TOPICS['/odom']
    with FoxgloveSink(port=0) as sink, LiveViewClient(sink.port) as view:
        odom = sink.channel('/odom', type_name, qos)
        view.subscribe(['/odom'])
        for _ in range(100):  # until the subscription is served
            odom.log(b'a', 1)
            if view.pump(lambda: view.messages['/odom'], timeout_s=0.1):
                break
        assert view.messages['/odom']
        view.unsubscribe(['/odom'])
        kept = len(view.messages['/odom'])
        odom.log(b'b', 2)
        odom.release()
        assert view.pump(lambda: '/odom' not in view.channels)
        assert len(view.messages['/odom']) == kept


def test_what_the_client_cannot_do_is_one_line():
    """No server, a topic never advertised, too few messages: LiveViewError with one line."""
    with pytest.raises(LiveViewError) as refused:
        LiveViewClient(free_port(), timeout_s=2.0)
    assert str(refused.value).startswith('cannot connect to the live view at ws://127.0.0.1:')
    assert '\n' not in str(refused.value)
    type_name, qos = TOPICS['/odom']
    with FoxgloveSink(port=0) as sink, LiveViewClient(sink.port, timeout_s=0.5) as view:
        sink.channel('/odom', type_name, qos)
        with pytest.raises(LiveViewError, match='does not advertise /nothing; it has /odom'):
            view.subscribe(['/nothing'])
        with pytest.raises(LiveViewError, match=r'/odom: 0 of 2 messages'):
            view.wait_for_messages('/odom', count=2)
        sink.channel('/scan', *TOPICS['/scan'])
        view.wait_for_channels(['/scan'])
        view.close()  # the connection gone: a subscription is one line, and not noted
        for call in (lambda: view.subscribe(['/scan']), lambda: view.unsubscribe(['/odom'])):
            with pytest.raises(LiveViewError, match='closed the connection') as gone:
                call()
            assert '\n' not in str(gone.value)
        assert '/scan' not in view._subscription_of_topic


def test_a_client_that_left_messages_unread_closes_without_waiting_out_the_timeout():
    """Unread messages do not stall the reader, so close() sees the connection end at once."""
    type_name, qos = TOPICS['/odom']
    with FoxgloveSink(port=0) as sink:
        odom = sink.channel('/odom', type_name, qos)
        view = LiveViewClient(sink.port)
        view.subscribe(['/odom'])
        for _ in range(100):  # until the subscription is served
            odom.log(b'a', 1)
            if view.pump(lambda: view.messages['/odom'], timeout_s=0.1):
                break
        for stamp in range(200):  # far more than a bounded reader queue holds (16)
            odom.log(b'b', stamp)
        closing = threading.Thread(target=view.close, daemon=True)
        closing.start()
        # A stalled reader never reads the end of the connection: close() then waits
        # out websockets' close_timeout (10 s). A deadline of half that tells them apart.
        closing.join(timeout=5.0)
        assert not closing.is_alive()
