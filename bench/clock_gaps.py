#!/usr/bin/env python3
"""
Does the physics wait while a world or a meshed model is read? ``/clock`` gaps, tree against tree.

    .venv/bin/python bench/clock_gaps.py [--rounds 3] [--tree DIR]... [--quick]

Starts ``sim_node`` from each tree given (default: this one; pass an older
checkout with ``--tree`` to compare, e.g. ``git worktree add /tmp/base
9a04502``), in turns, at real time with the default outputs, and listens to
``/clock`` from this process, noting when each message arrives. Two requests
through the simulation standard, each with an empty mesh cache:

- **LoadWorld** of the warehouse of ``bench/sdf_world.py`` (35 models with
  COLLADA, STL and OBJ meshes, 153,088 triangles, one of them a concave wall
  mesh of 73,728): the read phase (files, includes, meshes converted) runs
  while the old world still steps, so its ``/clock`` keeps coming; so does,
  since the world is built beside the old one, the build (``loadURDF`` of each
  body in a client of its own, the lock taken a body or so at a time); then
  the switch, and ``/clock`` says 0 once, the simulation stopped there as the
  standard says (no ``/clock`` while paused). An older tree builds the bodies
  at the switch, with the lock held.
- **SpawnEntity** of a meshed SDF model (a statue of 20,480 triangles in
  COLLADA, moving, so each piece becomes a convex hull) while the room runs.

For each: the longest ``/clock`` gap (wall time between two messages) while
the request was answered, split for the load into what comes before the
switch (``load_read_*``: the read, and the build where it is done beside) and
the switch itself (the last message of the old world to the zero of the new
one), and the request's own wall time. Writes
``bench/clock_gaps.json``. Numbers are printed, never asserted.
"""

import argparse
import os
import statistics
import sys
import tempfile
import threading
import time

from common import BENCH_DIR, local_date, machine_info, REPO, write_json

RESULTS_PATH = os.path.join(BENCH_DIR, 'clock_gaps.json')
STATUE_SUBDIVISIONS = 5  # an icosphere of 20,480 triangles


def write_statue(models):
    """Write ``models/statue``: a moving SDF model with a COLLADA mesh; return its directory."""
    import trimesh
    from sdf_world import _dae, _mesh_link, _model
    mesh = trimesh.creation.icosphere(subdivisions=STATUE_SUBDIVISIONS, radius=0.3)
    directory = _model(models, 'statue', '<model name="statue">'
                       + _mesh_link('meshes/statue.dae', False, mass=20.0) + '</model>')
    _dae(os.path.join(directory, 'meshes', 'statue.dae'), [(mesh, (0.6, 0.6, 0.5, 1.0))])
    return directory


class ClockListener:
    """``/clock`` on a domain, each message's arrival (monotonic s) and stamp (ns) kept."""

    def __init__(self, domain_id):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile
        from rosgraph_msgs.msg import Clock
        from simulation_interfaces import srv
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node('clock_gaps', context=self.context)
        self.arrivals = []
        self.lock = threading.Lock()
        self.node.create_subscription(Clock, '/clock', self._take, QoSProfile(depth=1000))
        self.srv = srv
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _take(self, msg):
        with self.lock:
            self.arrivals.append((time.monotonic(), msg.clock.sec * 10**9 + msg.clock.nanosec))

    def since(self, start):
        """Return the arrivals from ``start`` on, after the last one before it (if any)."""
        with self.lock:
            before = [a for a in self.arrivals if a[0] < start][-1:]
            return before + [a for a in self.arrivals if a[0] >= start]

    def wait_clock(self, timeout_s=60.0):
        """Wait until /clock messages arrive steadily (ten in a row)."""
        deadline = time.monotonic() + timeout_s
        start = time.monotonic()
        while time.monotonic() < deadline:
            if len(self.since(start)) >= 10:
                return
            time.sleep(0.01)
        raise RuntimeError('no /clock from the simulator')

    def call(self, name, srv_type, request, timeout_s=120.0):
        """Call a standard service and wait for its reply; return (reply, wall s)."""
        client = self.node.create_client(srv_type, f'/{name}')
        if not client.wait_for_service(timeout_sec=timeout_s):
            raise RuntimeError(f'no /{name} service')
        start = time.monotonic()
        future = client.call_async(request)
        deadline = start + timeout_s
        while not future.done() and time.monotonic() < deadline:
            time.sleep(0.001)
        took = time.monotonic() - start
        self.node.destroy_client(client)
        if not future.done():
            raise RuntimeError(f'/{name} did not answer within {timeout_s} s')
        reply = future.result()
        if reply.result.result != 1:  # RESULT_OK
            raise RuntimeError(f'/{name}: {reply.result.error_message}')
        return reply, took

    def close(self):
        import rclpy
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


def gaps_ms(arrivals):
    """Return the wall gaps (ms) between consecutive arrivals."""
    return [1e3 * (b[0] - a[0]) for a, b in zip(arrivals, arrivals[1:])]


def measure(tree, root, domain_id, round_index):
    """Run one sim_node of ``tree``: a LoadWorld and a SpawnEntity; return what /clock showed."""
    from r2d2_sim.client import ros_child_env
    from r2d2_sim.testing import ChildProcess, sim_node_command
    env = ros_child_env(domain_id)
    env['PYTHONPATH'] = os.pathsep.join(p for p in (tree, env.get('PYTHONPATH')) if p)
    env['R2D2_SIM_CACHE_DIR'] = os.path.join(root, f'cache_{os.path.basename(tree)}_'
                                                   f'{round_index}')
    models = os.path.join(root, 'models')
    command = sim_node_command({'world_paths': [root], 'model_paths': [models],
                                'world': 'package://r2d2_sim/urdf/room.world.yaml'})
    log = os.path.join(root, f'sim_{round_index}.log')
    listener = ClockListener(domain_id)
    process = ChildProcess(command, env, cwd=tree, log_path=log).start()
    try:
        listener.wait_clock()
        srv = listener.srv
        # LoadWorld: the read phase, then the switch (the zero stamp of the new world).
        start = time.monotonic()
        _, load_s = listener.call('load_world', srv.LoadWorld,
                                  srv.LoadWorld.Request(uri=os.path.join(root, 'warehouse.sdf')))
        seen = listener.since(start)
        zero = next(i for i, a in enumerate(seen) if a[1] == 0 and i > 0)
        read_gaps = gaps_ms(seen[:zero])
        switch_ms = 1e3 * (seen[zero][0] - seen[zero - 1][0])
        # Play again, then SpawnEntity of the meshed model while the world runs.
        request = srv.SetSimulationState.Request()
        request.state.state = 1  # STATE_PLAYING
        listener.call('set_simulation_state', srv.SetSimulationState, request)
        listener.wait_clock()
        start = time.monotonic()
        spawn = srv.SpawnEntity.Request(name='statue', uri=os.path.join(models, 'statue',
                                                                        'model.sdf'))
        spawn.initial_pose.pose.position.x = 3.0
        spawn.initial_pose.pose.position.z = 0.5
        _, spawn_s = listener.call('spawn_entity', srv.SpawnEntity, spawn)
        time.sleep(0.1)  # the messages after the reply, to see the whole gap
        spawn_gaps = gaps_ms(listener.since(start))
    finally:
        process.stop(timeout_s=10.0)
        listener.close()
    return {'load_ms': 1e3 * load_s, 'load_read_max_gap_ms': max(read_gaps, default=0.0),
            'load_read_messages': len(read_gaps) + 1, 'load_switch_gap_ms': switch_ms,
            'spawn_ms': 1e3 * spawn_s, 'spawn_max_gap_ms': max(spawn_gaps)}


def main():
    """Measure each tree in turns; print medians; write bench/clock_gaps.json."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--tree', action='append', help='a checkout to run sim_node from '
                        '(repeatable; default: this one)')
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--quick', action='store_true', help='one round')
    args = parser.parse_args()
    trees = [os.path.abspath(t) for t in (args.tree or [REPO])]
    rounds = 1 if args.quick else args.rounds
    sys.path.insert(0, BENCH_DIR)
    from sdf_world import write_world
    from r2d2_sim.testing import lease_domain
    import logging
    import warnings
    logging.getLogger('trimesh').setLevel(logging.ERROR)
    warnings.simplefilter('ignore', PendingDeprecationWarning)
    results = {tree: [] for tree in trees}
    with tempfile.TemporaryDirectory() as root:
        write_world(root)
        write_statue(os.path.join(root, 'models'))
        lease = lease_domain()
        try:
            for i in range(rounds):
                for tree in trees:  # in turns, so that the machine's load falls on both
                    results[tree].append(measure(tree, root, lease.domain_id, i))
                    print(f'round {i + 1} {tree}: ' + ', '.join(
                        f'{k} {v:.0f}' for k, v in results[tree][-1].items()), flush=True)
        finally:
            lease.release()
    keys = list(next(iter(results.values()))[0])
    print(f'\nmedians over {rounds} round(s), ms')
    print(f'{"":28}' + ''.join(f'{os.path.basename(t)[:16]:>18}' for t in trees))
    summary = {}
    for key in keys:
        row = [statistics.median(r[key] for r in results[tree]) for tree in trees]
        summary[key] = dict(zip(trees, row))
        print(f'{key:28}' + ''.join(f'{v:18.1f}' for v in row))
    write_json(RESULTS_PATH, {'date': local_date(), 'machine': machine_info(),
                              'trees': trees, 'rounds': results, 'medians': summary})


if __name__ == '__main__':
    main()
