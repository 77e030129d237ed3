"""
A saved state comes back bit for bit: whatever ran since, the next run repeats the first.

Episodes of a learning environment start from one saved state, each with the
world's boxes placed elsewhere: a run after :meth:`Simulation.restore_state`
must equal the same run in a simulation that never ran anything else, after
any history of other runs (contacts with boxes, a pushed box, turns), and
compared with ``==``, never approximately. Bodies added or removed since the
save make the state one of other bodies: refused in one line.
"""

import math

import pytest

from r2d2_sim.errors import WorldError
from r2d2_sim.sim.settings.table import ConfigError
from r2d2_sim.sim.simulation import SpawnRequest
from r2d2_sim.sim.spawnables import box_urdf

SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'scan_rate': 10.0, 'scan_samples': 90,
                       'publish_rate': 10.0, 'imu_rate': 0.0}
STEPS = 360  # 1.5 s at 240 Hz
PARKED = (0.0, 0.0, -10.0)  # under the ground, out of every ray's and body's way
# Each run: where the boxes stand, and the commands (step -> linear, angular).
RUN_A = {'boxes': [(1.0, 0.0), (2.0, 1.0)], 'commands': {0: (0.8, 0.0), 200: (-0.3, 0.5)}}
RUN_B = {'boxes': [(0.6, -0.4), (1.2, 0.7)], 'commands': {0: (0.5, -0.8), 120: (0.9, 0.4)}}
RUN_C = {'boxes': [(0.8, 0.3), (-1.0, 0.0)], 'commands': {0: (-0.6, 1.0), 90: (0.7, 0.0)}}


def build(make, **parameters):
    """Return a simulation with two fixed boxes and a pushable cube, all parked, and its save."""
    simulation = make(**parameters)
    for name in ('box_0', 'box_1'):
        simulation.spawn(SpawnRequest(name, resource_string=box_urdf((0.3, 0.3, 0.5)),
                                      position=PARKED))
    simulation.spawn(SpawnRequest('cube', resource_string=box_urdf((0.1, 0.1, 0.1), mass_kg=0.5),
                                  position=(0.5, 0.0, 0.05)))
    return simulation, simulation.save_state()


def run(simulation, saved, how):
    """Restore, place the boxes, drive ``how``; return every body's state at every step."""
    simulation.restore_state(saved)
    for index, (x, y) in enumerate(how['boxes']):
        simulation.set_entity_state(f'box_{index}', '', (x, y, 0.25), (0.0, 0.0, 0.0, 1.0),
                                    (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    states, scans = [], []
    robot = simulation.robot
    for step in range(STEPS):
        if step in how['commands']:
            robot.command(*how['commands'][step])
        result = simulation.step()
        states.append(tuple((body.name, body.world_state())
                            for body in simulation.world.bodies.values()))
        if result is not None and result.measurements[0].scan is not None:
            scans.append(result.measurements[0].scan.tobytes())
    return states, scans


def test_a_run_after_a_restore_equals_the_run_of_a_simulation_that_ran_nothing_else(make):
    """Fresh A; then B, A, C, C, A in another simulation: each A and each C equal its first."""
    fresh, fresh_saved = build(make)
    first_a = run(fresh, fresh_saved, RUN_A)
    # The runs touch what they should: R2D2 drives into box_0 in A and pushes the cube.
    assert first_a[0][-1] != first_a[0][0]
    simulation, saved = build(make)
    run(simulation, saved, RUN_B)
    assert run(simulation, saved, RUN_A) == first_a
    first_c = run(simulation, saved, RUN_C)
    assert run(simulation, saved, RUN_C) == first_c
    assert run(simulation, saved, RUN_A) == first_a
    assert run(fresh, fresh_saved, RUN_C) == first_c


def test_time_goes_on_and_the_sensors_start_again_from_the_restore(make):
    """The step count keeps counting; the scan is due one period after the restore, as at start."""
    simulation, saved = build(make)
    run(simulation, saved, RUN_A)
    assert simulation.step_count == STEPS
    simulation.restore_state(saved)
    assert simulation.step_count == STEPS
    assert simulation.steps_to_next_publish() == 24
    results = [simulation.step() for _ in range(24)]
    assert results[-1].measurements[0].scan is not None
    assert all(r is None for r in results[:-1])


def test_a_state_of_other_bodies_is_refused_in_one_line_and_the_world_stays(make):
    """After a spawn or a state reset: WorldError naming why; the same bodies again: restored."""
    simulation, saved = build(make)
    first_a = run(simulation, saved, RUN_A)
    simulation.spawn(SpawnRequest('late', resource_string=box_urdf(), position=(5.0, 5.0, 0.1)))
    with pytest.raises(WorldError, match='^the saved state is of other bodies: bodies were added, '
                                         'removed or loaded again since it was saved$'):
        simulation.restore_state(saved)
    assert 'late' in simulation.world.bodies
    simulation.delete_entity('late')  # the same bodies again, under the same ids
    assert run(simulation, saved, RUN_A) == first_a
    simulation.reset(state=True)  # every body loaded again
    with pytest.raises(WorldError, match='^the saved state is of other bodies'):
        simulation.restore_state(saved)
    simulation.step()  # and the world runs on


def test_a_state_of_a_deleted_body_is_refused_when_another_takes_its_name_and_id(make):
    """
    A body spawned in a deleted one's place takes its id (PyBullet reuses ids) and its name.

    The restore was accepted and put the new body (a 1 m fixed wall) where the
    saved cube stood, overlapping R2D2: the bodies themselves are compared now.
    """
    simulation, saved = build(make)
    cube_id = simulation.world.bodies['cube'].id
    simulation.delete_entity('cube')
    simulation.spawn(SpawnRequest('cube', resource_string=box_urdf((1.0, 1.0, 1.0)),
                                  position=(5.0, 5.0, 0.5)))
    assert simulation.world.bodies['cube'].id == cube_id  # what made the old check pass
    with pytest.raises(WorldError, match='^the saved state is of other bodies: bodies were added, '
                                         'removed or loaded again since it was saved$'):
        simulation.restore_state(saved)
    assert simulation.entities.state('cube').position == pytest.approx((5.0, 5.0, 0.5))


def test_a_state_saved_before_a_blow_up_is_refused_in_one_line_and_the_world_stays(make):
    """
    The blow-up loads the robot and the ground again: last in Bullet's order, whatever their ids.

    Restoring the state saved before failed in PyBullet ("Couldn't restore
    state") after putting the ground plane where the robot was saved.
    """
    simulation, saved = build(make)
    run(simulation, saved, RUN_A)
    simulation.robot.body.set_base_state(linear_velocity=(math.nan, 0.0, 0.0))
    simulation.step()
    assert simulation.blow_ups == 1
    before = [(name, body.world_state()) for name, body in simulation.world.bodies.items()]
    with pytest.raises(WorldError, match='^the saved state is of other bodies: bodies were added, '
                                         'removed or loaded again since it was saved$'):
        simulation.restore_state(saved)
    assert [(name, body.world_state())
            for name, body in simulation.world.bodies.items()] == before
    simulation.reset(state=True)  # built again: a state saved now comes back
    again = simulation.save_state()
    first_a = run(simulation, again, RUN_A)
    assert run(simulation, again, RUN_A) == first_a


def test_a_state_is_saved_when_a_model_s_file_is_gone_since_start_up(make, tmp_path):
    """
    The crate's URDF (no collision groups of its own) removed after start-up: saved and restored.

    Whether a URDF sets its own groups is read when it is loaded; save_state said the
    crate "sets its own collision groups", reading its file only then.
    """
    crate = tmp_path / 'crate.urdf'
    crate.write_text(box_urdf((0.2, 0.2, 0.2), mass_kg=1.0, name='crate'))
    simulation = make(scan_rate=0.0, extra_models=[f'{crate} 1.0 0.0 0.1'])
    crate.unlink()
    saved = simulation.save_state()
    first = run(simulation, saved, {'boxes': [], 'commands': {0: (0.8, 0.0)}})
    assert first[0][-1] != first[0][0]
    assert run(simulation, saved, {'boxes': [], 'commands': {0: (0.8, 0.0)}}) == first


def test_restart_noise_reseeds_every_stream_and_takes_new_noise_settings(make):
    """The same seed reads the same noisy scans after a restore; another seed others."""
    simulation, saved = build(make, scan_noise_std=0.01)
    simulation.restart_noise(7)
    _, seven = run(simulation, saved, RUN_A)
    simulation.restart_noise(8)
    _, eight = run(simulation, saved, RUN_A)
    simulation.restart_noise(7)
    assert run(simulation, saved, RUN_A)[1] == seven
    assert eight != seven
    simulation.restart_noise(7, scan_noise_std=0.0)
    _, exact = run(simulation, saved, RUN_A)
    simulation.restart_noise(9, scan_noise_std=0.0)
    assert run(simulation, saved, RUN_A)[1] == exact  # no noise: the seed changes nothing
    assert exact != seven


def test_restart_noise_refuses_what_is_no_noise_parameter_in_one_line(make):
    """A name of another parameter, or a value out of range: ConfigError, nothing changed."""
    simulation, _ = build(make, scan_noise_std=0.01)
    with pytest.raises(ConfigError, match='^max_linear_velocity: not a noise parameter$'):
        simulation.restart_noise(1, max_linear_velocity=3.0)
    with pytest.raises(ConfigError, match='scan_noise_std'):
        simulation.restart_noise(1, scan_noise_std=-1.0)
    with pytest.raises(ConfigError, match='noise_seed'):
        simulation.restart_noise(-5)
    assert simulation.robot.config.scan_noise_std_m == 0.01
