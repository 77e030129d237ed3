"""
Resets repeat runs bit for bit, and deleted start-up entities come back: in process, over ROS.

Through the testing API (``reset_world``) and the standard's services
(``reset_simulation``, ``set_simulation_state``, ``delete_entity``), each
robot's ``ground_truth`` is read at every physics step of a 2 s run and
compared with ``==``. Robots a and b meet head on over a small box: with the
bodies put back in place, the runs after a reset parted from the first 3
steps in (Bullet's contacts and pair order outlived the reset).
"""

import json
import math

import pytest
from simulation_interfaces import msg, srv

OK = msg.Result.RESULT_OK
STATE = msg.SimulationState
STEPS = 480  # 2 s at 240 Hz, published every step
TWO_AND_A_BOX = {'robots': ['a', 'b'], 'b.initial_pose': [2.0, 0.0, math.pi],
                 'extra_models': ['cube_small.urdf 1.0 0.05 0.025']}
COMMANDS = {0: (1.0, 0.2), 240: (-0.5, 0.0), 360: (0.3, -1.0)}


def truth(odometry):
    """Return a ground_truth message's pose and twist as plain tuples (no stamp)."""
    pose, twist = odometry.pose.pose, odometry.twist.twist
    return ((pose.position.x, pose.position.y, pose.position.z),
            (pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w),
            (twist.linear.x, twist.linear.y, twist.linear.z),
            (twist.angular.x, twist.angular.y, twist.angular.z))


def drive(harness):
    """Step 2 s one physics step at a time, every robot on COMMANDS; return each step's truths."""
    seen = []
    for step in range(STEPS):
        if step in COMMANDS:
            for name in harness.robot_names:
                harness.robot(name).send_cmd_vel(*COMMANDS[step])
        harness.advance(1)
        seen.append(tuple((name, truth(harness.robot(name).ground_truth()))
                          for name in harness.robot_names))
    return seen


def test_a_full_reset_repeats_the_erring_odometry_of_a_fresh_start(r2d2_sim_factory):
    """Encoders with white noise: after reset_world, 1 s at 0.3 m/s reads as after start-up."""
    harness = r2d2_sim_factory(cmd_vel_timeout=0.0, encoder_noise_std=0.05, noise_seed=11)
    runs = []
    for _ in range(2):
        if not runs:
            harness.advance()  # as reset_world does after a reset: one control period
        harness.robot().send_cmd_vel(0.3, 0.0)
        harness.advance(240)
        runs.append(truth(harness.robot().odom()))
        harness.reset_world()
    assert runs[1] == runs[0]


def call(harness, name, srv_type, request):
    """Call one of the standard's services; return the reply's result code."""
    return harness.call_service(srv_type, '/' + name, request).result.result


def test_a_state_reset_of_the_harness_repeats_ground_truth_bit_for_bit(r2d2_sim_factory):
    """reset_world(time=False, state=True, spawned=False): the same commands, the same truths."""
    harness = r2d2_sim_factory(cmd_vel_timeout=0.0, **TWO_AND_A_BOX)
    harness.advance()  # as reset_world does after a reset: one control period (one step)
    first = drive(harness)
    harness.reset_world(time=False, state=True, spawned=False)
    assert harness.sim.step_count == STEPS + 2  # time went on
    assert drive(harness) == first


@pytest.mark.parametrize('how', ['STOPPED', 'SCOPE_DEFAULT', 'SCOPE_STATE'])
def test_the_standard_resets_repeat_a_run_bit_for_bit(r2d2_sim_factory, how):
    """STOPPED and a full reset give the start-up run again; so does STATE, at a later time."""
    harness = r2d2_sim_factory(cmd_vel_timeout=0.0, **TWO_AND_A_BOX)
    first = drive(harness)
    if how == 'STOPPED':
        request = srv.SetSimulationState.Request()
        request.state.state = STATE.STATE_STOPPED
        assert call(harness, 'set_simulation_state', srv.SetSimulationState, request) == OK
    else:
        scope = getattr(srv.ResetSimulation.Request, how)
        assert call(harness, 'reset_simulation', srv.ResetSimulation,
                    srv.ResetSimulation.Request(scope=scope)) == OK
    assert harness.sim.step_count == (STEPS if how == 'SCOPE_STATE' else 0)
    assert drive(harness) == first


def test_deleted_start_up_entities_come_back_with_a_full_reset(r2d2_sim_factory):
    """The ground, a model and the robot deleted (its topics too); DEFAULT: all back, same run."""
    harness = r2d2_sim_factory(cmd_vel_timeout=0.0,
                               extra_models=['cube_small.urdf 0.8 0.05 0.025'])
    sim = harness.sim
    start_up = harness.entities()
    assert len(start_up) == 3 and start_up[:2] == ['ground_plane', 'r2d2']
    first = drive(harness)
    for name in start_up:
        assert call(harness, 'delete_entity', srv.DeleteEntity,
                    srv.DeleteEntity.Request(entity=name)) == OK
    assert harness.entities() == [] and harness.robot_names == []
    # The robot had its interfaces on the simulator's node: they went with it.
    topics = {publisher.topic_name for publisher in sim.publishers}
    assert '/ground_truth' not in topics and '/odom' not in topics and '/clock' in topics
    assert not any(s.topic_name == '/cmd_vel' for s in sim.subscriptions)
    assert '/r2d2_sim/get_joint_info' not in {service.srv_name for service in sim.services}
    assert json.loads(sim.status())['robots'] == {}  # what ~/get_status says
    harness.advance(24)  # a world with nothing in it steps on
    assert call(harness, 'reset_simulation', srv.ResetSimulation,
                srv.ResetSimulation.Request(scope=0)) == OK
    assert harness.entities() == start_up and harness.robot_names == ['r2d2']
    assert '/ground_truth' in {publisher.topic_name for publisher in sim.publishers}
    assert drive(harness) == first


def test_only_the_full_scopes_bring_deleted_start_up_entities_back(r2d2_sim):
    """STATE and SPAWNED leave the deleted ground plane out; STOPPED brings it back."""
    assert call(r2d2_sim, 'delete_entity', srv.DeleteEntity,
                srv.DeleteEntity.Request(entity='ground_plane')) == OK
    for scope in ('SCOPE_STATE', 'SCOPE_SPAWNED', 'SCOPE_TIME'):
        request = srv.ResetSimulation.Request(scope=getattr(srv.ResetSimulation.Request, scope))
        assert call(r2d2_sim, 'reset_simulation', srv.ResetSimulation, request) == OK
        assert r2d2_sim.entities() == ['r2d2'], scope
    request = srv.SetSimulationState.Request()
    request.state.state = STATE.STATE_STOPPED
    assert call(r2d2_sim, 'set_simulation_state', srv.SetSimulationState, request) == OK
    assert r2d2_sim.entities() == ['ground_plane', 'r2d2']


def test_the_harness_follows_a_listed_robot_deleted_and_built_again(r2d2_sim_factory):
    """After reset_world the first handle is robot a's again, reading its new interfaces."""
    harness = r2d2_sim_factory(robots=['a', 'b'], **{'b.initial_pose': [2.0, 0.0, math.pi]})
    harness.send_cmd_vel(0.3)
    harness.advance(seconds=0.5)
    harness.delete_entity('a')
    assert harness.robot().name == 'b' and harness.robot_names == ['b']
    harness.reset_world()
    assert [harness.robot().name, *harness.robot_names] == ['a', 'a', 'b']
    assert harness.ground_truth().pose.pose.position.x == pytest.approx(0.0, abs=1e-3)
    harness.send_cmd_vel(0.3)
    harness.advance(seconds=0.5)
    assert harness.ground_truth().pose.pose.position.x > 0.05


def test_a_recording_follows_the_robot_out_of_the_world_and_back(r2d2_sim_factory, tmp_path):
    """
    Recorded: ground_truth up to the delete, none while it is gone, the reset world's after.

    Its topics leave the recording and the live view with it (which then
    stops re-sending its latched robot_description), and come back after.
    """
    from mcap.reader import make_reader
    path = tmp_path / 'run.mcap'
    harness = r2d2_sim_factory(record=str(path))
    harness.advance(24)
    topics = harness.sim.sink.topics
    assert '/ground_truth' in topics and '/robot_description' in topics
    harness.delete_entity('r2d2')
    assert harness.sim.sink.topics == ['/clock']
    harness.advance(24)
    harness.reset_world()  # time back to 0, then one control period: step 1
    assert harness.sim.sink.topics == topics
    harness.advance(24)
    harness.close()
    with open(path, 'rb') as stream:
        messages = [(channel, message) for _, channel, message
                    in make_reader(stream).iter_messages(log_time_order=False)]
    steps = [round(message.log_time * 240 / 1e9) for channel, message in messages
             if channel.topic == '/ground_truth']
    # After the reset the log time counts on from the last logged (/clock at step 48).
    assert steps == list(range(25)) + list(range(49, 74))
