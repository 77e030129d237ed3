"""
The node's live view and recording with robots spawned and deleted: what a deleted robot leaves.

In-process (``SimHarness``) with the live view and the recording on; robots
spawned through the core in namespaces of their own, then deleted.
"""

import gc
import socket

import foxglove
from mcap.reader import make_reader

from r2d2_sim.testing import LiveViewClient, SimHarness


def free_port():
    """Return a TCP port nothing listens on now."""
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def sdk_channels():
    """Return how many foxglove.Channel objects this process holds."""
    gc.collect()
    return sum(isinstance(o, foxglove.Channel) for o in gc.get_objects())


def test_a_deleted_robot_leaves_no_channel_but_in_the_file(tmp_path):
    """Viewers see its topics go; the sink holds what it held before; the file lists them."""
    port = free_port()
    path = tmp_path / 'run.mcap'
    with SimHarness(foxglove_port=port, record=str(path)) as harness, \
            LiveViewClient(port) as view:
        urdf = harness.sim.simulation.robot.source
        topics, before = list(harness.sim.sink.topics), sdk_channels()
        for cycle in range(5):
            name = harness.spawn(urdf, name=f'bot{cycle}', namespace=f'/bot{cycle}',
                                 position=(3.0 + cycle, 0.0, 0.48))
            harness.advance(steps=2)
            assert view.pump(lambda: f'/bot{cycle}/odom' in view.channels)
            harness.delete_entity(name)
            assert view.pump(lambda: not any(t.startswith('/bot') for t in view.channels))
        assert harness.sim.sink.topics == topics
        assert sdk_channels() == before
    with open(path, 'rb') as stream:
        recorded = {c.topic for c in make_reader(stream).get_summary().channels.values()}
    assert {f'/bot{cycle}/odom' for cycle in range(5)} <= recorded  # MCAP keeps its records
