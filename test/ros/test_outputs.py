"""
Every pre-serialized output against the typed message it stands for, for every robot.

The outputs patch bytes in place instead of filling messages, so a wrong
offset would publish garbage that only a subscriber notices. Here each
output publishes many random frames into a recording publisher; the bytes
must deserialize to exactly the message a typed implementation builds from
the same frame. (Bytes are not compared with ``serialize_message``: rmw
leaves alignment padding unwritten, so two serializations of one message can
differ there; test_serialization.py checks the written bytes.)
"""

import math
import random
from types import SimpleNamespace

from nav_msgs.msg import Odometry
import pytest
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from r2d2_sim.model.transforms import BaseState
from r2d2_sim.physics.records import JointStates
from r2d2_sim.model.kinematics import OdometryState
from r2d2_sim.ros.outputs import ClockOutput, GroundTruthOutput, JointStateOutput, OdometryOutput
from r2d2_sim.sim.settings.config import parse_config
from r2d2_sim.sim.robots.robot import Frame
from r2d2_sim.sim.simulation import Simulation
from r2d2_sim.model.transforms import yaw_to_quaternion

ROBOTS = {
    'package R2D2': {},
    'classic R2D2': {'urdf': 'r2d2.urdf', 'base_forward_axis': 'y', 'wheel_velocity_sign': -1,
                     'max_wheel_force': 20.0, 'odom_frame_id': 'o', 'base_frame_id': 'base_xy',
                     'world_frame_id': 'map_frame'},
    'robot without wheels': {'urdf': 'cube.urdf', 'left_wheel_names': [],
                             'right_wheel_names': []},
}
FRAMES = 100


class RecordingPublisher:
    """Keeps what an output publishes."""

    def __init__(self, msg_type, topic):
        self.msg_type, self.topic, self.published = msg_type, topic, []

    def publish(self, msg):
        self.published.append(msg)


class RecordingNode:
    """Stands in for the rclpy node the outputs create their publishers on."""

    def __init__(self):
        self.publishers = {}

    def create_publisher(self, msg_type, topic, qos):
        self.publishers[topic] = RecordingPublisher(msg_type, topic)
        return self.publishers[topic]


@pytest.fixture(params=ROBOTS.values(), ids=ROBOTS.keys())
def simulation(request):
    """Provide the core simulation of one supported robot."""
    sim = Simulation(parse_config(request.param))
    yield sim
    sim.close()


def random_frame(rng, joints, with_odometry):
    """Return a frame with random (sometimes extreme) values."""
    def value():
        return rng.choice([rng.uniform(-1e3, 1e3), rng.uniform(-1, 1), 0.0, -0.0, 1e-300])

    def vector(n):
        return tuple(value() for _ in range(n))
    odometry = None
    if with_odometry:
        odometry = OdometryState(x_m=value(), y_m=value(),
                                 yaw_rad=rng.uniform(-math.pi, math.pi),
                                 linear_m_s=value(), angular_rad_s=value())
    # Up to the largest stamp ROS time holds (int32 seconds: 68 years of simulated time).
    step = rng.choice([0, 1, 239, 240, rng.randrange((2**31 - 1) * 240)])
    time_ns = step * 10**9 // 240
    return Frame(step, time_ns, JointStates(vector(joints), vector(joints), vector(joints)),
                 BaseState(vector(3), vector(4), vector(3), vector(3)), odometry)


def published(publisher):
    """Deserialize everything a recording publisher got."""
    return [deserialize_message(b, publisher.msg_type) for b in publisher.published]


def test_state_outputs_publish_exactly_the_typed_messages(simulation):
    """Clock, joint_states, ground_truth and odom: 100 random frames, every field equal."""
    node, config, robot = RecordingNode(), simulation.config, simulation.robot
    clock = ClockOutput(node)
    outputs = [JointStateOutput(node, robot.movable), GroundTruthOutput(node, config)]
    if robot.controller is not None:
        outputs.append(OdometryOutput(node, config, robot.footprint_height_m))
    rng = random.Random(7)
    frames = [random_frame(rng, len(robot.movable), robot.controller is not None)
              for _ in range(FRAMES)]
    for frame in frames:
        clock.publish(frame.time_ns)
        for output in outputs:
            output.publish(frame)
    for publisher in node.publishers.values():
        assert len(publisher.published) == FRAMES
        assert all(type(b) is bytes for b in publisher.published)  # the cheap rclpy path
    names = [j.name for j in robot.movable]
    for frame, clock, joints, truth in zip(
            frames, published(node.publishers['/clock']),
            published(node.publishers['joint_states']),
            published(node.publishers['ground_truth'])):
        sec, nanosec = divmod(frame.time_ns, 10**9)
        assert clock == Clock(clock=clock.clock.__class__(sec=sec, nanosec=nanosec))
        expected = JointState(name=names, position=list(frame.joints.positions),
                              velocity=list(frame.joints.velocities),
                              effort=list(frame.joints.efforts))
        expected.header.stamp.sec, expected.header.stamp.nanosec = sec, nanosec
        assert joints == expected
        expected = Odometry()
        expected.header.stamp.sec, expected.header.stamp.nanosec = sec, nanosec
        expected.header.frame_id = config.world_frame_id
        expected.child_frame_id = config.base_frame_id
        p, o = expected.pose.pose.position, expected.pose.pose.orientation
        p.x, p.y, p.z = frame.base.position
        o.x, o.y, o.z, o.w = frame.base.orientation
        t = expected.twist.twist
        t.linear.x, t.linear.y, t.linear.z = frame.base.linear_velocity
        t.angular.x, t.angular.y, t.angular.z = frame.base.angular_velocity
        assert truth == expected
    if robot.controller is None:
        assert 'odom' not in node.publishers
        return
    for frame, odom in zip(frames, published(node.publishers['odom'])):
        expected = Odometry()
        expected.header.stamp.sec, expected.header.stamp.nanosec = divmod(frame.time_ns, 10**9)
        expected.header.frame_id = config.odom_frame_id
        expected.child_frame_id = config.base_frame_id
        for i, variance in enumerate(config.pose_covariance_diagonal):
            expected.pose.covariance[7 * i] = variance
        for i, variance in enumerate(config.twist_covariance_diagonal):
            expected.twist.covariance[7 * i] = variance
        o = frame.odometry
        p, q = expected.pose.pose.position, expected.pose.pose.orientation
        p.x, p.y, p.z = o.x_m, o.y_m, robot.footprint_height_m
        q.x, q.y, q.z, q.w = yaw_to_quaternion(o.yaw_rad)
        expected.twist.twist.linear.x = o.linear_m_s
        expected.twist.twist.angular.z = o.angular_rad_s
        assert odom == expected


def test_real_frames_round_trip(simulation):
    """Frames the simulation itself reads (not random ones) come out as they went in."""
    node = RecordingNode()
    output = JointStateOutput(node, simulation.robot.movable)
    truth = GroundTruthOutput(node, simulation.config)
    for _ in range(5):
        for _ in range(24):
            simulation.step()
        frame = simulation.read_states().measurements[0].frame
        output.publish(frame)
        truth.publish(frame)
        joints = published(node.publishers['joint_states'])[-1]
        assert tuple(joints.position) == tuple(frame.joints.positions)
        pose = published(node.publishers['ground_truth'])[-1].pose.pose
        assert (pose.position.x, pose.position.y, pose.position.z) == frame.base.position


def test_tf_output_publishes_exactly_the_typed_transforms():
    """/tf with odometry, ground truth and the package R2D2's links: every transform, stamp."""
    from r2d2_sim.ros.tf_outputs import link_transforms, TfOutput
    from r2d2_sim.model.transforms import compose, inverse, Transform
    config = parse_config({'publish_ground_truth_tf': True, 'frame_prefix': 'abc/'})
    simulation = Simulation(config)
    links = link_transforms(config, simulation.robot)
    frames, published_tf = tf_published(TfOutput, config, simulation, links, 11, True)
    assert len(published_tf) == FRAMES
    for frame, msg in zip(frames, published_tf):
        o = frame.odometry
        odom = Transform((o.x_m, o.y_m, 0.0), yaw_to_quaternion(o.yaw_rad))
        truth = true_footprint(frame, simulation.robot.footprint_height_m)
        expected = [('abc/odom', 'abc/base_footprint', odom),
                    ('world', 'abc/odom', compose(truth, inverse(odom)))]
        expected += [('abc/' + j.parent_link, 'abc/' + j.child_link, j.transform)
                     for j in links.moving(list(frame.joints.positions))]
        assert len(msg.transforms) == len(expected)
        for t, (parent, child, transform) in zip(msg.transforms, expected):
            assert (t.header.frame_id, t.child_frame_id) == (parent, child)
            assert (t.header.stamp.sec, t.header.stamp.nanosec) == divmod(frame.time_ns, 10**9)
            tr, r = t.transform.translation, t.transform.rotation
            assert (tr.x, tr.y, tr.z) == transform.translation
            assert (r.x, r.y, r.z, r.w) == transform.rotation
    simulation.close()


def tf_published(tf_output, config, simulation, links, seed, odometry):
    """Publish FRAMES random frames of ``simulation``'s robot; return them and the /tf sent."""
    node = RecordingNode()
    output = tf_output(node, config, simulation.robot, links)
    rng = random.Random(seed)
    frames = [random_frame(rng, len(simulation.robot.movable), odometry)
              for _ in range(FRAMES)]
    for frame in frames:
        output.publish(frame)
    return frames, published(node.publishers['/tf'])


def true_footprint(frame, footprint_height_m):
    """Return the footprint under the frame's true body pose (footprint -> base undone)."""
    from r2d2_sim.model.transforms import compose, IDENTITY, inverse, normalised, Transform
    base = frame.base
    return compose(Transform(base.position, normalised(base.orientation)),
                   inverse(Transform((0.0, 0.0, footprint_height_m), IDENTITY.rotation)))


def test_tf_output_of_a_robot_without_wheels_is_world_to_footprint_from_the_truth():
    """With ground truth and no wheels (no odom): world -> footprint, the truth less its height."""
    from r2d2_sim.ros.tf_outputs import TfOutput
    config = parse_config({**ROBOTS['robot without wheels'], 'publish_ground_truth_tf': True})
    simulation = Simulation(config)
    try:
        frames, published_tf = tf_published(TfOutput, config, simulation, None, 12, False)
        height_m = simulation.robot.footprint_height_m
    finally:
        simulation.close()
    assert published_tf
    for frame, msg in zip(frames, published_tf, strict=True):
        expected = true_footprint(frame, height_m)
        (t,) = msg.transforms
        assert (t.header.frame_id, t.child_frame_id) == ('world', 'base_footprint')
        tr, r = t.transform.translation, t.transform.rotation
        assert ((tr.x, tr.y, tr.z), (r.x, r.y, r.z, r.w)) == expected


def test_a_robot_of_one_link_has_no_urdf_root_below_its_base():
    """
    With link transforms, a URDF without joints (one link, its name unread) adds no frame.

    Such a URDF has no root link to hang below the base (nothing to publish,
    as robot_state_publisher publishes nothing for it); it once gave a None
    frame and a TypeError at start-up.
    """
    from r2d2_sim.ros.tf_outputs import link_transforms, static_transforms
    config = parse_config({**ROBOTS['robot without wheels'], 'publish_link_tf': True})
    simulation = Simulation(config)
    try:
        links = link_transforms(config, simulation.robot)
        with_links = static_transforms(config, simulation.robot, links)
        without = static_transforms(config, simulation.robot, None)
    finally:
        simulation.close()
    assert links.root_link is None
    assert with_links == without


def test_scan_and_imu_outputs_publish_exactly_the_readings_given():
    """Put scan ranges (float32) and IMU fields where the typed messages have them."""
    import numpy
    from r2d2_sim.ros.outputs import ImuOutput, ScanOutput
    from r2d2_sim.model.sensors import ImuModel, ImuReading, ScanGeometry
    rng = random.Random(5)
    config = parse_config({'scan_rate': 20.0, 'frame_prefix': 'p/'})
    geometry = ScanGeometry(-2.0, 2.0, 181, 0.1, 9.0)
    scans = [numpy.array([rng.choice([rng.uniform(0.1, 9.0), math.inf, -math.inf])
                          for _ in range(181)], dtype=numpy.float32) for _ in range(20)]
    readings = [ImuReading(tuple(rng.uniform(-1, 1) for _ in range(4)),
                           tuple(rng.uniform(-5, 5) for _ in range(3)),
                           tuple(rng.uniform(-20, 20) for _ in range(3))) for _ in range(20)]
    sensor = SimpleNamespace(model=ImuModel(linear_acceleration_std_m_s2=0.1,
                                            rng=numpy.random.default_rng(0)))
    node = RecordingNode()
    scan_output, imu_output = ScanOutput(node, config, geometry), ImuOutput(node, config, sensor)
    times = [rng.randrange(10**15) for _ in range(20)]
    for time_ns, scan, reading in zip(times, scans, readings):
        scan_output.publish(time_ns, scan)
        imu_output.publish(time_ns, reading)
    for time_ns, scan, msg in zip(times, scans, published(node.publishers['scan'])):
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == divmod(time_ns, 10**9)
        assert msg.header.frame_id == 'p/base_scan'
        assert numpy.array_equal(numpy.array(msg.ranges, dtype=numpy.float32), scan)
        assert (msg.angle_min, msg.angle_increment) == pytest.approx((-2.0, 4.0 / 180))
        assert (msg.range_min, msg.range_max, msg.time_increment) == pytest.approx((0.1, 9.0, 0))
    for time_ns, reading, msg in zip(times, readings, published(node.publishers['imu'])):
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == divmod(time_ns, 10**9)
        assert msg.header.frame_id == 'p/imu_link'
        q, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
        assert (q.x, q.y, q.z, q.w) == reading.orientation_xyzw
        assert (w.x, w.y, w.z) == reading.angular_velocity_rad_s
        assert (a.x, a.y, a.z) == reading.linear_acceleration_m_s2
        assert msg.linear_acceleration_covariance[0] == pytest.approx(0.01)
        assert msg.linear_acceleration_covariance[4] == pytest.approx(0.01)
    assert len(node.publishers['scan'].published) == len(node.publishers['imu'].published) == 20
