"""
A Gazebo world as sim_node's ``world`` parameter, in a process of its own.

The arena (``sdf_files.arena``), its models found through
``GZ_SIM_RESOURCE_PATH`` as a Gazebo user has it set: the entities and named
poses come through the standard, and what the world has that is not
simulated is one warning line in the log, not one per element.
"""

import pytest

from sdf_files import arena, POST


def test_sim_node_starts_in_a_gazebo_world_found_through_the_gazebo_variable(
        r2d2_sim_process, tmp_path, monkeypatch):
    monkeypatch.setenv('R2D2_SIM_CACHE_DIR', str(tmp_path / 'cache'))
    monkeypatch.setenv('GZ_SIM_RESOURCE_PATH', str(tmp_path / 'models'))
    world = arena(tmp_path)
    sim = r2d2_sim_process(world=world, start_paused=True, scan_rate=0.0)
    assert sim.entities() == ['ground_plane', 'r2d2', 'arena_wall', 'pillar', 'corner']
    assert sim.current_world().name == 'arena'
    assert [pose.name for pose in sim.named_poses()] == ['start', 'goal']
    assert sim.entity_state('corner').position[:2] == pytest.approx(POST[:2], abs=1e-6)
    result = sim.stop()
    log = result.stdout + result.stderr
    assert log.count('not simulated') == 1
    assert ('world arena: not simulated: physics max_step_size 0.001 s (r2d2_sim steps '
            '0.00416667 s: physics_rate), plugin, light') in log
