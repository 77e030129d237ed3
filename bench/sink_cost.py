"""
What the live view and the recording cost: microseconds per step with every output.

    .venv/bin/python bench/sink_cost.py [--rounds 3] [--steps 2400]

Each configuration runs in a process of its own (``--child``), in turns,
round after round, so that the sink's own threads (the WebSocket server, the
MCAP writer compressing in the background) are counted in that process's CPU
time and no other configuration's. In each, the node and raw
``stepSimulation`` of its world take turns every 240 steps; the node's cost
is the main thread's CPU in its turns plus every other thread's over the run,
raw's the main thread's in its turns, and what a configuration adds is the
difference (on our shared machine raw stepping alone drifts 170-310 us per
step between processes, so only differences taken within one are compared):

- ``outputs``: every output but the camera (state every step, scan 10 Hz, IMU
  100 Hz, TF with the links and ``world -> odom``);
- ``outputs+sink``: the same with ``record`` and ``foxglove_port``, a viewer
  process connected and subscribed to every channel; ``outputs+record`` and
  ``outputs+view`` with one of them;
- ``camera`` and ``camera+sink``: the same two with the head camera at 30 Hz,
  colour and depth;
- ``untaken`` and ``untaken+view``: every output but the camera with nobody
  subscribed, without and with a live view that no viewer watches (an output
  nobody takes, over DDS or in the live view, builds nothing);
- ``relay`` and ``relay+sink``: ``outputs`` and ``outputs+sink`` with
  ``outputs_process``, whose child publishes and holds the sink: what is left
  in the simulator's process (the child's CPU is its own).

Every configuration but the ``untaken`` ones has each topic taken by a
subscription in the child (``common.take_every_topic``): the outputs build
only what someone takes, so "every output" means every output received.

Each child steps at rtf 0 without an executor (as ``SimHarness.advance``
does), 240 steps to warm up, then ``--steps`` of each timed. Prints a table, writes
``bench/sink.json``. Numbers are printed, never asserted.
"""

import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time

from common import (
    BENCH_DIR, init_ros, machine_info, local_date, make_sim_node, take_every_topic, write_json)

OUTPUTS = {'publish_link_tf': True, 'publish_ground_truth_tf': True}  # + the defaults
CAMERA = {'camera_rate': 30.0, 'camera_depth': True}
CHUNK = 240  # raw and node take turns every simulated second
CONFIGS = ('outputs', 'outputs+record', 'outputs+view', 'outputs+sink', 'camera',
           'camera+sink', 'untaken', 'untaken+view', 'relay', 'relay+sink')
SUBSCRIBED = 'subscribed'


def free_port() -> int:
    """Return a TCP port that nothing listens on now."""
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def viewer(port: int) -> None:
    """Connect to the live view, subscribe to every channel, drain until stdin closes."""
    import threading
    from websockets.sync.client import connect
    from r2d2_sim.recording.sink import SUBPROTOCOL
    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    with connect(f'ws://127.0.0.1:{port}', subprotocols=[SUBPROTOCOL], max_size=None,
                 open_timeout=10) as ws:
        channels, subscribed = {}, False
        while not done.is_set():
            try:
                frame = ws.recv(timeout=0.2)
            except TimeoutError:
                frame = None
            if isinstance(frame, str):
                message = json.loads(frame)
                if message['op'] == 'advertise':
                    channels.update({c['id']: c for c in message['channels']})
            if channels and not subscribed and frame is None:  # advertising has settled
                ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
                    {'id': i, 'channelId': c} for i, c in enumerate(channels, 1)]}))
                subscribed = True
                print(SUBSCRIBED, len(channels), flush=True)


def child(config: str, steps: int, domain_id: int) -> dict:
    """Build one configuration, warm it up, time ``steps`` steps of it and of raw in turns."""
    import pybullet
    params = dict(OUTPUTS, real_time_factor=0.0)
    if config.startswith('camera'):
        params.update(CAMERA)
    work = tempfile.mkdtemp(prefix='r2d2_sink_')
    watcher = None
    if config.endswith(('+sink', '+record')):
        params['record'] = os.path.join(work, 'run.mcap')
    if config.endswith(('+sink', '+view')):
        params['foxglove_port'] = free_port()
    if config.startswith('relay'):
        params['outputs_process'] = True
    init_ros(domain_id)
    node = make_sim_node(None, '/sink_bench', params)
    untaken = config.startswith('untaken')  # nobody subscribed, no viewer either
    taker = None if untaken else take_every_topic(None, [node])
    try:
        if 'foxglove_port' in params and not untaken:
            watcher = subprocess.Popen(
                [sys.executable, __file__, '--viewer', str(params['foxglove_port'])],
                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
            line = watcher.stdout.readline()
            if not line.startswith(SUBSCRIBED):
                raise RuntimeError(f'the viewer did not subscribe: {line!r}')
        client = node.world.client._client

        def raw(count):
            for _ in range(count):
                pybullet.stepSimulation(physicsClientId=client)
        node.advance(240)
        time.sleep(0.5)  # the viewer's subscriptions land, the warm-up's data is written
        main = {'raw': 0.0, 'node': 0.0}
        cpu0, thread0, wall0 = time.process_time(), time.thread_time(), time.perf_counter()
        for _ in range(steps // CHUNK):
            for name, advance in (('raw', raw), ('node', node.advance)):
                start = time.thread_time()
                advance(CHUNK)
                main[name] += time.thread_time() - start
        others = (time.process_time() - cpu0) - (time.thread_time() - thread0)
        done = steps // CHUNK * CHUNK
        node_us = 1e6 * (main['node'] + others) / done
        raw_us = 1e6 * main['raw'] / done
        return {'config': config, 'steps': done, 'raw_us_per_step': raw_us,
                'node_us_per_step': node_us, 'other_threads_us_per_step': 1e6 * others / done,
                'extra_us_per_step': node_us - raw_us,
                'wall_s': time.perf_counter() - wall0}
    finally:
        if taker is not None:
            taker.destroy_node()
        node.destroy_node()  # closes the recording: the writer's last chunk is outside the timing
        if watcher is not None:
            watcher.stdin.close()
            watcher.wait(timeout=10)
        recording = os.path.join(work, 'run.mcap')
        if os.path.exists(recording):
            os.remove(recording)
        os.rmdir(work)


def run(rounds: int, steps: int, domain_id: int) -> dict:
    """Run every configuration ``rounds`` times in turn; return the samples and medians."""
    samples = {config: [] for config in CONFIGS}
    for round_index in range(rounds):
        for config in CONFIGS:
            result = subprocess.run(
                [sys.executable, __file__, '--child', config, '--steps', str(steps),
                 '--domain', str(domain_id)], capture_output=True, text=True, timeout=600)
            if result.returncode != 0:
                raise RuntimeError(f'{config}: {result.stderr.strip()[-2000:]}')
            samples[config].append(json.loads(result.stdout.strip().splitlines()[-1]))
            print(f'round {round_index + 1}/{rounds} {config}: '
                  f'+{samples[config][-1]["extra_us_per_step"]:.1f} us CPU per step over raw',
                  flush=True)
    keys = ('raw_us_per_step', 'node_us_per_step', 'extra_us_per_step',
            'other_threads_us_per_step')
    median = {config: {key: statistics.median(s[key] for s in runs) for key in keys}
              for config, runs in samples.items()}
    images_per_step = CAMERA['camera_rate'] / 240.0

    def cost(terms, per=1.0):
        """Median over rounds of the sum of sign * extra(config) within each round, / per."""
        return statistics.median(
            sum(sign * samples[config][i]['extra_us_per_step'] for config, sign in terms) / per
            for i in range(rounds))
    outputs = ('outputs', -1)
    return {'date': local_date(), 'machine': machine_info(), 'rounds': rounds, 'steps': steps,
            'samples': samples, 'median': median,
            'summary': {'outputs_extra_us_per_step': cost([('outputs', 1)]),
                        'sink_us_per_step': cost([('outputs+sink', 1), outputs]),
                        'record_us_per_step': cost([('outputs+record', 1), outputs]),
                        'view_us_per_step': cost([('outputs+view', 1), outputs]),
                        'unwatched_view_us_per_step': cost([('untaken+view', 1),
                                                            ('untaken', -1)]),
                        'relay_extra_us_per_step': cost([('relay', 1)]),
                        'relay_sink_us_per_step': cost([('relay+sink', 1), ('relay', -1)]),
                        'untaken_extra_us_per_step': cost([('untaken', 1)]),
                        'camera_us_per_image': cost([('camera', 1), outputs], images_per_step),
                        'sink_us_per_image': cost([('camera+sink', 1), ('camera', -1),
                                                   ('outputs+sink', -1), ('outputs', 1)],
                                                  images_per_step)}}


def print_table(results: dict) -> None:
    """Print the medians and the costs derived from them."""
    print(f'\nmedians of {results["rounds"]} rounds, {results["steps"]} steps each, CPU us per '
          'step: node (its other threads) / raw = + extra')
    for config, m in results['median'].items():
        print(f'  {config:14s} {m["node_us_per_step"]:8.1f} '
              f'({m["other_threads_us_per_step"]:.1f}) / {m["raw_us_per_step"]:.1f} '
              f'= +{m["extra_us_per_step"]:.1f}')
    s = results['summary']
    print(f'every output but the camera: +{s["outputs_extra_us_per_step"]:.1f} us per step '
          f'over raw; live view with a viewer + recording: +{s["sink_us_per_step"]:.1f} us '
          f'per step (recording alone +{s["record_us_per_step"]:.1f}, live view alone '
          f'+{s["view_us_per_step"]:.1f})')
    print(f'nobody subscribed: +{s["untaken_extra_us_per_step"]:.1f} us per step over raw; a '
          f'live view no viewer watches: {s["unwatched_view_us_per_step"]:+.1f}')
    print(f'outputs_process: +{s["relay_extra_us_per_step"]:.1f} us per step over raw in the '
          f'simulator\'s process; its live view with a viewer + recording there: '
          f'{s["relay_sink_us_per_step"]:+.1f}')
    print(f'head camera 320x240 with depth: {s["camera_us_per_image"] / 1000:.2f} ms per image; '
          f'the sink: +{s["sink_us_per_image"]:.0f} us per image')


def main(argv=None) -> int:
    """Run the benchmark, or one of its child roles."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rounds', type=int, default=3)
    parser.add_argument('--steps', type=int, default=2400)
    parser.add_argument('--domain', type=int, default=96)
    parser.add_argument('--child', choices=CONFIGS, help=argparse.SUPPRESS)
    parser.add_argument('--viewer', type=int, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.viewer:
        viewer(args.viewer)
        return 0
    if args.child:
        print(json.dumps(child(args.child, args.steps, args.domain)))
        return 0
    results = run(args.rounds, args.steps, args.domain)
    print_table(results)
    write_json(os.path.join(BENCH_DIR, 'sink.json'), results)
    return 0


if __name__ == '__main__':
    sys.exit(main())
