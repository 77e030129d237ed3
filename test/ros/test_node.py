"""
The node in-process: a probe node in the same context drives it and listens.

The simulator is advanced explicitly with ``SimNode.advance`` (the in-process
API), so every test controls simulated time exactly and runs faster than real
time; an executor thread delivers messages between the two nodes.
"""

import json
import math

from helpers import latest_truth, make_sim, Probe, RATE_HZ, wait_for
from geometry_msgs.msg import Twist
import pytest
from std_srvs.srv import Trigger

from r2d2_sim.model.kinematics import quaternion_to_yaw, twist_to_wheel_velocities
from r2d2_sim.ros.node import SimNode, StartupError

WHEELS = ['left_front_wheel_joint', 'left_back_wheel_joint',
          'right_front_wheel_joint', 'right_back_wheel_joint']


def truth_pose(msg):
    """Return (x, y, yaw) of an Odometry message."""
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    return p.x, p.y, quaternion_to_yaw(q.x, q.y, q.z, q.w)


def stamp_s(msg):
    """Return a header stamp in seconds."""
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def test_joint_states_lists_every_movable_joint(sim, probe):
    """joint_states names the 8 non-fixed joints with finite values."""
    sim.advance(10)
    probe.wait_count('joint_states', 5)
    msg = probe.messages['joint_states'][-1]
    assert sorted(msg.name) == sorted(WHEELS + [
        'gripper_extension', 'left_gripper_joint', 'right_gripper_joint', 'head_swivel'])
    assert len(msg.position) == len(msg.velocity) == len(msg.effort) == len(msg.name)
    assert all(math.isfinite(v) for v in list(msg.position) + list(msg.velocity))


def test_clock_and_stamps_are_simulation_time(sim, probe):
    """/clock advances exactly 1/240 s per step and every stamp uses it."""
    probe.advance_and_collect(RATE_HZ)
    clocks = [m.clock.sec + m.clock.nanosec * 1e-9 for m in probe.messages['clock']]
    assert clocks[-1] == 1.0  # 240 steps of 1/240 s, exactly: integer nanoseconds
    assert len(clocks) == RATE_HZ
    assert clocks[0] == pytest.approx(1 / RATE_HZ, abs=1e-9)
    assert all(b - a == pytest.approx(1 / RATE_HZ, abs=1e-9) for a, b in zip(clocks, clocks[1:]))
    for topic in ('joint_states', 'odom', 'ground_truth'):
        assert stamp_s(probe.messages[topic][-1]) == 1.0, topic
    odom, truth = probe.messages['odom'][-1], probe.messages['ground_truth'][-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ('odom', 'base_link')
    assert (truth.header.frame_id, truth.child_frame_id) == ('world', 'base_link')
    assert odom.pose.covariance[0] > 0.0 and odom.twist.covariance[35] > 0.0


def test_clock_comes_at_every_stamp_when_a_sensor_outpaces_the_state(ros):
    """
    publish_rate 50 Hz, the IMU at 100 Hz: /clock at each step that publishes anything.

    A node on simulated time then never receives a message stamped later than its
    clock (before, half the IMU messages were up to 12.5 ms ahead of it).
    """
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import Imu
    sim = make_sim(ros, publish_rate=50.0, imu_rate=100.0)
    probe = Probe(ros, sim)
    imu = []
    probe.node.create_subscription(Imu, 'imu', imu.append, QoSProfile(
        depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT))
    for _ in range(24):  # chunks the probe's depth-100 queues keep whole
        before = len(probe.messages['clock'])
        sim.advance(10)
        assert wait_for(lambda: len(probe.messages['clock']) > before)
    probe.wait_count('joint_states', 50)
    assert wait_for(lambda: len(imu) >= 100), len(imu)

    def stamps(messages):
        return {(m.header.stamp.sec, m.header.stamp.nanosec) for m in messages}
    published = stamps(imu) | stamps(probe.messages['joint_states'])
    probe.wait_count('clock', len(published))
    clocks = {(m.clock.sec, m.clock.nanosec) for m in probe.messages['clock']}
    assert clocks == published and len(probe.messages['clock']) == len(published)


def test_a_robot_spawned_between_publications_is_not_stamped_ahead_of_the_clock(ros):
    """
    publish_rate 50 Hz, a spawn at step 7 (the last publication at step 5): its /tf_static.

    The clock moves on only at steps that publish, so the new robot's static
    transforms carry the last publication's time, not the step it came at.
    """
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from rosgraph_msgs.msg import Clock
    from tf2_msgs.msg import TFMessage
    from r2d2_sim.sim.entities import SpawnRequest
    sim = make_sim(ros, publish_rate=50.0, scan_rate=0.0, imu_rate=0.0)
    node = ros.create_node('listener', use_sim_time=False)
    clocks, statics = [], []
    node.create_subscription(Clock, '/clock', clocks.append, 100)
    node.create_subscription(TFMessage, '/tf_static', statics.append, QoSProfile(
        depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    assert wait_for(lambda: sim._clock_output._publisher.get_subscription_count())
    sim.advance(7)  # 50 Hz at 240 Hz: a publication every 4.8 steps, the last at step 5
    assert sim.simulation.last_frame_step == 5 and sim.step_count == 7
    with sim.lock:
        sim.simulation.spawn(SpawnRequest(name='b', uri=sim.simulation.robot.source,
                                          namespace='/b', position=(2.0, 0.0, 0.5)))

    def spawned():
        return [t.header.stamp for m in statics for t in m.transforms
                if t.header.frame_id.startswith('b/')]
    published = sim.last_publication_ns  # step 5's time, below the time now (step 7's)
    assert published < sim.sim_time_ns
    assert wait_for(lambda: spawned() and clocks and clocks[-1].clock.nanosec == published)
    assert {s.sec * 10**9 + s.nanosec for s in spawned()} == {published}


def test_robot_description_is_latched(sim, probe):
    """A late subscriber still receives the URDF text."""
    probe.wait_count('robot_description', 1)
    assert '<robot' in probe.messages['robot_description'][0].data


def test_forward_speed_tracks_command(sim, probe):
    """0.3 m/s commanded: ground truth speed within 5 % after the first 0.5 s."""
    probe.drive(0.3, 0.0, 0.5)
    x0, y0, _ = latest_truth(sim)
    probe.drive(0.3, 0.0, 2.0)
    x1, y1, yaw1 = latest_truth(sim)
    speed = math.hypot(x1 - x0, y1 - y0) / 2.0
    assert speed == pytest.approx(0.3, rel=0.05)
    assert x1 - x0 > 0.5  # forward is +x (REP-103)
    probe.wait_count('ground_truth', 10)
    twist = probe.messages['ground_truth'][-1].twist.twist
    assert twist.linear.x == pytest.approx(0.3, rel=0.05)  # twist in base_link


def test_yaw_rate_tracks_command(sim, probe):
    """0.5 rad/s commanded: ground truth yaw rate within 10 % after the first 0.5 s."""
    probe.drive(0.0, 0.5, 0.5)
    _, _, yaw0 = latest_truth(sim)
    probe.drive(0.0, 0.5, 2.0)
    _, _, yaw1 = latest_truth(sim)
    rate = math.remainder(yaw1 - yaw0, 2 * math.pi) / 2.0
    assert rate == pytest.approx(0.5, rel=0.10)


def _odom_error(sim):
    o = sim.simulation.robot.controller.odometry
    x, y, yaw = latest_truth(sim)
    return math.hypot(o.x_m - x, o.y_m - y), abs(math.remainder(o.yaw_rad - yaw, 2 * math.pi))


def test_odometry_matches_truth_straight(sim, probe):
    """After 2 s straight the odometry is within 5 % of distance and 5 degrees."""
    probe.drive(0.3, 0.0, 2.0)
    distance = sim.simulation.robot.controller.odometry.distance_m
    position_error, heading_error = _odom_error(sim)
    assert distance > 0.5
    assert position_error < 0.05 * distance
    assert heading_error < math.radians(5)


def test_odometry_matches_truth_after_quarter_turn(sim, probe):
    """
    After a 90 degree arc (0.3 m/s, 0.5 rad/s for pi s) odometry agrees with truth.

    The skid-steered body slides outwards in arcs, which wheel odometry cannot
    see: measured 8.9 % of the distance with the default acceleration limits.
    """
    probe.drive(0.3, 0.5, math.pi)
    _, _, yaw = latest_truth(sim)
    assert math.degrees(yaw) == pytest.approx(90, abs=9)
    position_error, heading_error = _odom_error(sim)
    assert position_error < 0.10 * sim.simulation.robot.controller.odometry.distance_m
    assert heading_error < math.radians(5)


def test_timeout_brakes_the_wheels(sim, probe):
    """No cmd_vel for 0.5 s of simulated time: wheel targets go to zero, robot stops."""
    probe.drive(0.3, 0.0, 0.5)
    sim.advance(RATE_HZ // 2 - 12)  # just under the timeout since the last command
    assert sim.simulation.robot.controller.wheel_targets != (0.0, 0.0)
    sim.advance(RATE_HZ)
    assert sim.simulation.robot.controller.wheel_targets == (0.0, 0.0)
    x0 = latest_truth(sim)[0]
    sim.advance(RATE_HZ)
    assert abs(latest_truth(sim)[0] - x0) < 0.01
    body = sim.simulation.robot.body
    states = body.joint_states([body.joint(n).index for n in WHEELS])
    assert max(abs(v) for v in states.velocities) < 0.5


def test_timeout_zero_disables_braking(ros):
    """cmd_vel_timeout 0 keeps the last command forever."""
    sim = make_sim(ros, cmd_vel_timeout=0.0)
    probe = Probe(ros, sim)
    probe.send(0.3)
    sim.advance(3 * RATE_HZ)
    velocity = sim.simulation.robot.body.base_state().linear_velocity
    assert velocity[0] == pytest.approx(0.3, rel=0.05)


def test_the_node_casts_its_scans_on_two_threads_when_it_may_use_two_cores(ros, monkeypatch):
    """ray_threads auto (0) is 2 in the node on two cores or more, 1 on one; a value stays."""
    import os
    for cores, expected in ((1, 1), (2, 2), (8, 2)):
        monkeypatch.setattr(os, 'sched_getaffinity', lambda pid, n=cores: set(range(n)))
        sim = make_sim(ros)
        assert (sim.config.ray_threads, sim.simulation.world.ray_threads) == (expected, expected)
    assert make_sim(ros, ray_threads=3).simulation.world.ray_threads == 3


def test_huge_command_is_clamped_preserving_curvature(sim, probe):
    """1e308 on both axes gives wheels at the limit, turning, all finite."""
    probe.send(1e308, 1e308)
    sim.advance(1)
    controller = sim.simulation.robot.controller
    left, right = twist_to_wheel_velocities(controller.geometry, *controller.target)
    limit = controller.geometry.max_wheel_velocity_rad_s
    assert max(abs(left), abs(right)) == pytest.approx(limit)
    assert right > left  # positive yaw: the right wheel runs faster


def test_get_joint_info_service(sim, probe):
    """~/get_joint_info returns the 17 attributes of every joint and its link as JSON."""
    response = probe.call(Trigger, '/r2d2_sim/get_joint_info', Trigger.Request())
    assert response.success
    info = json.loads(response.message)
    joints = info['joints']
    assert len(joints) == 15
    keys = {'index', 'name', 'type', 'type_code', 'q_index', 'u_index', 'flags', 'damping',
            'friction', 'lower_limit', 'upper_limit', 'max_force', 'max_velocity',
            'link_name', 'axis', 'parent_frame_position', 'parent_frame_orientation',
            'parent_index'}
    for joint in joints:
        assert keys <= set(joint)
        assert set(joint['link']) == {'name', 'mass', 'lateral_friction', 'world_position',
                                      'world_orientation'}
    by_name = {j['name']: j for j in joints}
    wheel = by_name['left_front_wheel_joint']
    assert wheel['type'] == 'revolute' and math.hypot(*wheel['axis']) == pytest.approx(1.0)
    assert wheel['link']['world_position'][1] > 0.1  # left is +y
    assert by_name['gripper_extension']['type'] == 'prismatic'
    assert by_name['base_to_right_leg']['type'] == 'fixed'
    assert [j['index'] for j in joints] == list(range(15))
    assert sum(j['link']['mass'] for j in joints) > 5.0


@pytest.mark.parametrize('params, fragment', [
    ({'physics_rate': -1.0}, 'physics_rate'),
    ({'publish_rate': 1000.0}, 'publish_rate'),
    ({'left_wheel_names': ['nope_joint']}, 'nope_joint'),
    ({'right_wheel_names': ['head_swivel_missing']}, 'not in the URDF'),
    ({'left_wheel_names': ['gripper_extension']}, 'prismatic'),
    ({'urdf': '/no/such/file.urdf'}, 'not found'),
    ({'initial_pose': [0.0, 0.0]}, 'initial_pose'),
])
def test_bad_parameters_refuse_to_start(ros, params, fragment):
    """Invalid parameters raise StartupError naming the problem."""
    with pytest.raises(StartupError, match=fragment):
        make_sim(ros, **params)


def test_integer_values_are_accepted_for_real_parameters(ros):
    """physics_rate:=240 (an integer on the command line) is as good as 240.0."""
    sim = make_sim(ros, physics_rate=120, publish_rate=60)
    assert sim.config.physics_rate_hz == 120.0
    assert sim.steps_to_next_publish() == 2


def test_publish_rate_divides_physics(ros):
    """publish_rate 50 at 240 Hz publishes 50 times per simulated second."""
    sim = make_sim(ros, publish_rate=50.0)
    probe = Probe(ros, sim)
    for _ in range(RATE_HZ // 8):
        sim.advance(8)
        probe.wait_count('joint_states', sum(1 for m in probe.messages['joint_states']))
    probe.wait_count('joint_states', 50)
    stamps = [stamp_s(m) for m in probe.messages['joint_states'] if stamp_s(m) > 0.0]
    assert len(stamps) == 50 and stamps[-1] == 1.0


def test_two_named_simulators_share_one_process(ros):
    """
    Name two SimNodes and give them namespaces: each robot obeys only its own cmd_vel.

    Their relative topics are apart; /clock is absolute and /tf shared, which
    is what a remap of /clock and frame_prefix are for (README, Robustness).
    """
    sims = {ns: ros.add_node(SimNode(f'sim_{ns}', namespace=f'/{ns}', context=ros.context),
                             use_sim_time=False)
            for ns in ('a', 'b')}
    assert sims['a'].get_fully_qualified_name() == '/a/sim_a'
    assert sims['b'].get_fully_qualified_name() == '/b/sim_b'
    node = ros.create_node('two_sims_probe', use_sim_time=False)
    pub = node.create_publisher(Twist, '/a/cmd_vel', 10)
    received = sims['a'].commands_received
    command = Twist()
    command.linear.x = 0.3
    pub.publish(command)
    assert wait_for(lambda: sims['a'].commands_received > received), 'a got no cmd_vel'
    for sim in sims.values():
        sim.advance(240)
    assert latest_truth(sims['a'])[0] > 0.1
    assert abs(latest_truth(sims['b'])[0]) < 1e-3 and sims['b'].commands_received == 0
