"""
Files a hostile world brings, or another user of the machine leaves, in the core.

No ROS. A security review found each of these: a mesh that is a FIFO (the load
waited for a writer forever), a zipped COLLADA file (pycollada unpacks it past
every bound), a URDF's meshes (loaded by PyBullet unbounded), an SDF model
spawned from outside the allowed places, and a mesh cache others can write.
Each must be refused at once in one line with the standard's code, naming the
file and never its contents. Calls that used to block run in a thread under a
deadline (5 s) that only a blocked call meets.
"""

import os
import threading

import pytest

from r2d2_sim.errors import RefusedError
from sdf_files import sdf

SIMULATION_DEFAULTS = {'scan_rate': 0.0, 'imu_rate': 0.0, 'cmd_vel_timeout': 0.0}
DEADLINE_S = 5.0


def within_deadline(call, unblock=lambda: None):
    """
    Return what ``call()`` raised (or returned) when it ends within DEADLINE_S.

    Fails the test when it does not end; ``unblock`` then releases it (a
    thread blocked in a system call cannot be stopped from outside).
    """
    outcome = {}

    def run():
        try:
            outcome['value'] = call()
        except BaseException as exc:  # handed to the test
            outcome['value'] = exc
    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(DEADLINE_S)
    if thread.is_alive():
        unblock()
        thread.join(DEADLINE_S)
        pytest.fail(f'the call did not end within {DEADLINE_S:g} s')
    return outcome['value']


def release_fifo(path):
    """Open ``path`` for writing and close it: a reader blocked on the FIFO reads its end."""
    def unblock():
        try:
            os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
        except OSError:
            pass
    return unblock


def mesh_world(directory, uri, name='hostile'):
    """Write an SDF world of one static model with the mesh ``uri``; return its path."""
    path = directory / f'{name}.sdf'
    path.write_text(sdf(
        f'<world name="{name}"><model name="thing"><static>true</static><link name="l">'
        f'<collision name="c"><geometry><mesh><uri>{uri}</uri></mesh></geometry></collision>'
        '</link></model></world>'))
    return str(path)


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """Keep meshes converted in a cache of the test's own."""
    monkeypatch.setenv('R2D2_SIM_CACHE_DIR', str(tmp_path / 'cache'))
    return tmp_path / 'cache'


def test_a_mesh_that_is_a_fifo_is_refused_at_once_not_waited_for(make, tmp_path, cache):
    os.mkfifo(tmp_path / 'wall.stl')
    world = mesh_world(tmp_path, 'wall.stl')
    simulation = make(world_paths=[str(tmp_path)])
    refused = within_deadline(lambda: simulation.load_world(world),
                              release_fifo(str(tmp_path / 'wall.stl')))
    assert isinstance(refused, RefusedError), refused
    assert refused.code == 'UNSUPPORTED_ASSETS'
    assert 'wall.stl is not a regular file' in refused.message
    assert simulation.world_file.name == 'empty'
