"""
The core's entities against the standard's text, without ROS: frames of twists, names, filters.

Hand-computable cases: a robot turned 90 degrees, a box thrown in free fall,
names and filters a peer could send.
"""

import math
import subprocess
import sys

import pytest

from r2d2_sim.errors import RefusedError
from r2d2_sim.sim.entities import MAX_FILTER_LENGTH, MAX_NAME_LENGTH, name_filter
from r2d2_sim.sim.simulation import SpawnRequest

BOX = ('<robot name="box"><link name="box"><inertial><mass value="1"/><inertia ixx="0.01" '
       'iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial><collision><geometry>'
       '<box size="0.2 0.2 0.2"/></geometry></collision></link></robot>')


SIMULATION_DEFAULTS = {'scan_rate': 0.0, 'imu_rate': 0.0}


def spawn_box(simulation, position, name='box'):
    """Spawn the 1 kg, 0.2 m box at ``position`` (its centre, world frame); return its name."""
    return simulation.spawn(SpawnRequest(name, resource_string=BOX, position=position))


def test_a_twist_in_an_entity_frame_is_turned_into_the_world(make):
    """EntityState: the twist is observed in header.frame_id; R2D2 faces +y, so its x is +y."""
    simulation = make(initial_pose=[0.0, 0.0, math.pi / 2])
    box = spawn_box(simulation, (3.0, 0.0, 5.0))
    simulation.set_entity_state(box, 'r2d2', (2.0, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0),
                                linear=(1.0, 0.0, 0.0), angular=(0.0, 0.5, 0.0))
    state = simulation.entities.state(box)
    base = simulation.entities.state('r2d2').position
    # Pose: 2 m along the robot's x (world +y) and 1 m up, turned 90 degrees with it.
    assert state.position == pytest.approx((base[0], base[1] + 2.0, base[2] + 1.0), abs=1e-5)
    assert state.linear_velocity == pytest.approx((0.0, 1.0, 0.0), abs=1e-6)
    assert state.angular_velocity == pytest.approx((-0.5, 0.0, 0.0), abs=1e-6)
    simulation.set_entity_state(box, '', (3.0, 0.0, 5.0), (0.0, 0.0, 0.0, 1.0),
                                linear=(1.0, 0.0, 0.0), angular=(0.0, 0.0, 0.0))
    velocity = simulation.entities.state(box).linear_velocity
    assert velocity == pytest.approx((1.0, 0.0, 0.0), abs=1e-6)


def test_a_spawned_body_keeps_its_speed_in_free_fall(make):
    """No Bullet damping on entities: thrown at 5 m/s, still 5 m/s after 1 s (Bullet: 3.69)."""
    simulation = make(ground_plane=False, extra_models=['cube_small.urdf 0 5 50'])
    box = spawn_box(simulation, (0.0, -5.0, 50.0))
    model = simulation.models[0]
    simulation.set_entity_state(box, '', (0.0, -5.0, 50.0), (0.0, 0.0, 0.0, 1.0),
                                linear=(5.0, 0.0, 0.0), angular=(0.0, 0.0, 0.0))
    model.set_base_state(linear_velocity=(5.0, 0.0, 0.0))
    for _ in range(240):
        simulation.step()
    for velocity in (simulation.entities.state(box).linear_velocity,
                     model.world_state().linear_velocity):
        assert velocity[0] == pytest.approx(5.0, abs=1e-6)
        assert velocity[2] == pytest.approx(-9.8, abs=1e-3)  # g for 1 s, undamped too


def test_a_spawn_into_a_robot_says_in_one_line_that_it_will_shove_it(make):
    """A box in R2D2's body, a robot in another: one warning each; a box beside it, none."""
    warnings = []
    simulation = make(warnings=warnings)
    spawn_box(simulation, (1.0, 0.0, 0.1), name='beside')  # on the floor, 1 m ahead
    assert warnings == []
    spawn_box(simulation, (0.0, 0.0, 0.5), name='inside')  # in the body
    simulation.spawn(SpawnRequest('c', uri='package://r2d2_sim/urdf/r2d2.urdf', namespace='c',
                                  position=(0.2, 0.0, 0.48)))
    assert len(warnings) == 2 and not any('\n' in line for line in warnings)
    assert warnings[0].startswith('inside overlaps robot r2d2 by ')
    assert warnings[1].startswith('c overlaps robot r2d2 by ')


def test_entity_names_are_bounded(make):
    """A 100,000-character name is refused; with renaming it is cut to a name that fits."""
    simulation = make()
    with pytest.raises(RefusedError) as refused:
        spawn_box(simulation, (1.0, 0.0, 0.1), name='b' * 100_000)
    assert refused.value.code == 'NAME_INVALID' and str(MAX_NAME_LENGTH) in str(refused.value)
    name = simulation.spawn(SpawnRequest('b' * 100_000, allow_renaming=True,
                                         resource_string=BOX, position=(1.0, 0.0, 0.1)))
    assert len(name) <= MAX_NAME_LENGTH and name.startswith('bbb')
    assert simulation.entities.names() == ['ground_plane', 'r2d2', name]


@pytest.mark.parametrize('position, orientation', [
    ((1.0, 0.0), (0.0, 0.0, 0.0, 1.0)), ((1.0, 0.0, 0.1, 0.0), (0.0, 0.0, 0.0, 1.0)),
    ((1.0, 0.0, 0.1), (0.0, 0.0, 1.0)), ((1.0, 0.0, 0.1), (0.0, 0.0, 0.0, 1.0, 0.0))])
def test_a_pose_of_the_wrong_length_is_refused_in_one_line(make, position, orientation):
    """A Python caller may give any sequence: 3 numbers and 4, or INVALID_POSE, nothing moved."""
    simulation = make()
    box = spawn_box(simulation, (1.0, 0.0, 0.1))
    before = simulation.entities.state(box)
    with pytest.raises(RefusedError, match='^INVALID_POSE'):
        simulation.set_entity_state(box, '', position, orientation, (0.0, 0.0, 0.0),
                                    (0.0, 0.0, 0.0))
    with pytest.raises(RefusedError, match='^INVALID_POSE'):
        simulation.spawn(SpawnRequest('other', resource_string=BOX, position=position,
                                      orientation=orientation))
    assert simulation.entities.state(box) == before
    assert simulation.entities.names() == ['ground_plane', 'r2d2', box]


@pytest.mark.parametrize('linear, angular', [((1e300, 0.0, 0.0), (0.0, 0.0, 0.0)),
                                             ((0.0, 0.0, 0.0), (0.0, 60.0, 0.0))])
def test_a_twist_no_body_survives_is_refused_in_one_line(make, linear, angular):
    """Finite but past what a robot's health check calls a blow-up: nothing moved, not NaN."""
    simulation = make()
    box = spawn_box(simulation, (1.0, 0.0, 0.1))
    before = simulation.entities.state(box)
    with pytest.raises(RefusedError, match=r'^INVALID_POSE.*is not below 50 m/s and 50 rad/s'):
        simulation.set_entity_state(box, '', (1.0, 0.0, 0.15), (0.0, 0.0, 0.0, 1.0),
                                    linear, angular)
    for _ in range(24):
        simulation.step()
    assert simulation.entities.state(box).position == pytest.approx(before.position, abs=1e-3)


def test_name_filters_search_a_part_of_the_name():
    """The standard's filter: a regular expression that matches a part of the name."""
    assert name_filter('')('anything')
    assert name_filter('r2d')('r2d2') and not name_filter('^2d')('r2d2')
    assert name_filter('^(box|cube)_[0-9]+$')('cube_12')
    assert not name_filter('^(box|cube)_[0-9]+$')('cube_12x')


@pytest.mark.parametrize('pattern, fragment', [
    ('(', 'bad filter regex: missing )'),
    ('a' * (MAX_FILTER_LENGTH + 1), f'longer than {MAX_FILTER_LENGTH}'),
])
def test_a_bad_filter_is_refused_in_one_line(pattern, fragment):
    """A pattern RE2 refuses, or one too long: OPERATION_FAILED naming why."""
    with pytest.raises(RefusedError) as refused:
        name_filter(pattern)
    assert refused.value.code == 'OPERATION_FAILED' and fragment in str(refused.value)
    assert '\n' not in str(refused.value)


def test_filters_that_backtrack_exponentially_elsewhere_end_at_once():
    """(a+)+c on 40 a's: about 2^40 steps for a backtracking engine, linear for RE2."""
    code = ('from r2d2_sim.sim.entities import name_filter\n'
            "print(name_filter('(a+)+c')('a' * 40), name_filter('(.*)' * 20 + 'Z')('x' * 5000))")
    # The deadline is for a stuck engine (hours), not a measure of speed.
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ['False', 'False']
