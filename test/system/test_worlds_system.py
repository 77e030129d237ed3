"""
Worlds across processes: a client of the standard alone, SimProcess's verbs, a load during a step.

sim_node in its own process. A client that knows only simulation_interfaces
lists, loads, uses (named poses, a spawn in a named pose's frame, a bounds
filter) and unloads a world. SimProcess does the same through its verbs.
A LoadWorld that arrives while a step request runs (sim_node serves the
standard from two threads) is refused with INCORRECT_STATE and leaves the
world as it was.
"""

import json
import math
from pathlib import Path
import subprocess
import sys

import pytest
from simulation_interfaces import msg, srv

from common import REPO, TEST_DIR
from r2d2_sim.client import ros_child_env
from r2d2_sim.testing import HarnessError, StandardError

CLIENT = Path(TEST_DIR) / 'children' / 'world_client.py'
ROOM = 'package://r2d2_sim/urdf/room.world.yaml'
STATE = msg.SimulationState
FEATURES = msg.SimulatorFeatures


def test_a_client_of_the_standard_alone_lists_loads_uses_and_unloads_a_world(
        r2d2_sim_process, tmp_path):
    sim = r2d2_sim_process(start_paused=True, cmd_vel_timeout=0.0)
    out = tmp_path / 'seen.json'
    result = subprocess.run([sys.executable, str(CLIENT), str(out)],
                            env=ros_child_env(sim.domain_id), cwd=REPO, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-3000:]
    seen = json.loads(out.read_text())
    assert {FEATURES.AVAILABLE_WORLDS, FEATURES.WORLD_LOADING, FEATURES.WORLD_UNLOADING,
            FEATURES.NAMED_POSES, FEATURES.POSE_BOUNDS, FEATURES.ENTITY_BOUNDS_BOX} <= \
        set(seen['features'])
    assert seen['worlds'] == [['room', ROOM]]
    assert seen['loaded'] == 'room' and seen['state_after_load'] == STATE.STATE_STOPPED
    assert seen['area'] == ['spawn_area', msg.Bounds.TYPE_BOX,
                            [[0.7, 0.6, 1.0], [-0.7, -0.6, 0.0]]]
    assert seen['in_area'] == [seen['crate']]  # fell onto the floor of the spawn area
    assert seen['robot_at'][:2] == pytest.approx(seen['goal'], abs=0.01)
    assert abs(seen['robot_at'][2]) == pytest.approx(math.pi, abs=0.01)
    assert seen['state_after_unload'] == STATE.STATE_NO_WORLD
    assert seen['entities_after_unload'] == ['ground_plane', 'r2d2']
    assert seen['current_after_unload'] == srv.GetCurrentWorld.Response.NO_WORLD_LOADED
    assert seen['step_after_unload'] == msg.Result.RESULT_OPERATION_FAILED


def test_sim_process_verbs_load_a_world_and_use_its_named_poses(r2d2_sim_process):
    sim = r2d2_sim_process(start_paused=True, cmd_vel_timeout=0.0)
    assert sim.current_world().name == 'empty'
    assert [w.name for w in sim.available_worlds(tags=['indoor'])] == ['room']
    assert sim.load_world(ROOM).name == 'room'
    area = sim.named_pose('spawn_area')
    assert area.bounds.points == ((0.7, 0.6, 1.0), (-0.7, -0.6, 0.0))
    crate = sim.spawn('cube_small.urdf', at='spawn_area', position=(0.2, 0.1, 0.025))
    assert sim.entity_state(crate).position == pytest.approx((-0.8, 1.3, 0.025), abs=1e-6)
    sim.set_entity_state('r2d2', (0.0, 0.0, 0.471), at='dock')
    sim.step_physics(24)
    truth = sim.ground_truth().pose.pose.position
    assert (truth.x, truth.y) == pytest.approx((1.4, 0.0), abs=0.01)
    sim.set_entity_info(crate, tags=['test', 'crate'])
    assert sim.entity_info(crate).tags == ('test', 'crate')
    assert sim.standard.entities(tags=['crate']) == [crate]
    upper, lower = sim.entity_bounds(crate).points
    assert upper == pytest.approx((0.025, 0.025, 0.025), abs=1e-6)
    sim.unload_world()
    with pytest.raises(HarnessError, match='no world is loaded'):
        sim.step(1)
    sim.load_world(ROOM)
    assert sim.standard.state() == STATE.STATE_STOPPED


def test_sim_process_available_worlds_can_leave_out_a_bad_world_path(r2d2_sim_process,
                                                                     tmp_path):
    (tmp_path / 'bad.sdf').write_text('<sdf version="1.9"><world name="w"><unclosed')
    sim = r2d2_sim_process(start_paused=True, world_paths=[str(tmp_path)])
    with pytest.raises(StandardError, match='DEFAULT_SOURCES_FAILED.*bad.sdf'):
        sim.available_worlds()
    assert [w.name for w in sim.available_worlds(continue_on_error=True)] == \
        ['empty', 'room', 'samurai']


def test_a_load_world_during_a_step_is_refused_and_the_world_stays(r2d2_sim_process):
    sim = r2d2_sim_process(start_paused=True, world=ROOM, scan_rate=0.0, imu_rate=0.0)
    standard, probe = sim.standard, sim.probe
    before = standard.entities()
    stepper = probe.node.create_client(srv.StepSimulation, '/step_simulation')
    assert probe.spin_until(stepper.service_is_ready, 10.0)
    long_step = stepper.call_async(srv.StepSimulation.Request(steps=2**40))
    assert probe.spin_until(lambda: sim.status()['step'] > 0, 30.0)  # it runs
    reply = standard.call('load_world', srv.LoadWorld.Request(
        uri='package://r2d2_sim/urdf/empty.world.yaml'), check=False)
    assert reply.result.result == msg.Result.RESULT_INCORRECT_STATE
    assert 'step' in reply.result.error_message
    assert standard.current_world().name == 'room' and standard.entities() == before
    unload = standard.call('unload_world', srv.UnloadWorld.Request(), check=False)
    assert unload.result.result == msg.Result.RESULT_INCORRECT_STATE
    standard.set_state(STATE.STATE_PLAYING)  # ends the step at its next chunk
    assert probe.spin_until(long_step.done, 30.0)
    assert long_step.result().result.result == msg.Result.RESULT_OPERATION_FAILED
    standard.set_state(STATE.STATE_PAUSED)
    assert standard.load_world(uri='package://r2d2_sim/urdf/empty.world.yaml').world.name == \
        'empty'
    assert standard.state() == STATE.STATE_STOPPED
