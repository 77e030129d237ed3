"""
A LoadWorld at real time: the old world steps on while the new one is built, then stops at 0.

The node builds the new world a few bodies at a time with its lock held and
lets the paced loop take a step between; the swap, the zero ``/clock`` and
the pause come in one hold of the lock, so no step of the new world runs
before the caller's reply.
"""

import threading

from common import connected_clients
from helpers import make_sim, wait_for

from r2d2_sim.apps.sim_node import run_paced

WORLD = '''
r2d2_sim_world: 1
name: crowded
models:
''' + ''.join(f'  - {{uri: cube_small.urdf, name: cube_{i}, '
              f'position: [{2.0 + 0.2 * i}, 1.0, 0.025]}}\n' for i in range(12))


def test_the_old_world_steps_while_the_new_one_is_built(ros, tmp_path):
    path = tmp_path / 'crowded.world.yaml'
    path.write_text(WORLD)
    poses = {'b.initial_pose': [1.0, 0.0, 0.0], 'c.initial_pose': [-1.0, 0.0, 0.0]}
    sim = make_sim(ros, real_time_factor=1.0, world_paths=[str(tmp_path)],
                   robots=['a', 'b', 'c'], **poses)
    simulation = sim.simulation
    building = simulation.loading_world
    seen = []

    def loading_world(*args, **kwargs):  # the step count at each body built
        steps = building(*args, **kwargs)
        while True:
            seen.append(simulation.step_count)
            try:
                next(steps)
            except StopIteration as stop:
                return stop.value
            yield
    simulation.loading_world = loading_world
    stop = threading.Event()
    runner = threading.Thread(target=run_paced, args=(sim, stop), daemon=True)
    runner.start()
    try:
        assert wait_for(lambda: sim.step_count > 24, 10.0)
        world = sim.load_world(str(path))
        assert sim.paused and sim.step_count == 0  # stopped at 0 before any step of it
        assert world.name == 'crowded' and 'cube_11' in simulation.world.bodies
    finally:
        stop.set()
        runner.join(5.0)
    assert len(seen) >= 16  # the ground, three robots, twelve cubes, the swap
    assert seen[-2] > seen[0]  # the old world stepped on between the bodies


def test_a_simulation_closed_between_two_chunks_ends_the_load_in_one_line(ros, tmp_path):
    """As when the node is destroyed mid-load: a refusal, the world stays closed, nothing leaks."""
    import pytest
    from r2d2_sim.errors import RefusedError
    path = tmp_path / 'crowded.world.yaml'
    path.write_text(WORLD)
    sim = make_sim(ros, world_paths=[str(tmp_path)])  # running, nothing paces it here
    clients = connected_clients()
    waits = []

    def wait_for_a_step(before):  # between two chunks, the lock free: close then
        waits.append(before)
        if len(waits) == 1:
            with sim.lock:
                sim.simulation.close()
    sim._wait_for_a_step = wait_for_a_step
    with pytest.raises(RefusedError, match='shutting down'):
        sim.load_world(str(path))
    assert len(waits) == 1 and not sim.simulation.world.connected
    # The simulator's own client gone, and no build's left.
    assert len(connected_clients()) == len(clients) - 1
