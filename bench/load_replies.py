#!/usr/bin/env python3
"""
Are other requests answered while a heavy world loads? Replies and ``/clock``, tree by tree.

    .venv/bin/python bench/load_replies.py [--rounds 3] [--tree DIR]... [--quick]

A sibling of ``clock_gaps.py``, with a heavier world: 1.8 million triangles in
three static terrain meshes of 600,000 each (COLLADA, binary STL, OBJ), each
the collision and the visual of its model (3.6 million counted, inside the
budget of 4 million), and a moving model of 60 separate spheres in one STL
(76,800 triangles: 60 convex pieces). A user met replies delayed to 1.6-2.2 s
by such a load. Starts ``sim_node`` from each tree given (default: this one;
``--tree`` an older checkout, e.g. ``git archive COMMIT | tar -x -C DIR``), in
turns, in the room at real time, and asks for LoadWorld of that world with an
empty mesh cache while this process asks GetSimulationState every 10 ms (one
request at a time) and listens to ``/clock``. Reported: the load's wall time;
GetSimulationState's reply times in the second before (for scale) and of the
requests answered while the world was read, without the simulator's lock
(median, p99, max), and the longest ``/clock`` gap then (the old world still
steps); then, at the switch (PyBullet builds the bodies, with the lock; the
standard has the simulation stopped), the longest reply of a request waiting
then or sent after, and the ``/clock`` gap. Writes
``bench/load_replies.json``. Numbers are printed, never asserted.
"""

import argparse
import os
import statistics
import sys
import tempfile
import threading
import time

from common import BENCH_DIR, local_date, machine_info, percentile, REPO, write_json

RESULTS_PATH = os.path.join(BENCH_DIR, 'load_replies.json')
TERRAIN_QUADS = 548          # a side: 2 x 548^2 = 600,608 triangles a terrain
SPHERES, SPHERE_SUBDIVISIONS = 60, 3   # 60 x 1,280 triangles
PROBE_PERIOD_S = 0.01


def terrain(seed):
    """Return a bumpy 10 m square of 2 x TERRAIN_QUADS^2 triangles."""
    import numpy
    import trimesh
    n = TERRAIN_QUADS
    rng = numpy.random.default_rng(seed)
    x, y = numpy.meshgrid(numpy.linspace(0.0, 10.0, n + 1), numpy.linspace(0.0, 10.0, n + 1))
    z = rng.random(x.shape) * 0.2
    vertices = numpy.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    corner = (numpy.arange(n)[:, None] * (n + 1) + numpy.arange(n)[None, :]).ravel()
    faces = numpy.concatenate([numpy.stack([corner, corner + 1, corner + n + 2], axis=1),
                               numpy.stack([corner, corner + n + 2, corner + n + 1], axis=1)])
    return trimesh.Trimesh(vertices, faces, process=False)


def write_world(root):
    """Write the heavy world and its models under ``root``; return the world's path."""
    import trimesh
    from trimesh.exchange.obj import export_obj
    from trimesh.exchange.stl import export_stl
    from sdf_world import _dae, _mesh_link, _model
    models = os.path.join(root, 'models')
    names = []
    for index, extension in enumerate(('dae', 'stl', 'obj')):
        name = f'terrain_{extension}'
        directory = _model(models, name, f'<model name="{name}"><static>true</static>'
                           + _mesh_link(f'meshes/terrain.{extension}', True) + '</model>')
        path = os.path.join(directory, 'meshes', f'terrain.{extension}')
        mesh = terrain(index)
        if extension == 'dae':
            _dae(path, [(mesh, (0.5, 0.6, 0.4, 1.0))])
        elif extension == 'stl':
            with open(path, 'wb') as handle:
                handle.write(export_stl(mesh))
        else:
            with open(path, 'w') as handle:
                handle.write(export_obj(mesh, include_normals=False, include_color=False,
                                        include_texture=False))
        names.append(name)
    spheres = []
    for k in range(SPHERES):
        sphere = trimesh.creation.icosphere(subdivisions=SPHERE_SUBDIVISIONS, radius=0.05)
        sphere.apply_translation((0.2 * (k % 8), 0.2 * (k // 8), 0.05))
        spheres.append(sphere)
    directory = _model(models, 'beads', '<model name="beads">'
                       + _mesh_link('meshes/beads.stl', False, 5.0) + '</model>')
    with open(os.path.join(directory, 'meshes', 'beads.stl'), 'wb') as handle:
        handle.write(export_stl(trimesh.util.concatenate(spheres)))
    includes = ''.join(f'<include><uri>model://{name}</uri><name>{name}</name>'
                       f'<pose>{-15 + 11 * i} 6 -0.2 0 0 0</pose></include>'
                       for i, name in enumerate(names))
    path = os.path.join(root, 'heavy.sdf')
    with open(path, 'w') as handle:
        handle.write('<?xml version="1.0"?><sdf version="1.9"><world name="heavy">'
                     f'{includes}<include><uri>model://beads</uri><pose>3 -3 0 0 0 0</pose>'
                     '</include></world></sdf>')
    return path


class Prober:
    """GetSimulationState asked every PROBE_PERIOD_S, one at a time; each reply's time kept."""

    def __init__(self, listener):
        self.listener = listener
        srv = listener.srv
        self.client = listener.node.create_client(srv.GetSimulationState,
                                                  '/get_simulation_state')
        if not self.client.wait_for_service(timeout_sec=60.0):
            raise RuntimeError('no /get_simulation_state service')
        self.request = srv.GetSimulationState.Request()
        self.replies = []   # (sent, monotonic s; reply time, s)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        while not self.stop.is_set():
            sent = time.monotonic()
            future = self.client.call_async(self.request)
            while not future.done() and not self.stop.is_set():
                time.sleep(0.0005)
            if future.done():
                self.replies.append((sent, time.monotonic() - sent))
            time.sleep(PROBE_PERIOD_S)

    def between(self, start, end):
        """Return the reply times (ms) of requests sent from ``start`` and answered by ``end``."""
        return [1e3 * took for sent, took in self.replies if sent >= start and sent + took < end]

    def waiting_at(self, moment):
        """Return the reply times (ms) of the requests sent before ``moment``, answered after."""
        return [1e3 * took for sent, took in self.replies if sent < moment <= sent + took]

    def close(self):
        self.stop.set()
        self.thread.join(timeout=5.0)


def measure(tree, root, world, domain_id, round_index):
    """Run one sim_node of ``tree`` and load the heavy world; return what was seen."""
    from clock_gaps import ClockListener, gaps_ms
    from r2d2_sim.client import ros_child_env
    from r2d2_sim.testing import ChildProcess, sim_node_command
    env = ros_child_env(domain_id)
    env['PYTHONPATH'] = os.pathsep.join(p for p in (tree, env.get('PYTHONPATH')) if p)
    env['R2D2_SIM_CACHE_DIR'] = os.path.join(root, f'cache_{os.path.basename(tree)}_'
                                                   f'{round_index}')
    command = sim_node_command({'world_paths': [root],
                                'model_paths': [os.path.join(root, 'models')],
                                'world': 'package://r2d2_sim/urdf/room.world.yaml'})
    listener = ClockListener(domain_id)
    process = ChildProcess(command, env, cwd=tree,
                           log_path=os.path.join(root, f'sim_{round_index}.log')).start()
    prober = None
    try:
        listener.wait_clock()
        prober = Prober(listener)
        time.sleep(1.0)  # replies with nothing loading, for scale
        start = time.monotonic()
        srv = listener.srv
        _, load_s = listener.call('load_world', srv.LoadWorld, srv.LoadWorld.Request(uri=world),
                                  timeout_s=600.0)
        prober.close()
        seen = listener.since(start)
        zero = next(i for i, a in enumerate(seen) if a[1] == 0 and i > 0)
        switch = seen[zero - 1][0]  # the old world's last /clock: the bodies are built then
        idle = prober.between(start - 1.0, start)
        reading = prober.between(start, switch)
        switching = prober.between(switch, float('inf')) + prober.waiting_at(switch)
    finally:
        if prober is not None:
            prober.close()
        process.stop(timeout_s=10.0)
        listener.close()
    return {'load_ms': 1e3 * load_s,
            'reply_idle_p50_ms': statistics.median(idle),
            'reply_idle_max_ms': max(idle),
            'replies_while_reading': float(len(reading)),
            'reply_read_p50_ms': statistics.median(reading),
            'reply_read_p99_ms': percentile(reading, 99),
            'reply_read_max_ms': max(reading),
            'clock_read_max_gap_ms': max(gaps_ms(seen[:zero]), default=0.0),
            'reply_switch_max_ms': max(switching, default=0.0),
            'clock_switch_gap_ms': 1e3 * (seen[zero][0] - switch)}


def main():
    """Measure each tree in turns; print medians; write bench/load_replies.json."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument('--tree', action='append', help='a checkout to run sim_node from '
                        '(repeatable; default: this one)')
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--quick', action='store_true', help='one round')
    args = parser.parse_args()
    trees = [os.path.abspath(t) for t in (args.tree or [REPO])]
    rounds = 1 if args.quick else args.rounds
    sys.path.insert(0, BENCH_DIR)
    from r2d2_sim.testing import lease_domain
    import logging
    import warnings
    logging.getLogger('trimesh').setLevel(logging.ERROR)
    warnings.simplefilter('ignore', PendingDeprecationWarning)
    results = {tree: [] for tree in trees}
    with tempfile.TemporaryDirectory() as root:
        world = write_world(root)
        lease = lease_domain()
        try:
            for i in range(rounds):
                for tree in trees:  # in turns, so that the machine's load falls on both
                    results[tree].append(measure(tree, root, world, lease.domain_id, i))
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
