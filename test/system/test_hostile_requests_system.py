"""
What a hostile peer on the domain sends, against sim_node in its own process.

Each request was found by a security review to freeze the node, abort it or
keep SIGINT from stopping it. Each must now be answered with the standard's
code at once, the clock must run on, and SIGINT must end the node cleanly
(exit 0; a node that does not stop within the harness's 10 s is killed,
status -9). The node runs in a process of its own so that a frozen node
fails the test instead of freezing the test run.
"""

import os
import struct

from simulation_interfaces import srv

from r2d2_sim.client import wait_for
from sdf_files import sdf

LOAD, SPAWN = srv.LoadWorld.Response, srv.SpawnEntity.Response
# How long a call may go unanswered: a frozen node never answers.
CALL_TIMEOUT_S = 20.0


def clock_runs(sim) -> bool:
    """Return True once the simulated time has moved on from now (deadline: 10 s)."""
    before = sim.status()['sim_time_ns']
    return wait_for(lambda: sim.status()['sim_time_ns'] > before, 10.0)


def stops_on_sigint(sim) -> bool:
    """Stop the node with SIGINT; return True when it exited 0 (not killed)."""
    result = sim.stop()
    return result.returncode == 0


def test_comment_floods_to_load_world_and_spawn_entity_are_answered_at_once(
        r2d2_sim_process):
    sim = r2d2_sim_process(scan_rate=0.0, cmd_vel_timeout=0.0, timeout_s=CALL_TIMEOUT_S)
    flood = '<!---->' * 40  # 280 bytes: 2^40 tries for a backtracking root sniffer
    loaded = sim.standard.call('load_world', srv.LoadWorld.Request(resource_string=flood),
                               check=False)
    assert loaded.result.result == LOAD.UNSUPPORTED_FORMAT, loaded.result.error_message
    spawned = sim.standard.call('spawn_entity', srv.SpawnEntity.Request(
        resource_string=flood), check=False)
    assert spawned.result.result == SPAWN.RESOURCE_PARSE_ERROR, spawned.result.error_message
    assert clock_runs(sim)
    assert stops_on_sigint(sim)


def test_a_world_whose_mesh_is_a_fifo_is_refused_and_sigint_still_stops_the_node(
        r2d2_sim_process, tmp_path, monkeypatch):
    monkeypatch.setenv('R2D2_SIM_CACHE_DIR', str(tmp_path / 'cache'))
    os.mkfifo(tmp_path / 'wall.stl')  # opened the usual way, it waits for a writer forever
    (tmp_path / 'fifo.sdf').write_text(sdf(
        '<world name="fifo"><model name="wall"><static>true</static><link name="l">'
        '<collision name="c"><geometry><mesh><uri>wall.stl</uri></mesh></geometry>'
        '</collision></link></model></world>'))
    sim = r2d2_sim_process(scan_rate=0.0, cmd_vel_timeout=0.0, timeout_s=CALL_TIMEOUT_S,
                           world_paths=[str(tmp_path)])
    loaded = sim.standard.call('load_world', srv.LoadWorld.Request(
        uri=str(tmp_path / 'fifo.sdf')), check=False)
    assert loaded.result.result == LOAD.UNSUPPORTED_ASSETS, loaded.result.error_message
    assert 'not a regular file' in loaded.result.error_message
    assert clock_runs(sim)
    assert stops_on_sigint(sim)


def test_a_urdf_beside_a_sparse_2_gb_mesh_is_refused_and_the_node_lives_on(
        r2d2_sim_process, tmp_path, monkeypatch):
    monkeypatch.setenv('R2D2_SIM_CACHE_DIR', str(tmp_path / 'cache'))
    size = 2 << 30
    with open(tmp_path / 'huge.stl', 'wb') as handle:  # a binary STL header, then holes
        handle.write(b'\0' * 80 + struct.pack('<I', (size - 84) // 50))
        handle.truncate(size)
    (tmp_path / 'huge.urdf').write_text(
        '<robot name="huge"><link name="base"><visual><geometry><mesh filename="huge.stl"/>'
        '</geometry></visual></link></robot>')
    sim = r2d2_sim_process(scan_rate=0.0, cmd_vel_timeout=0.0, timeout_s=CALL_TIMEOUT_S)
    spawned = sim.standard.call('spawn_entity', srv.SpawnEntity.Request(
        uri=str(tmp_path / 'huge.urdf')), check=False)
    assert spawned.result.result == SPAWN.UNSUPPORTED_ASSETS, spawned.result.error_message
    assert 'huge.stl is larger than' in spawned.result.error_message
    assert clock_runs(sim)
    assert stops_on_sigint(sim)


def test_a_world_of_200_links_at_one_point_is_refused_and_the_clock_runs_on(
        r2d2_sim_process, tmp_path, monkeypatch):
    """30 kB that passed every budget: the next step ran for minutes (180 bodies, 25 s)."""
    monkeypatch.setenv('R2D2_SIM_CACHE_DIR', str(tmp_path / 'cache'))
    links = ''.join(
        f'<link name="l{i}"><pose>0 0 0.5 0 0 0</pose><inertial><mass>1</mass><inertia><ixx>0.01'
        '</ixx><iyy>0.01</iyy><izz>0.01</izz></inertia></inertial><collision name="c"><geometry>'
        '<box><size>0.3 0.3 0.3</size></box></geometry></collision></link>' for i in range(200))
    sim = r2d2_sim_process(scan_rate=0.0, cmd_vel_timeout=0.0, timeout_s=CALL_TIMEOUT_S)
    loaded = sim.standard.call('load_world', srv.LoadWorld.Request(resource_string=sdf(
        f'<world name="pile"><model name="m">{links}</model></world>')), check=False)
    assert loaded.result.result == LOAD.RESOURCE_PARSE_ERROR, loaded.result.error_message
    assert clock_runs(sim)
    assert stops_on_sigint(sim)
