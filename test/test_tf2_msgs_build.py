"""tf2_msgs built by tools/build_tf2_msgs.sh: a TFMessage crosses from one process to another."""

import os
import subprocess
import sys
import time

import pytest

# A subscriber in a child process: takes the first TFMessage on the topic and
# prints it serialized (CDR, hex), so the parent can compare every field.
CHILD = r'''
import os, sys, time
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from tf2_msgs.msg import TFMessage

topic, timeout_s = sys.argv[1], float(sys.argv[2])
ctx = Context()
rclpy.init(context=ctx, domain_id=int(os.environ['ROS_DOMAIN_ID']))
try:
    node = rclpy.create_node('tf2_msgs_test_sub', context=ctx)
    got = []
    qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(TFMessage, topic, got.append, qos)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    deadline = time.monotonic() + timeout_s
    while not got and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    if not got:
        print('TIMEOUT: no TFMessage on %s within %.1f s' % (topic, timeout_s), flush=True)
        sys.exit(3)
    print('MSG ' + serialize_message(got[0]).hex(), flush=True)
finally:
    rclpy.try_shutdown(context=ctx)
'''


def _import_tfmessage():
    """Return TFMessage with its C type support loaded, or fail saying how to build it."""
    try:
        from tf2_msgs.msg import TFMessage
        TFMessage.__class__.__import_type_support__()
        return TFMessage
    except Exception as exc:  # ImportError, or a type support library not found
        problem = '%s: %s' % (type(exc).__name__, exc)
    pytest.fail('tf2_msgs is not usable in %s (%s); run: tools/build_tf2_msgs.sh %s'
                % (sys.prefix, problem, sys.prefix), pytrace=False)


def _two_transforms(TFMessage):
    """Return a TFMessage with two transforms, every field set to a distinct value."""
    from geometry_msgs.msg import TransformStamped
    msg = TFMessage()
    for i, (parent, child) in enumerate((('odom', 'base_link'), ('base_link', 'head'))):
        t = TransformStamped()
        t.header.stamp.sec = 1700000000 + i
        t.header.stamp.nanosec = 123456789 + i
        t.header.frame_id = parent
        t.child_frame_id = child
        t.transform.translation.x = 0.1 + i
        t.transform.translation.y = -2.5e-7
        t.transform.translation.z = 3.141592653589793 * (i + 1)
        t.transform.rotation.x = 0.0
        t.transform.rotation.y = 0.0
        t.transform.rotation.z = 0.7071067811865476 * (1 - 2 * i)
        t.transform.rotation.w = 0.7071067811865476
        msg.transforms.append(t)
    return msg


def test_tfmessage_crosses_processes(monkeypatch):
    """Two transforms published here arrive unchanged in a subscriber process."""
    TFMessage = _import_tfmessage()
    import rclpy
    from rclpy.context import Context
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.serialization import deserialize_message

    domain_id = 200 + os.getpid() % 30
    topic = '/tf2_msgs_build_test_%d' % os.getpid()
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id), PYTHONUNBUFFERED='1')
    msg = _two_transforms(TFMessage)

    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    child = node = None
    try:
        node = rclpy.create_node('tf2_msgs_test_pub', context=ctx)
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        pub = node.create_publisher(TFMessage, topic, qos)
        child = subprocess.Popen(
            [sys.executable, '-c', CHILD, topic, '7'], env=env,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # Publish (again) whenever a subscriber is matched, until the child
        # has taken one message and exited, or the deadline passes.
        deadline = time.monotonic() + 8.0
        while child.poll() is None and time.monotonic() < deadline:
            if pub.get_subscription_count() > 0:
                pub.publish(msg)
            time.sleep(0.02)
        try:
            out, err = child.communicate(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            child.kill()
            out, err = child.communicate()
            pytest.fail('subscriber process still running after 8 s\n' + out + err)
        assert child.returncode == 0, 'subscriber exited %d:\n%s%s' % (
            child.returncode, out, err)
        lines = [line for line in out.splitlines() if line.startswith('MSG ')]
        assert lines, 'no message printed by the subscriber:\n' + out + err
        # Compare messages, not bytes: Fast CDR leaves alignment padding in a
        # serialized message uninitialized, so equal messages may differ there.
        back = deserialize_message(bytes.fromhex(lines[0][4:]), TFMessage)
        assert back == msg, 'sent %r\nreceived %r' % (msg, back)
        assert [t.child_frame_id for t in back.transforms] == ['base_link', 'head']
    finally:
        if child is not None and child.poll() is None:
            child.kill()
            child.wait()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)
