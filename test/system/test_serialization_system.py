"""
MessageTemplate's patched bytes reach a typed subscriber in another process, value for value.

The bytes themselves are checked against the serializer's in
ros/test_serialization.py; the random values both draw are in helpers.py.
"""

import json
import os
import random
import struct
import subprocess
import sys
from typing import List, Sequence

from helpers import floats64, header, stamp, text
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState

from r2d2_sim.ros.serialization import MessageTemplate
from r2d2_sim.testing import wait_for


LISTENER = r'''
import json, sys, time
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState

domain_id, expected, timeout_s = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
context = Context()
rclpy.init(context=context, domain_id=domain_id)
node = rclpy.create_node('serialization_listener', context=context)
qos = QoSProfile(depth=expected, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.TRANSIENT_LOCAL)
counts = {'joint_states': 0, 'odom': 0}


def report(topic, msg, **values):
    counts[topic] += 1
    stamp = [msg.header.stamp.sec, msg.header.stamp.nanosec]
    print(json.dumps(dict(topic=topic, stamp=stamp, frame_id=msg.header.frame_id, **values)),
          flush=True)


def on_joints(msg):
    report('joint_states', msg, name=list(msg.name), position=list(msg.position),
           velocity=list(msg.velocity), effort=list(msg.effort))


def on_odom(msg):
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    v, w = msg.twist.twist.linear, msg.twist.twist.angular
    report('odom', msg, child_frame_id=msg.child_frame_id,
           pose=[p.x, p.y, p.z, q.x, q.y, q.z, q.w], twist=[v.x, v.y, v.z, w.x, w.y, w.z],
           covariance=list(msg.pose.covariance))


node.create_subscription(JointState, 'joint_states', on_joints, qos)
node.create_subscription(Odometry, 'odom', on_odom, qos)
executor = SingleThreadedExecutor(context=context)
executor.add_node(node)
deadline = time.monotonic() + timeout_s
try:
    while min(counts.values()) < expected and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
finally:
    executor.shutdown()
    node.destroy_node()
    rclpy.try_shutdown(context=context)
'''


def bits(values: Sequence[float]) -> List[bytes]:
    """Return the float64 bit patterns of ``values``: exact, and NaN equals NaN."""
    return [struct.pack('<d', value) for value in values]


def test_typed_subscriber_in_another_process_receives_patched_bytes(monkeypatch):
    """publisher.publish(template.to_bytes()) reaches a typed subscription, value for value."""
    import rclpy
    from rclpy.context import Context
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    messages = 20
    # Domains 170-199 are this project's share of the machine; discovery stays local.
    domain_id = 170 + os.getpid() % 30
    monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id), PYTHONUNBUFFERED='1')
    listener = subprocess.Popen([sys.executable, '-c', LISTENER, str(domain_id),
                                 str(messages), '15'],
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = None
    try:
        node = rclpy.create_node('serialization_talker', context=context)
        # Transient local with room for every message: whatever is published before
        # the listener's reader has matched this writer still reaches it.
        qos = QoSProfile(depth=messages, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        joint_pub = node.create_publisher(JointState, 'joint_states', qos)
        odom_pub = node.create_publisher(Odometry, 'odom', qos)

        rng = random.Random(80)
        names = [text(rng, length) for length in (3, 0, 7, 12, 1)]
        joints = MessageTemplate(JointState(header=header('base', 0, 0), name=names,
                                            position=[0.0] * 5, velocity=[0.0] * 5,
                                            effort=[0.0] * 5))
        joint_slots = [joints.stamp()] + [joints.field(f) for f in ('position', 'velocity',
                                                                    'effort')]
        covariance = floats64(rng, 36)
        odom_msg = Odometry(header=header('odom', 0, 0), child_frame_id='base_footprint')
        odom_msg.pose.covariance = covariance
        odom = MessageTemplate(odom_msg)
        odom_slots = [odom.stamp(), odom.field('pose.pose'), odom.field('twist.twist')]
        assert wait_for(lambda: listener.poll() is not None or (
            joint_pub.get_subscription_count() > 0 and odom_pub.get_subscription_count() > 0),
            timeout_s=10.0), 'the listener never subscribed'
        assert listener.poll() is None, listener.communicate()[1][-2000:]

        sent = {'joint_states': [], 'odom': []}
        for _ in range(messages):
            state = [stamp(rng)] + [floats64(rng, 5) for _ in range(3)]
            joint_slots[0].set(*state[0])
            for slot, values in zip(joint_slots[1:], state[1:]):
                slot.set(values)
            sent['joint_states'].append(state)
            joint_pub.publish(joints.to_bytes())
            state = [stamp(rng), floats64(rng, 7), floats64(rng, 6)]
            odom_slots[0].set(*state[0])
            odom_slots[1].set(state[1])
            odom_slots[2].set(state[2])
            sent['odom'].append(state)
            odom_pub.publish(odom.to_bytes())

        out, err = listener.communicate(timeout=20)
        received = {'joint_states': [], 'odom': []}
        for line in out.splitlines():
            report = json.loads(line)
            received[report['topic']].append(report)
        assert [len(received[t]) for t in received] == [messages, messages], err[-2000:]
        for (stamp_value, *arrays), report in zip(sent['joint_states'], received['joint_states']):
            assert report['stamp'] == list(stamp_value)
            assert report['frame_id'] == 'base' and report['name'] == names
            for key, values in zip(('position', 'velocity', 'effort'), arrays):
                assert bits(report[key]) == bits(values), key
        for (stamp_value, pose, twist), report in zip(sent['odom'], received['odom']):
            assert report['stamp'] == list(stamp_value)
            assert (report['frame_id'], report['child_frame_id']) == ('odom', 'base_footprint')
            assert bits(report['pose']) == bits(pose)
            assert bits(report['twist']) == bits(twist)
            assert bits(report['covariance']) == bits(covariance)
    finally:
        if listener.poll() is None:
            listener.kill()
            listener.communicate()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=context)
