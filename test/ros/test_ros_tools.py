"""
What ROS tools need from the node: TF, LaserScan, Imu, depth and TwistStamped, by their REPs.

In-process: the simulator and a probe node share a context; the world is
urdf/room.urdf, whose geometry is known (inner wall faces at x = +2, -3 and
y = +-2.5 m; 0.4 m boxes centred at (1, 1.2), (-1.5, -1) and (0, -1.5)).
"""

import math
import sys

from helpers import make_sim, wait_for
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
import numpy
import pytest
import rclpy
from rclpy.context import Context
from rclpy.qos import qos_profile_sensor_data, QoSProfile, DurabilityPolicy
from sensor_msgs.msg import CameraInfo, Image, Imu, LaserScan
from tf2_msgs.msg import TFMessage

from r2d2_sim.model.kinematics import quaternion_to_yaw
from r2d2_sim.sim.robots.sensors import LASER_HEIGHT_M
from r2d2_sim.testing import box_urdf, stamp_ns
from r2d2_sim.model.transforms import apply, normalised, quaternion_from_rpy, Transform

ROOM = 'package://r2d2_sim/urdf/room.urdf'
STATIC_QOS = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class Listener:
    """A probe node recording topics by name."""

    def __init__(self, ros, topics):
        self.node = ros.create_node('listener', use_sim_time=False)
        self.messages = {}
        for topic, (msg_type, qos) in topics.items():
            self.messages[topic] = []
            self.node.create_subscription(msg_type, topic, self.messages[topic].append, qos)

    def wait(self, topic, count=1):
        """Wait until ``count`` messages of ``topic`` arrived; return the last one."""
        assert wait_for(lambda: len(self.messages[topic]) >= count), f'no {topic}'
        return self.messages[topic][-1]


def transforms(messages):
    """Return {(parent, child): [TransformStamped, ...]} from TFMessages."""
    result = {}
    for msg in messages:
        for t in msg.transforms:
            result.setdefault((t.header.frame_id, t.child_frame_id), []).append(t)
    return result


# -- TF ------------------------------------------------------------------------------

def test_tf_chains_odom_footprint_base_with_the_odom_stamp(ros):
    """Publish odom -> base_footprint on /tf with odom's pose and stamp; the rest is static."""
    sim = make_sim(ros)
    listener = Listener(ros, {'/tf': (TFMessage, 100), 'odom': (Odometry, 100),
                              '/tf_static': (TFMessage, STATIC_QOS)})
    assert wait_for(lambda: listener.node.count_publishers('/tf') > 0)
    # Publishing every step: take each advance's 40 before the next, or a listener
    # starved on a busy machine falls more than its depth (100) behind and drops some.
    for advance in range(1, 7):
        sim.advance(40)
        listener.wait('odom', 40 * advance)
        listener.wait('/tf', 40 * advance)
    assert len(listener.messages['/tf']) == len(listener.messages['odom'])
    odom_by_stamp = {stamp_ns(m.header.stamp): m for m in listener.messages['odom']}
    chain = transforms(listener.messages['/tf'])[('odom', 'base_footprint')]
    assert chain and all(stamp_ns(t.header.stamp) in odom_by_stamp for t in chain)
    for t in chain:
        pose = odom_by_stamp[stamp_ns(t.header.stamp)].pose.pose
        assert (t.transform.translation.x, t.transform.translation.y) == (
            pose.position.x, pose.position.y)
        assert t.transform.translation.z == 0.0  # the footprint is on the ground
        assert t.transform.rotation == pose.orientation
    static = transforms([listener.wait('/tf_static')])
    footprint = static[('base_footprint', 'base_link')][0].transform
    assert footprint.translation.z == pytest.approx(0.47, abs=0.01)  # body frame height
    # The odom message places base_link where the tree does: on the footprint, that high.
    assert all(m.pose.pose.position.z == footprint.translation.z
               for m in listener.messages['odom'])
    scan = static[('base_link', 'base_scan')][0].transform.translation
    assert footprint.translation.z + scan.z == pytest.approx(LASER_HEIGHT_M)
    assert ('base_link', 'imu_link') in static


def test_late_subscribers_get_the_static_transforms(ros):
    """/tf_static is transient local: a subscriber that comes later still gets it."""
    sim = make_sim(ros, camera_rate=5.0)
    sim.advance(10)
    listener = Listener(ros, {'/tf_static': (TFMessage, STATIC_QOS)})
    static = transforms([listener.wait('/tf_static')])
    assert ('base_footprint', 'base_link') in static
    # With robot_state_publisher doing the links, the camera's frame still hangs on head.
    optical = static[('head', 'head_camera_optical')][0].transform.rotation
    # The optical z axis (forward) is the head's x: rotate (0, 0, 1) by the quaternion.
    x, y, z, w = optical.x, optical.y, optical.z, optical.w
    forward = (2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y))
    assert forward == pytest.approx((1.0, 0.0, 0.0), abs=1e-9)


def test_frame_prefix_and_link_transforms(ros):
    """With a prefix every robot frame is prefixed; link TF covers moving and fixed joints."""
    sim = make_sim(ros, frame_prefix='r2/', publish_link_tf=True, camera_rate=5.0)
    listener = Listener(ros, {'/tf': (TFMessage, 100), '/tf_static': (TFMessage, STATIC_QOS),
                              'odom': (Odometry, 10), 'ground_truth': (Odometry, 10),
                              'scan': (LaserScan, 10), 'imu': (Imu, 10)})
    robot = sim.simulation.robot.body
    sim.world.client.resetJointState(robot.id, robot.joint('head_swivel').index,
                                     0.5)
    sim.advance(1)
    listener.wait('/tf')
    dynamic = transforms(listener.messages['/tf'])
    static = transforms([listener.wait('/tf_static')])
    assert ('r2/odom', 'r2/base_footprint') in dynamic
    assert ('r2/base_link', 'r2/head') in dynamic  # head_swivel moves
    head = dynamic[('r2/base_link', 'r2/head')][-1].transform.rotation
    assert 2 * math.atan2(head.z, head.w) == pytest.approx(0.5, abs=0.05)
    assert ('r2/base_link', 'r2/right_leg') in static  # fixed joint, once
    assert ('r2/head', 'r2/head_camera_optical') in static
    for parent, child in list(dynamic) + list(static):
        assert parent.startswith('r2/') and child.startswith('r2/')
    sim.advance(24)
    odom, truth = listener.wait('odom'), listener.wait('ground_truth')
    assert (odom.header.frame_id, odom.child_frame_id) == ('r2/odom', 'r2/base_link')
    assert (truth.header.frame_id, truth.child_frame_id) == ('world', 'r2/base_link')
    assert listener.wait('scan').header.frame_id == 'r2/base_scan'
    assert listener.wait('imu').header.frame_id == 'r2/imu_link'
    # Every one of the 15 URDF joints appears exactly once.
    joints = [pair for pair in list(dynamic) + list(static)
              if pair[0] not in ('r2/odom', 'r2/base_footprint') and 'optical' not in pair[1]
              and pair[1] not in ('r2/base_scan', 'r2/imu_link')]
    assert len(joints) == len(set(joints)) == 15


def test_ground_truth_tf_places_odom_so_that_the_chain_is_the_true_pose(r2d2_sim_factory):
    """The chain world -> odom -> base_footprint -> base_link, looked up, is the true pose."""
    harness = r2d2_sim_factory(publish_ground_truth_tf=True, cmd_vel_timeout=0.0)
    harness.listen_tf()
    harness.send_cmd_vel(linear=0.3, angular=0.5)
    harness.advance(480)
    truth = harness.ground_truth()
    chain = harness.lookup_transform('world', 'base_link')
    assert chain.stamp_ns == stamp_ns(truth.header.stamp)  # the latest, of that very step
    assert_pose_is_truth(chain, truth)
    world_odom = harness.lookup_transform('world', 'odom')
    assert math.hypot(*world_odom.translation[:2]) > 0.001  # skid steering slips


def test_ground_truth_tf_holds_the_true_height_and_tilt(r2d2_sim_factory):
    """
    On a tilted platform 0.3 m up, world -> base_link is ground_truth's pose, z and tilt too.

    world -> odom once took the true x, y and yaw only: the chain put the body
    at its height at rest (0.47 m), upright, whatever the robot stood on.
    """
    harness = r2d2_sim_factory(publish_ground_truth_tf=True, cmd_vel_timeout=0.0)
    harness.listen_tf()
    tilt = quaternion_from_rpy(0.0, 0.15, 0.0)
    harness.spawn(box_urdf((2.0, 2.0, 0.3)), name='platform', position=(3.0, 0.0, 0.15),
                  orientation=tilt)
    harness.set_entity_state('r2d2', (3.0, 0.0, 0.3 + 0.5), orientation=tilt)
    harness.advance(seconds=1.0)
    truth = harness.ground_truth()
    p, q = truth.pose.pose.position, truth.pose.pose.orientation
    assert p.z > 0.7 and abs(2.0 * math.asin(q.y)) > 0.1  # up on the platform, pitched
    chain = harness.lookup_transform('world', 'base_link', stamp_ns(truth.header.stamp))
    assert_pose_is_truth(chain, truth)


def test_ground_truth_tf_places_a_robot_without_wheels(r2d2_sim_factory):
    """
    A robot without wheels has no odom: world -> base_footprint is its truth.

    It published no world frame at all, and said nothing: its scan could not
    be placed in the world.
    """
    harness = r2d2_sim_factory(urdf='cube.urdf', left_wheel_names=[], right_wheel_names=[],
                               publish_ground_truth_tf=True)
    harness.listen_tf()
    harness.set_entity_state('cube', (1.0, -2.0, 1.5), orientation=quaternion_from_rpy(
        0.2, -0.1, 0.7))
    harness.advance(3)  # falling, turned
    truth = harness.ground_truth()
    chain = harness.lookup_transform('world', 'base_link', stamp_ns(truth.header.stamp))
    assert_pose_is_truth(chain, truth)
    with pytest.raises(Exception, match='odom'):
        harness.lookup_transform('world', 'odom')
    harness.lookup_transform('world', 'base_scan')  # the scan has a place in the world


def assert_pose_is_truth(chain, truth):
    """Assert a looked-up world -> base_link is ground_truth's pose (a rotation's sign aside)."""
    p, q = truth.pose.pose.position, truth.pose.pose.orientation
    assert chain.stamp_ns == stamp_ns(truth.header.stamp)
    assert chain.translation == pytest.approx((p.x, p.y, p.z), abs=1e-9)
    rotation = normalised((q.x, q.y, q.z, q.w))  # as tf2 takes it
    sign = math.copysign(1.0, sum(a * b for a, b in zip(chain.rotation, rotation)))
    assert tuple(sign * c for c in chain.rotation) == pytest.approx(rotation, abs=1e-9)


def test_a_laser_point_lands_on_the_wall_in_odom(r2d2_sim_factory):
    """REP-105 chain odom -> base_scan: a beam's return, moved into odom, is on the wall."""
    from sensor_msgs.msg import LaserScan
    harness = r2d2_sim_factory(world=ROOM, cmd_vel_timeout=0.0)
    scans = []
    harness.create_node('scan_listener').create_subscription(LaserScan, 'scan', scans.append, 10)
    harness.listen_tf()
    harness.advance(seconds=0.5)
    scan = scans[-1]
    ahead = scan.ranges[round((0.0 - scan.angle_min) / scan.angle_increment)]
    point = harness.lookup_transform('odom', 'base_scan', stamp_ns(scan.header.stamp))
    x, y, _ = apply(Transform(point.translation, point.rotation), (ahead, 0.0, 0.0))
    assert x == pytest.approx(2.0, abs=0.02) and abs(y) < 0.02  # the room's +x wall


def test_without_tf2_msgs_tf_is_off_with_one_warning(ros, monkeypatch, capfd):
    """A machine without tf2_msgs runs everything else and says once why /tf is missing."""
    monkeypatch.setitem(sys.modules, 'tf2_msgs.msg', None)  # import raises ImportError
    sim = make_sim(ros)
    sim.advance(24)
    assert not [o for robot in sim.robots for o in robot.outputs.state
                if type(o).__name__ == 'TfOutput']
    assert sim.count_publishers('/tf') == 0
    warnings = [line for line in capfd.readouterr().err.splitlines() if 'tf2_msgs' in line]
    assert len(warnings) == 1 and 'build_tf2_msgs' in warnings[0]


# -- the laser scanner -----------------------------------------------------------------

def test_scan_follows_rep_117_against_the_room(ros):
    """360 beams over a full circle, +x wall at 2 m, box faces, stamped in sim time."""
    sim = make_sim(ros, world=ROOM)
    listener = Listener(ros, {'scan': (LaserScan, 10)})
    sim.advance(24)  # 10 Hz: the first scan is due at step 24
    scan = listener.wait('scan')
    assert stamp_ns(scan.header.stamp) == 24 * 10**9 // 240 == sim.sim_time_ns
    assert scan.header.frame_id == 'base_scan'
    assert len(scan.ranges) == 360
    assert scan.angle_increment == pytest.approx(2 * math.pi / 360)
    # No duplicate beam: the last is one increment short of a full turn.
    assert scan.angle_max == pytest.approx(scan.angle_min + 359 * scan.angle_increment)
    assert scan.time_increment == 0.0 and scan.scan_time == pytest.approx(0.1)
    assert len(scan.intensities) == 0
    x = sim.simulation.robot.body.base_state().position[0]

    def beam(angle_rad):
        return scan.ranges[round((angle_rad - scan.angle_min) / scan.angle_increment)]
    assert beam(0.0) == pytest.approx(2.0 - x, abs=2e-3)           # wall ahead
    assert beam(math.pi / 2) == pytest.approx(2.5, abs=2e-3)        # wall to the left
    assert beam(-math.pi / 2) == pytest.approx(1.5 - 0.2, abs=2e-3)  # box face at y = -1.3
    assert beam(-math.pi) == pytest.approx(3.0 + x, abs=2e-3)       # wall behind
    assert all(scan.range_min <= r <= scan.range_max for r in scan.ranges)  # closed room


def test_scan_reports_no_return_as_plus_inf_and_too_close_as_minus_inf(ros):
    """REP-117: nothing within range_max is +inf; a hit below range_min is -inf."""
    sim = make_sim(ros, world=ROOM, scan_range_min=2.2, scan_range_max=2.8)
    listener = Listener(ros, {'scan': (LaserScan, 10)})
    sim.advance(24)
    ranges = numpy.array(listener.wait('scan').ranges)
    assert ranges[180] == -math.inf  # the +x wall at 2 m is closer than 2.2 m
    assert ranges[0] == math.inf     # the -x wall at 3 m is beyond 2.8 m
    assert ranges[270] == pytest.approx(2.5, abs=2e-3)


def test_scan_noise_is_seeded_and_zero_means_exact(ros):
    """The same seed gives the same noisy scan; noise 0 gives the geometry."""
    scans = []
    for seed, noise in ((3, 0.01), (3, 0.01), (4, 0.01), (3, 0.0)):
        sim = make_sim(ros, world=ROOM, scan_noise_std=noise, noise_seed=seed)
        scans.append(numpy.array(sim.simulation.robot.laser.scan()))
        sim.destroy_node()
        ros.nodes.remove(sim)
    assert numpy.array_equal(scans[0], scans[1])
    assert not numpy.array_equal(scans[0], scans[2])
    error = scans[0] - scans[3]
    assert 0.005 < numpy.std(error) < 0.015


def drive_watched(ros, steps, linear, angular, **params):
    """Drive a new simulator; return the robot's final base state and what it touched."""
    from r2d2_sim.sim.oracles import RunWatch
    sim = make_sim(ros, cmd_vel_timeout=0.0, **params)
    watch = RunWatch(sim.simulation, clearance=False)
    sim.simulation.robot.command(linear, angular)
    sim.advance(steps)
    watch.close()
    return sim.simulation.robot.body.base_state(), watch.touched()


def test_the_scanner_changes_no_physics_while_the_robot_touches_only_the_ground(ros):
    """
    In the open, a drive with the scanner on and off ends at the same pose, to the bit.

    Only in the open: the scanner takes the links crossing its plane (R2D2's
    body and legs) out of Bullet's broadphase and puts them back in a ray
    group of their own, which reorders the contacts Bullet finds for them.
    While those links touch nothing, that changes nothing (the wheels keep
    their entries); the test checks that the drive touched nothing, or it
    would prove nothing.
    """
    on, touched = drive_watched(ros, 600, 0.3, 0.5, scan_rate=10.0)
    off, _ = drive_watched(ros, 600, 0.3, 0.5, scan_rate=0.0)
    assert touched == []
    assert on == off


def test_with_the_scanner_on_a_drive_into_a_wall_repeats_itself_to_the_bit(ros):
    """
    Once the body touches something, each scanner setting repeats, but on and off part.

    The re-inserted links' contacts come in another order, so Bullet's solver
    sums them in another order: after this drive, 6 s along the room's wall,
    the robot stood at y 1.9127 m with the scanner on and 1.9145 m with it
    off. Runs with the same parameters still repeat bit for bit.
    """
    runs = [drive_watched(ros, 1440, 0.5, 0.3, world=ROOM, scan_rate=10.0) for _ in range(2)]
    assert runs[0][1] == ['room']
    assert runs[0] == runs[1]


def test_sensor_topics_reach_default_and_sensor_data_subscribers(ros):
    """Reliable publishers match both reliable and best-effort (sensor data) subscribers."""
    sim = make_sim(ros)
    listener = Listener(ros, {'scan': (LaserScan, qos_profile_sensor_data),
                              'imu': (Imu, qos_profile_sensor_data),
                              'odom': (Odometry, qos_profile_sensor_data)})
    other = Listener(ros, {'scan': (LaserScan, 10), 'imu': (Imu, 10)})
    sim.advance(48)
    for topic in ('scan', 'imu', 'odom'):
        listener.wait(topic)
    other.wait('scan')
    other.wait('imu')


# -- the IMU ---------------------------------------------------------------------------

def test_imu_at_rest_reads_gravity_up_and_world_orientation(ros):
    """REP-145: +9.8 m/s^2 on z at rest, orientation in the world frame (not the start)."""
    sim = make_sim(ros, initial_pose=[0.0, 0.0, 1.0], imu_rate=100.0)
    listener = Listener(ros, {'imu': (Imu, 100)})
    sim.advance(240)
    imu = listener.wait('imu', 100)
    assert imu.header.frame_id == 'imu_link'
    assert stamp_ns(imu.header.stamp) <= sim.sim_time_ns
    q = imu.orientation
    assert quaternion_to_yaw(q.x, q.y, q.z, q.w) == pytest.approx(1.0, abs=0.01)
    a = imu.linear_acceleration
    assert (a.x, a.y, a.z) == pytest.approx((0.0, 0.0, 9.8), abs=0.05)
    w = imu.angular_velocity
    assert (w.x, w.y, w.z) == pytest.approx((0.0, 0.0, 0.0), abs=0.01)
    assert list(imu.orientation_covariance) == [0.0] * 9  # exact, provided (not -1)


def test_imu_measures_a_turn_in_its_own_frame_with_noise_covariance(ros):
    """Turning at 0.5 rad/s reads +0.5 on the sensor's z; covariances are std^2."""
    sim = make_sim(ros, cmd_vel_timeout=0.0, imu_angular_velocity_noise_std=0.01)
    listener = Listener(ros, {'imu': (Imu, 1000)})
    sim.simulation.robot.command(0.0, 0.5)
    sim.advance(480)
    imu = listener.wait('imu')
    assert imu.angular_velocity.z == pytest.approx(0.5, abs=0.08)
    assert imu.angular_velocity_covariance[0] == pytest.approx(1e-4)
    assert imu.angular_velocity_covariance[8] == pytest.approx(1e-4)


# -- depth -----------------------------------------------------------------------------

def test_depth_of_a_wall_at_a_known_distance(ros):
    """The centre pixel of the head camera facing the +x wall reads its distance (REP-118)."""
    sim = make_sim(ros, world=ROOM, camera_rate=10.0, camera_depth=True, camera_width=64,
                   camera_height=48)
    listener = Listener(ros, {'camera/depth/image_raw': (Image, 10),
                              'camera/depth/camera_info': (CameraInfo, 10),
                              'camera/image_raw': (Image, 10)})
    sim.advance(24)
    depth = listener.wait('camera/depth/image_raw')
    info = listener.wait('camera/depth/camera_info')
    rgb = listener.wait('camera/image_raw')
    assert depth.encoding == '32FC1' and depth.step == 4 * 64
    assert (depth.width, depth.height) == (info.width, info.height) == (64, 48)
    assert (rgb.width, rgb.height) == (64, 48)
    assert depth.header.frame_id == rgb.header.frame_id == info.header.frame_id
    pixels = numpy.frombuffer(bytes(depth.data), dtype='<f4').reshape(48, 64)
    camera = sim.simulation.robot.camera
    robot = sim.simulation.robot.body
    lens_x = robot.link_pose(robot.link_index('head'))[0][0] + camera._lens_offset_m
    assert pixels[24, 32] == pytest.approx(2.0 - lens_x, abs=5e-3)
    # Along the optical axis, not the ray: the whole row across the wall reads the same.
    assert pixels[24, 8] == pytest.approx(pixels[24, 32], abs=5e-3)
    assert info.k[0] == info.k[4] and (info.k[2], info.k[5]) == (32.0, 23.0)


def test_depth_without_anything_in_view_is_plus_inf(ros):
    """Sky (nothing within the far plane) reads +inf, as REP-118 says."""
    sim = make_sim(ros, camera_rate=10.0, camera_depth=True, camera_width=32,
                   camera_height=24, camera_fov=90.0)
    _, depth = sim.simulation.robot.camera.render(depth=True)
    assert depth[0, 16] == math.inf  # the top row looks above the horizon
    assert math.isfinite(depth[23, 16])  # the bottom row sees the ground


# -- TwistStamped ----------------------------------------------------------------------

def _stamped(sim, linear, stamp_ns_):
    msg = TwistStamped()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns_, 10**9)
    msg.twist.linear.x = linear
    return msg


def test_twist_stamped_drives_zero_stamp_is_now_and_stale_is_refused(ros, capfd):
    """enable_stamped_cmd_vel: fresh and zero stamps drive; older than the timeout is refused."""
    sim = make_sim(ros, enable_stamped_cmd_vel=True)
    node = ros.create_node('stamped_sender', use_sim_time=False)
    pub = node.create_publisher(TwistStamped, 'cmd_vel', 10)
    assert wait_for(lambda: pub.get_subscription_count() > 0)
    sim.advance(480)  # t = 2 s
    for stamp, accepted in ((sim.sim_time_ns, True), (0, True),
                            (sim.sim_time_ns - 10**9, False)):
        before, rejected = sim.commands_received, sim.commands_rejected
        pub.publish(_stamped(sim, 0.3, stamp))
        assert wait_for(lambda: sim.commands_received > before)
        assert (sim.commands_rejected == rejected) == accepted
    sim.advance(240)
    assert sim.simulation.robot.body.base_state().position[0] > 0.05
    stale = [line for line in capfd.readouterr().err.splitlines() if 'rejected cmd_vel' in line]
    assert len(stale) == 1 and 'cmd_vel_timeout' in stale[0]


def test_a_timeout_beyond_any_run_never_calls_a_stamped_command_stale(ros):
    """cmd_vel_timeout 1e308 with stamped commands: an old stamp drives, nothing overflows."""
    sim = make_sim(ros, enable_stamped_cmd_vel=True, cmd_vel_timeout=1.0e308)
    node = ros.create_node('stamped_sender', use_sim_time=False)
    pub = node.create_publisher(TwistStamped, 'cmd_vel', 10)
    assert wait_for(lambda: pub.get_subscription_count() > 0)
    sim.advance(480)  # t = 2 s
    before = sim.commands_received
    pub.publish(_stamped(sim, 0.3, sim.sim_time_ns - 10**9))
    assert wait_for(lambda: sim.commands_received > before)
    assert sim.commands_rejected == 0
    sim.advance(240)
    assert sim.simulation.robot.body.base_state().position[0] > 0.05


def test_a_twist_publisher_is_named_when_stamped_commands_are_expected(ros, capfd):
    """The wrong-type warning works the other way round too (a Twist sender, another context)."""
    sim = make_sim(ros, {'graph_check_period_s': 0.05}, enable_stamped_cmd_vel=True)
    context = Context()
    rclpy.init(context=context, domain_id=ros.domain_id)
    other = rclpy.create_node('plain_twist_sender', context=context)
    try:
        other.create_publisher(Twist, 'cmd_vel', 10)
        seen = []

        def warned():
            sim.advance(1)
            seen.extend(line for line in capfd.readouterr().err.splitlines()
                        if 'plain_twist_sender' in line)
            return seen
        assert wait_for(warned, 10.0)
        assert 'this node takes geometry_msgs/msg/TwistStamped' in seen[0]
    finally:
        other.destroy_node()
        rclpy.try_shutdown(context=context)
