"""
What a hostile peer on the domain sends, against sim_node in its own process.

Each request was found by a security review to freeze the node, abort it or
keep SIGINT from stopping it. Each must now be answered with the standard's
code at once, the clock must run on, and SIGINT must end the node cleanly
(exit 0; a node that does not stop within the harness's 10 s is killed,
status -9). The node runs in a process of its own so that a frozen node
fails the test instead of freezing the test run.
"""

from simulation_interfaces import srv

from r2d2_sim.client import wait_for

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
