"""
Outputs nobody takes are not built, and a subscriber that comes later gets what it always got.

An output asks its publisher how many subscriptions it matched before it
builds a message (issue 38: "outputs computed only when someone takes
them"). The measurements go on whether or not anyone listens (the noise
streams, the odometry, the contact state), so a subscriber that arrives
late receives, from then on, the very bytes a subscriber present from the
start receives. The recording takes everything (test/recording checks its contents), the
live view what a viewer subscribes to; ``/tf`` kept for the harness's own
lookups is built when asked.
"""

import json

from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu, JointState, LaserScan
from tf2_msgs.msg import TFMessage

from helpers import make_sim, wait_for

# Noise on every noisy reading: a skipped build must not move any stream.
NOISY = dict(cmd_vel_timeout=0.0, scan_rate=60.0, imu_rate=120.0, noise_seed=7,
             scan_noise_std=0.02, imu_angular_velocity_noise_std=0.01,
             imu_linear_acceleration_noise_std=0.05, imu_orientation_noise_std=0.01,
             encoder_noise_std=0.01)
TOPICS = {'joint_states': JointState, 'odom': Odometry, 'ground_truth': Odometry,
          'scan': LaserScan, 'imu': Imu}
STEPS, LATE = 96, 48
# Sensor-data (best effort) subscriptions for the sensors, default ones for the state: both
# match the outputs' reliable publishers.
SENSORS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)
QOS = {'joint_states': 1000, 'odom': 1000, 'ground_truth': 1000, 'scan': SENSORS, 'imu': SENSORS}


class CountingPublisher:
    """Counts an rclpy publisher's publish calls, passing each on."""

    def __init__(self, output):
        self.calls = 0
        publisher = output._publisher
        publish = publisher.publish

        def counted(msg):
            self.calls += 1
            publish(msg)
        publisher.publish = counted


def stamp_ns(raw, msg_type):
    stamp = deserialize_message(raw, msg_type).header.stamp
    return stamp.sec * 10**9 + stamp.nanosec


def drive_and_listen(ros, subscribe_at, **params):
    """Drive a noisy run of STEPS; listen (raw bytes) to TOPICS from step ``subscribe_at``."""
    sim = make_sim(ros, **NOISY, **params)
    sim.simulation.robot.command(0.4, 0.8)
    heard = {topic: [] for topic in TOPICS}
    node = ros.create_node('listener', use_sim_time=False)
    for step in range(0, STEPS, 8):
        if step == subscribe_at:
            subscriptions = [node.create_subscription(msg_type, topic, heard[topic].append,
                                                      QOS[topic], raw=True)
                             for topic, msg_type in TOPICS.items()]
            assert wait_for(lambda: all(s.get_publisher_count() for s in subscriptions))
            outputs = sim.robots[0].outputs
            publishers = [output._publisher for output in
                          outputs.state[:3] + [outputs.scan, outputs.imu]]
            assert wait_for(lambda: all(p.get_subscription_count() for p in publishers))
        sim.advance(8)
    # Every state topic once a step from the subscription on, scan and IMU at their rates.
    expected = {'joint_states': STEPS - subscribe_at, 'odom': STEPS - subscribe_at,
                'ground_truth': STEPS - subscribe_at, 'scan': (STEPS - subscribe_at) // 4,
                'imu': (STEPS - subscribe_at) // 2}
    assert wait_for(lambda: all(len(heard[t]) >= n for t, n in expected.items())), \
        {t: len(heard[t]) for t in TOPICS}
    node.destroy_node()  # else its subscriptions take the next run's messages from its start
    return {topic: {stamp_ns(raw, TOPICS[topic]): raw for raw in messages}
            for topic, messages in heard.items()}, sim


def test_an_output_nobody_takes_builds_nothing(ros):
    sim = make_sim(ros, **NOISY)
    outputs = sim.robots[0].outputs
    counters = [CountingPublisher(output) for output in outputs.state[:3]]
    counters += [CountingPublisher(outputs.scan), CountingPublisher(outputs.imu)]
    sim.advance(24)
    assert [c.calls for c in counters] == [0, 0, 0, 0, 0]
    node = ros.create_node('listener', use_sim_time=False)
    heard = []
    subscription = node.create_subscription(JointState, 'joint_states', heard.append, 100)
    assert wait_for(lambda: subscription.get_publisher_count() > 0)
    assert wait_for(lambda: outputs.state[0]._publisher.get_subscription_count() > 0)
    sim.advance(24)
    assert [c.calls for c in counters] == [24, 0, 0, 0, 0]
    assert wait_for(lambda: len(heard) == 24)
    assert heard[-1].header.stamp.nanosec == round(48 / 240 * 1e9)


def test_a_late_subscriber_hears_the_bytes_of_one_there_from_the_start(ros):
    early, early_sim = drive_and_listen(ros, 0)
    early_state = early_sim.simulation.robot.body.base_state()
    early_sim.destroy_node()
    late, late_sim = drive_and_listen(ros, LATE)
    assert min(late['joint_states']) == (LATE + 1) * 10**9 // 240  # nothing heard before
    for topic in TOPICS:
        assert late[topic], topic
        for stamp, raw in late[topic].items():
            assert raw == early[topic][stamp], (topic, stamp)
    # Nothing the run measured moved: the noise streams and the odometry went on unheard.
    assert late_sim.simulation.robot.body.base_state() == early_state


def test_tf_is_built_when_asked_and_is_what_a_subscriber_hears(ros):
    sim = make_sim(ros, cmd_vel_timeout=0.0)
    tf = sim.robots[0].outputs.tf
    counter = CountingPublisher(tf)
    sim.simulation.robot.command(0.3, 0.0)
    sim.advance(12)
    assert counter.calls == 0
    asked = deserialize_message(tf.latest, TFMessage)
    stamp = asked.transforms[0].header.stamp
    assert (stamp.sec, stamp.nanosec) == (0, round(12 / 240 * 1e9))
    assert asked.transforms[0].transform.translation.x > 0.0
    assert tf.latest is tf.latest  # built once per publication
    heard = []
    node = ros.create_node('listener', use_sim_time=False)
    node.create_subscription(TFMessage, '/tf', heard.append, 100, raw=True)
    assert wait_for(lambda: tf._publisher.get_subscription_count() > 0)
    sim.advance(1)
    assert counter.calls == 1
    assert wait_for(lambda: len(heard) == 1)
    assert heard[0] == tf.latest


def test_a_recording_takes_every_message_with_nobody_subscribed(tmp_path):
    from r2d2_sim.recording.reader import RecordingFile
    from r2d2_sim.testing import SimHarness
    path = tmp_path / 'run.mcap'
    with SimHarness(record=str(path), cmd_vel_timeout=0.0, scan_rate=60.0,
                    imu_rate=120.0) as harness:
        harness.advance(48)
    recording = RecordingFile(path)
    counts = {channel.topic: recording.message_counts.get(channel_id, 0)
              for channel_id, channel in recording.channels.items()}
    # Every step of the 48 (and the start-up's publication at 0 for the state).
    assert counts['/joint_states'] >= 48 and counts['/ground_truth'] >= 48, counts
    assert counts['/scan'] >= 12 and counts['/imu'] >= 24 and counts['/tf'] >= 48, counts


def test_tf_latest_is_the_newest_frame_after_its_subscriber_left(ros):
    sim = make_sim(ros, cmd_vel_timeout=0.0)
    tf = sim.robots[0].outputs.tf
    node = ros.create_node('listener', use_sim_time=False)
    subscription = node.create_subscription(TFMessage, '/tf', lambda _: None, 10)
    assert wait_for(lambda: tf._publisher.get_subscription_count() > 0)
    sim.advance(1)  # published, and kept as latest
    node.destroy_subscription(subscription)
    assert wait_for(lambda: tf._publisher.get_subscription_count() == 0)
    sim.advance(1)  # not published: latest is built from this frame when asked
    stamp = deserialize_message(tf.latest, TFMessage).transforms[0].header.stamp
    assert (stamp.sec, stamp.nanosec) == (0, round(2 / 240 * 1e9))


def test_contacts_unheard_still_end_as_they_would_have_been_heard():
    # The DELETEALL that follows the last contact is due at the step contact ends,
    # heard or not: a subscriber that comes back later gets no stale one.
    from r2d2_sim.ros.outputs import ContactsOutput
    from r2d2_sim.sim.oracles import Touch
    from r2d2_sim.sim.settings.config import parse_config
    from test_outputs import RecordingNode
    node = RecordingNode()
    output = ContactsOutput(node, parse_config({'publish_contacts': True}))
    published = node.publishers['contacts'].published
    listened = [True]
    output._demand = lambda: listened[0]
    touch = Touch('box', 'base_link', 'box_link', (1.0, 0.0, 0.1), 5.0)
    output.publish(10, [touch])   # heard: the contact
    listened[0] = False
    output.publish(20, [])        # the contact ends while nobody listens
    listened[0] = True
    output.publish(30, [])        # nothing touched since: nothing to say
    assert len(published) == 1
    output.publish(40, [touch])
    output.publish(50, [])
    assert len(published) == 3    # the contact, then its end


def test_a_latched_publisher_is_always_taken(ros):
    # A late joiner of a transient-local topic gets what was published before it came.
    from rclpy.qos import DurabilityPolicy
    from std_msgs.msg import String
    from r2d2_sim.ros.mirror import demand
    node = ros.create_node('latched', use_sim_time=False)
    latched = node.create_publisher(
        String, 'latched', QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    volatile = node.create_publisher(String, 'volatile', 1)
    assert demand(latched)() == 1 and demand(volatile)() == 0


def test_the_live_view_takes_only_what_a_viewer_subscribes_to(ros):
    # A live view nobody watches builds nothing; a viewer's topic is built, and is what
    # a DDS subscriber of that step hears.
    import socket
    from r2d2_sim.testing import LiveViewClient
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        port = sock.getsockname()[1]
    sim = make_sim(ros, foxglove_port=port, cmd_vel_timeout=0.0)
    status = json.loads(sim.status())  # where to point a viewer
    assert (status['live_view'], status['recording']) == (f'ws://127.0.0.1:{port}', None)
    state = {output._publisher.topic_name: output
             for output in sim.robots[0].outputs.state[:3]}
    assert sorted(state) == ['/ground_truth', '/joint_states', '/odom']
    counters = [CountingPublisher(state[topic]) for topic in sorted(state)]
    sim.simulation.robot.command(0.3, 0.0)
    sim.advance(24)
    assert [c.calls for c in counters] == [0, 0, 0]
    with LiveViewClient(port) as viewer:
        viewer.wait_for_channels(['/odom'])
        viewer.subscribe(['/odom'])
        channel = state['/odom']._publisher.channel
        assert viewer.pump(channel.taken)  # the server took the subscription
        sim.advance(24)
        assert [c.calls for c in counters] == [0, 0, 24]
        odom = viewer.wait_for_messages('/odom', 24)
        assert odom[-1].log_time_ns == round(48 / 240 * 1e9)
        viewer.unsubscribe(['/odom'])
        assert viewer.pump(lambda: not channel.taken())
        sim.advance(24)
        assert [c.calls for c in counters] == [0, 0, 24]
