"""
An SDF model whose URDF PyBullet refuses: the error names the model and its file, quietly.

No ROS. r2d2_sim writes each SDF body as a URDF in a temporary directory;
the user never wrote that file, so an error naming it (or PyBullet's b3Error
lines on stdout, about link names r2d2_sim made up) tells them nothing. No
valid SDF makes PyBullet refuse today, so the test breaks the URDF writer:
every URDF it writes gets its base link twice.
"""

import pytest

from r2d2_sim.errors import RefusedError, WorldError
from r2d2_sim.sim.sdf import loading
from r2d2_sim.sim.simulation import SpawnRequest
from sdf_files import sdf

SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'scan_rate': 0.0, 'imu_rate': 0.0}
DOOR = ('<model name="door"><pose>0 5 0.5 0 0 0</pose><link name="leaf"><inertial><mass>1'
        '</mass></inertial><collision name="c"><geometry><box><size>1 0.1 1</size></box>'
        '</geometry></collision></link></model>')


@pytest.fixture
def refused_urdf(monkeypatch):
    """Make every URDF written from SDF one PyBullet refuses (two links of one name)."""
    written = loading.urdf_text

    def twice(body, *args):
        text, triangles = written(body, *args)
        first = text.index('<link ')
        link = text[first:text.index('</link>', first) + len('</link>')]
        return text.replace(link, f'{link}\n{link}', 1), triangles
    monkeypatch.setattr(loading, 'urdf_text', twice)


def assert_quietly_named(message, file, capfd):
    assert 'SDF model door of ' + file in message
    assert '.urdf' not in message and 'r2d2_sim_sdf_' not in message  # not the made file
    assert 'b3Error' not in capfd.readouterr().out


def test_a_world_with_a_refused_model_names_it_at_start(make, tmp_path, refused_urdf, capfd):
    world = tmp_path / 'door.sdf'
    world.write_text(sdf(f'<world name="w">{DOOR}</world>'))
    with pytest.raises(WorldError) as refused:
        make(world=str(world))
    assert_quietly_named(str(refused.value), str(world), capfd)


def test_load_world_with_a_refused_model_names_it(make, tmp_path, refused_urdf, capfd):
    world = tmp_path / 'door.sdf'
    world.write_text(sdf(f'<world name="w">{DOOR}</world>'))
    simulation = make(world_paths=[str(tmp_path)])
    capfd.readouterr()
    with pytest.raises(RefusedError) as refused:
        simulation.load_world(str(world))
    assert_quietly_named(refused.value.message, str(world), capfd)


@pytest.mark.parametrize('as_file', [False, True])
def test_a_refused_spawn_names_the_model(make, tmp_path, refused_urdf, capfd, as_file):
    model = tmp_path / 'door.sdf'
    model.write_text(sdf(DOOR))
    simulation = make(world_paths=[str(tmp_path)])
    capfd.readouterr()
    request = SpawnRequest(uri=str(model)) if as_file else SpawnRequest(
        resource_string=sdf(DOOR))
    with pytest.raises(RefusedError) as refused:
        simulation.spawn(request)
    assert refused.value.code == 'RESOURCE_PARSE_ERROR'
    assert_quietly_named(refused.value.message, str(model) if as_file else 'the resource_string',
                         capfd)
