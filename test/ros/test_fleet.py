"""
Several robots in one world, through ROS: each in its namespace, one /clock, both TF layouts.

In-process (the ``r2d2_sim_factory`` fixture); the standard's services across
processes are system/test_fleet_system.py's. Robot a stands at the origin
facing +x, robot b 2 m ahead facing it (``FACING``, in helpers.py); R2D2's
grippers touch when their base links are about 1.03 m apart.
"""

import math

from helpers import FACING, needs_standard, x_of
import pytest
from geometry_msgs.msg import TwistStamped
from rcl_interfaces.srv import GetParameters
from sensor_msgs.msg import LaserScan
from std_srvs.srv import Trigger

from r2d2_sim.testing import RefusedError, StartupError, wait_for

FORWARD_BEAM = 180
ROBOT_TOPICS = ('cmd_vel', 'joint_states', 'odom', 'ground_truth', 'scan', 'imu',
                'robot_description')


def topic_types(harness):
    """Return {topic: [types]} as the harness's node sees the graph."""
    return dict(harness._link.get_topic_names_and_types())


def test_two_robots_see_touch_and_stay_their_own(r2d2_sim_factory):
    """The done-when scene: b's scan sees a come, they touch, nothing of one moves the other."""
    sim = r2d2_sim_factory(robots=FACING, cmd_vel_timeout=0.0)
    a, b = sim.robot('a'), sim.robot('b')
    assert sim.robot_names == ['a', 'b'] and sim.robot() is a
    scans = []
    sim.create_node('listener').create_subscription(LaserScan, '/b/scan', scans.append, 10)
    b_start = b.ground_truth()
    a.send_cmd_vel(linear=0.3)
    sim.advance(seconds=2.0)  # a drives about 0.5 m, still short of touching
    assert x_of(a.ground_truth()) > 0.45 and x_of(a.odom()) > 0.45
    first, last = scans[0], scans[-1]
    assert first.header.frame_id == 'b/base_scan'
    assert first.ranges[FORWARD_BEAM] - last.ranges[FORWARD_BEAM] == pytest.approx(
        x_of(a.ground_truth()) - 0.0, abs=0.05)
    # b stands still: its ground truth and odometry are its own, untouched.
    assert x_of(b.ground_truth()) == pytest.approx(x_of(b_start), abs=1e-3)
    assert x_of(b.odom()) == pytest.approx(2.0, abs=1e-3)
    assert b.odom().child_frame_id == 'b/base_link' and a.odom().child_frame_id == 'a/base_link'
    assert b.commands_received == 0 and a.commands_received == 1
    # On into b: b is shoved back, a stops short of passing through it.
    assert sim.advance_until(lambda: x_of(b.ground_truth()) > 2.02, timeout_s=6.0)
    a.send_cmd_vel(linear=0.0)
    sim.advance(seconds=1.0)
    gap = x_of(b.ground_truth()) - x_of(a.ground_truth())
    assert gap > 0.95
    for robot in (a, b):
        assert robot.ground_truth().pose.pose.position.z == pytest.approx(0.47, abs=0.03)


def test_each_robot_has_every_interface_in_its_namespace_and_the_world_one_clock(
        r2d2_sim_factory):
    """cmd_vel, states, sensors, camera, description, joint info per robot; one /clock."""
    sim = r2d2_sim_factory(robots=FACING, camera_rate=5.0, camera_width=16, camera_height=12)
    sim.advance(seconds=0.25)
    topics = topic_types(sim)
    for robot in ('a', 'b'):
        for topic in ROBOT_TOPICS + ('camera/image_raw', 'camera/camera_info'):
            assert f'/{robot}/{topic}' in topics, (robot, topic)
    assert sim.sim.count_publishers('/clock') == 1
    assert sim.sim.count_publishers('/tf') == 2 and sim.sim.count_publishers('/tf_static') == 2
    assert not [t for t in topics if t in ('/cmd_vel', '/odom', '/scan')]
    info = sim.call_service(Trigger, '/b/r2d2_sim/get_joint_info', Trigger.Request())
    assert info.success and '"joints"' in info.message
    status = sim.reset()
    assert status['robots'] == {
        'a': {'namespace': '/a', 'tf': '/tf', 'commands_received': 0},
        'b': {'namespace': '/b', 'tf': '/tf', 'commands_received': 0}}


def test_each_robot_keeps_its_own_limits_timeout_and_command_type(r2d2_sim_factory):
    """b: slower, braking after 0.5 s, taking TwistStamped; a: the world's settings."""
    sim = r2d2_sim_factory(robots={'a': {}, 'b': {
        'initial_pose': [0.0, 2.0, 0.0], 'max_linear_velocity': 0.1, 'cmd_vel_timeout': 0.5,
        'enable_stamped_cmd_vel': True}}, cmd_vel_timeout=0.0)
    a, b = sim.robot('a'), sim.robot('b')
    assert sim.sim.robot('b').cmd_vel._stamped
    types = topic_types(sim)
    assert types['/b/cmd_vel'] == ['geometry_msgs/msg/TwistStamped']
    assert types['/a/cmd_vel'] == ['geometry_msgs/msg/Twist']
    a.send_cmd_vel(linear=0.3)
    b.send_cmd_vel(twist=TwistStamped())  # stamp 0: now
    b.send_cmd_vel(linear=0.3)
    sim.advance(seconds=0.45)
    assert b.ground_truth().twist.twist.linear.x == pytest.approx(0.1, abs=0.01)
    sim.advance(seconds=1.5)
    assert a.ground_truth().twist.twist.linear.x == pytest.approx(0.3, abs=0.01)
    assert abs(b.ground_truth().twist.twist.linear.x) < 0.01  # braked after its timeout


def test_shared_tf_is_one_tree_under_world_with_each_robot_prefixed(r2d2_sim_factory):
    """REP-105 per robot on /tf: world -> a/odom -> a/base_footprint -> a/base_link -> sensors."""
    sim = r2d2_sim_factory(robots=FACING, publish_ground_truth_tf=True, cmd_vel_timeout=0.0)
    sim.listen_tf()
    sim.robot('a').send_cmd_vel(linear=0.3, angular=0.2)
    sim.advance(seconds=1.0)
    for name in ('a', 'b'):
        truth = sim.robot(name).ground_truth().pose.pose
        chain = [('world', f'{name}/odom'), (f'{name}/odom', f'{name}/base_footprint'),
                 (f'{name}/base_footprint', f'{name}/base_link'),
                 (f'{name}/base_link', f'{name}/base_scan'),
                 (f'{name}/base_link', f'{name}/imu_link')]
        for parent, child in chain:
            sim.lookup_transform(parent, child)
        base = sim.lookup_transform('world', f'{name}/base_link').transform.translation
        assert base[:2] == pytest.approx((truth.position.x, truth.position.y), abs=1e-6)
        assert base[2] == pytest.approx(truth.position.z, abs=0.002)  # TF: its height at rest
        odom = sim.lookup_transform(f'{name}/odom', f'{name}/base_link').transform.translation
        assert odom[2] == pytest.approx(0.47, abs=0.005)  # base_footprint on the ground
    # One tree: the robots' frames reach each other through world.
    between = sim.lookup_transform('a/base_link', 'b/base_link').transform.translation
    assert math.hypot(between[0], between[1]) == pytest.approx(
        2.0 - x_of(sim.robot('a').ground_truth()), abs=0.05)


def test_namespaced_tf_gives_each_robot_its_own_tree_of_plain_frames(r2d2_sim_factory):
    """tf_layout namespaced: /a/tf and /b/tf with odom -> base_footprint -> base_link; no /tf."""
    sim = r2d2_sim_factory(robots=FACING, tf_layout='namespaced', publish_ground_truth_tf=True)
    a, b = sim.robot('a'), sim.robot('b')
    assert (a.tf_topics, b.tf_topics) == (('/a/tf', '/a/tf_static'), ('/b/tf', '/b/tf_static'))
    a.listen_tf()
    b.listen_tf()
    sim.advance(seconds=0.5)
    assert sim.sim.count_publishers('/tf') == 0 and sim.sim.count_publishers('/tf_static') == 0
    for robot, x in ((a, 0.0), (b, 2.0)):
        for parent, child in (('world', 'odom'), ('odom', 'base_footprint'),
                              ('base_footprint', 'base_link'), ('base_link', 'base_scan')):
            robot.lookup_transform(parent, child)
        base = robot.lookup_transform('world', 'base_link').transform.translation
        assert base[0] == pytest.approx(x, abs=0.01)
    assert 'b/odom' not in b.listen_tf().buffer.frames and 'odom' in b.listen_tf().buffer.frames
    assert b.odom().header.frame_id == 'odom'


def test_robot_parameters_are_declared_and_read_back(r2d2_sim_factory):
    """The parameters robots and NAME.parameter are declared and answer with their values."""
    sim = r2d2_sim_factory(robots=FACING)
    request = GetParameters.Request(names=['robots', 'b.initial_pose', 'tf_layout'])
    reply = sim.call_service(GetParameters, '/r2d2_sim/get_parameters', request)
    robots, pose, layout = reply.values
    assert list(robots.string_array_value) == ['a', 'b']
    assert list(pose.double_array_value) == pytest.approx([2.0, 0.0, math.pi])
    assert layout.string_value == 'shared'


@pytest.mark.parametrize('parameters, fragment', [
    ({'robots': {'a': {'namespace': '/x'}, 'b': {'namespace': 'x'}}},
     'robots a and b both have the namespace /x'),
    ({'robots': {'a': {'max_wheel_force': -1.0}}}, 'a.max_wheel_force'),
    ({'robots': {'a': {}, 'b': {}}}, 'robots a and b overlap where they start'),
    ({'robots': {'a': {'frame_prefix': 'x/'},
                 'b': {'initial_pose': [3.0, 0, 0], 'frame_prefix': 'x/'}}},
     "robots a and b both prefix their frames 'x/'"),
    ({'robots': {'a': {'namespace': '/' + 'n' * 151}}}, 'at most 150 characters'),
    # Refused while robot b's interfaces are built: the line says which robot.
    ({'robots': {'a': {}, 'b': {'initial_pose': [3.0, 0, 0], 'base_frame_id': 'head'}}},
     "robot b: the URDF has links named like frames the node publishes itself"),
    # Refused while robot b itself is built (its wheels).
    ({'robots': {'a': {}, 'b': {'initial_pose': [3.0, 0, 0], 'left_wheel_names': ['nope_l'],
                                'right_wheel_names': ['nope_r']}}},
     'robot b: wheel joint(s) nope_l, nope_r not in the URDF'),
])
def test_a_bad_fleet_is_one_line_at_start_up(r2d2_sim_factory, parameters, fragment):
    """Shared namespaces, overlap, shared frame prefixes, bad values: StartupError, one line."""
    with pytest.raises(StartupError) as raised:
        r2d2_sim_factory(**parameters)
    assert fragment in str(raised.value) and '\n' not in str(raised.value)


def test_a_robot_spawned_in_process_gets_its_interfaces_and_loses_them_on_delete(
        r2d2_sim_factory):
    """The harness's spawn with a namespace: a driven robot; delete takes node and topics."""
    sim = r2d2_sim_factory(cmd_vel_timeout=0.0)  # the default robot r2d2, at the root
    name = sim.spawn('package://r2d2_sim/urdf/r2d2.urdf', name='c', namespace='c',
                     position=(0.0, 2.0, 0.48))
    c = sim.robot(name)
    assert c.namespace == '/c' and sim.robot_names == ['r2d2', 'c']
    c.send_cmd_vel(linear=0.3)
    sim.advance(seconds=1.0)
    assert x_of(c.ground_truth()) > 0.2 and abs(x_of(sim.ground_truth())) < 0.01
    assert c.odom().header.frame_id == 'c/odom'
    sim.delete_entity('c')
    sim.advance(seconds=0.1)
    assert sim.robot_names == ['r2d2'] and 'c' not in sim.entities()
    # The graph forgets the publishers asynchronously: wait for it by deadline.
    assert wait_for(lambda: not [t for t in topic_types(sim) if t.startswith('/c/')
                                 and sim._link.count_publishers(t)], 10.0)
    assert wait_for(lambda: sim.sim.count_publishers('/tf') == 1, 10.0)
    with pytest.raises(Exception) as raised:
        sim.robot('c')
    assert 'no robot named' in str(raised.value)


@pytest.mark.parametrize('namespace, fragment', [
    ('/', "the simulator's own namespace"),
    ('/a', 'robot a has the namespace /a already'),
    ('a b', 'must be a ROS namespace'),
    ('/' + 'x' * 300, 'at most 150 characters'),  # rclpy's limits, and its topics' in DDS
])
def test_a_spawn_in_a_bad_namespace_is_namespace_invalid(r2d2_sim_factory, namespace,
                                                         fragment):
    """A taken, the simulator's or a malformed namespace; nothing is left of the attempt."""
    sim = r2d2_sim_factory(robots=FACING)
    with pytest.raises(RefusedError) as raised:
        sim.spawn('package://r2d2_sim/urdf/r2d2.urdf', name='c', namespace=namespace,
                  position=(0.0, 2.0, 0.48))
    assert raised.value.code == 'NAMESPACE_INVALID' and fragment in str(raised.value)
    assert sim.entities() == ['ground_plane', 'a', 'b'] and sim.robot_names == ['a', 'b']


def test_the_recording_holds_every_robot_and_both_static_trees(tmp_path):
    """Recording two robots: /a/* and /b/* in one MCAP, /tf_static once per robot."""
    from mcap.reader import make_reader
    from r2d2_sim.testing import SimHarness
    path = tmp_path / 'run.mcap'
    with SimHarness(robots=FACING, record=str(path)) as sim:
        sim.advance(seconds=0.5)
    counts = {}
    with open(path, 'rb') as stream:
        for _, channel, _ in make_reader(stream).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    for robot in ('a', 'b'):
        for topic in ('odom', 'ground_truth', 'joint_states', 'scan', 'robot_description'):
            assert counts.get(f'/{robot}/{topic}'), (robot, topic)
    assert counts['/tf_static'] == 2 and counts['/clock'] == 121
    assert counts['/tf'] == 2 * 121


def test_a_spawned_robot_may_not_take_another_robots_frames(r2d2_sim_factory):
    """On the shared /tf a robot's frames are its name's: a clash is NAME_NOT_UNIQUE."""
    sim = r2d2_sim_factory(robots={'a': {'frame_prefix': 'c/'}})
    with pytest.raises(RefusedError) as raised:
        sim.spawn('package://r2d2_sim/urdf/r2d2.urdf', name='c', namespace='/c',
                  position=(0.0, 2.0, 0.48))
    assert raised.value.code == 'NAME_NOT_UNIQUE' and "prefix 'c/'" in str(raised.value)
    assert sim.entities() == ['ground_plane', 'a'] and sim.robot_names == ['a']


def test_a_reset_right_after_a_spawn_resets(r2d2_sim_factory):
    """The new robot has published nothing yet; reset_world still resets everything."""
    sim = r2d2_sim_factory(robots=FACING)
    sim.advance(seconds=0.1)
    sim.spawn('package://r2d2_sim/urdf/r2d2.urdf', name='c', namespace='/c',
              position=(0.0, 2.0, 0.48))
    sim.reset_world()
    assert sim.robot_names == ['a', 'b'] and sim.entities() == ['ground_plane', 'a', 'b']
    assert sim.sim.step_count == 1  # time went back to 0; then one control period
    assert x_of(sim.robot('b').ground_truth()) == pytest.approx(2.0, abs=1e-3)
    sim.spawn('package://r2d2_sim/urdf/r2d2.urdf', name='c', namespace='/c',
              position=(0.0, 2.0, 0.48))  # its namespace is free again
    sim.advance()
    assert sim.robot('c').ground_truth().pose.pose.position.y == pytest.approx(2.0, abs=1e-3)


def test_the_live_view_forgets_a_deleted_robot(r2d2_sim_factory):
    """Spawn and delete c three times: no /c/ channel, /tf_static's two robots alone latched."""
    sim = r2d2_sim_factory(robots=FACING, foxglove_port=_free_port())
    sink = sim.sim.sink
    for _ in range(3):
        sim.spawn('package://r2d2_sim/urdf/r2d2.urdf', name='c', namespace='/c',
                  position=(0.0, 2.0, 0.48))
        assert '/c/robot_description' in sink.topics
        sim.advance()
        sim.delete_entity('c')
    assert not [t for t in sink.topics if t.startswith('/c/')]
    assert len(sink._handles['/tf_static']) == 2 and len(sink._handles['/tf']) == 2


def test_a_robot_spawned_without_wheels_says_so_by_name(r2d2_sim_factory, capfd):
    """A cube in a namespace: every interface but odom, and one warning naming the robot."""
    sim = r2d2_sim_factory()
    sim.spawn('cube.urdf', name='box', namespace='/box', position=(2.0, 0.0, 0.5))
    box = sim.robot('box')
    sim.advance()
    assert not box.has_wheels and box.ground_truth().pose.pose.position.x == pytest.approx(2.0)
    warnings = [line for line in capfd.readouterr().err.splitlines() if 'wheel joints' in line]
    assert len(warnings) == 1 and 'robot box:' in warnings[0]


def test_each_robots_blow_up_is_reported(r2d2_sim_factory, capfd):
    """Two robots blowing up within the throttle period: one error line each."""
    sim = r2d2_sim_factory(robots=FACING)
    for robot in sim.sim.simulation.robots:
        robot.body.set_base_state(linear_velocity=(1e5, 0.0, 0.0))
    sim.advance()
    errors = [line for line in capfd.readouterr().err.splitlines() if 'blew up' in line]
    assert len(errors) == 2
    assert 'robot a ' in errors[0] and 'robot b ' in errors[1]


def _free_port():
    import socket
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def test_a_name_ros_refuses_is_one_line_and_leaves_no_node(r2d2_sim_factory):
    """The fleet turns rclpy's refusal of a robot's namespace into ConfigError."""
    import copy
    from r2d2_sim.sim.settings.table import ConfigError
    sim = r2d2_sim_factory(robots=FACING)
    nodes_before = len(sim._link.get_node_names())
    robots = sim.sim.simulation.robots
    refused = copy.copy(robots[1])  # b again, where ROS allows no namespace
    refused.namespace = '/9starts_with_a_digit'
    with pytest.raises(ConfigError) as raised:
        sim.sim.fleet.follow(robots + [refused])
    assert 'robot b cannot have its interfaces in /9starts_with_a_digit' in str(raised.value)
    assert '\n' not in str(raised.value) and len(sim.sim.robots) == 2
    assert wait_for(lambda: len(sim._link.get_node_names()) == nodes_before, 5.0)


@needs_standard
def test_an_unforeseen_error_in_a_service_is_answered_not_fatal(r2d2_sim_factory, monkeypatch):
    """A defect behind get_entities: OPERATION_FAILED in the reply, one error line, no crash."""
    from simulation_interfaces.srv import GetEntities

    def broken():
        raise RuntimeError('a defect')
    sim = r2d2_sim_factory()
    monkeypatch.setattr(sim.sim.simulation.entities, 'names', broken)
    reply = sim.call_service(GetEntities, '/get_entities', GetEntities.Request())
    assert reply.result.result == reply.result.RESULT_OPERATION_FAILED
    assert 'RuntimeError: a defect' in reply.result.error_message
    monkeypatch.undo()
    reply = sim.call_service(GetEntities, '/get_entities', GetEntities.Request())
    assert reply.result.result == reply.result.RESULT_OK and 'r2d2' in reply.entities
