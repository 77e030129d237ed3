"""The testing API's scenery: fixed and pushable boxes, and a scan's range at an angle."""

import math

import pytest
from sensor_msgs.msg import LaserScan

from r2d2_sim.sim.entities import Category
from r2d2_sim.sim.settings.config import parse_config
from r2d2_sim.sim.simulation import Simulation, SpawnRequest
from r2d2_sim.testing import box_urdf, scan_range


@pytest.mark.parametrize('mass_kg, category', [(0.0, Category.STATIC_OBJECT),
                                               (2.0, Category.DYNAMIC_OBJECT)])
def test_a_massless_box_is_a_wall_a_heavy_one_is_pushed(mass_kg, category):
    """R2D2 drives 1.5 m/s into a 0.4 m box 1 m ahead: a wall stays put, a 2 kg box moves."""
    simulation = Simulation(parse_config({'scan_rate': 0.0, 'imu_rate': 0.0,
                                          'cmd_vel_timeout': 0.0}))
    try:
        name = simulation.spawn(SpawnRequest(
            'obstacle', resource_string=box_urdf((0.4, 1.0, 0.4), mass_kg=mass_kg),
            position=(1.0, 0.0, 0.2)))
        assert simulation.entities.category(name) == category
        simulation.robot.command(1.5, 0.0)
        for _ in range(3 * 240):
            simulation.step()
        box_x = simulation.entities.state(name).position[0]
        robot_x = simulation.entities.state('r2d2').position[0]
        if mass_kg:
            assert box_x > 1.2  # shoved along
        else:
            assert box_x == pytest.approx(1.0, abs=1e-9)
            assert robot_x < 1.0 - 0.2  # stopped at the wall's face
    finally:
        simulation.close()


def test_box_urdf_refuses_what_is_not_a_box():
    """Sizes and masses that make no solid: ValueError naming them."""
    with pytest.raises(ValueError, match='positive sizes'):
        box_urdf((1.0, 0.0, 1.0))
    with pytest.raises(ValueError, match='mass'):
        box_urdf(mass_kg=float('nan'))


def scan(angle_min, count, increment):
    """Return a LaserScan whose beam i has range i."""
    msg = LaserScan(angle_min=angle_min, angle_increment=increment,
                    angle_max=angle_min + (count - 1) * increment)
    msg.ranges = [float(i) for i in range(count)]
    return msg


def test_scan_range_finds_the_nearest_beam_the_long_way_round_too():
    """360 beams from -pi, 1 degree apart (the node's default): beam 180 looks ahead."""
    full = scan(-math.pi, 360, 2 * math.pi / 360)
    assert scan_range(full, 0.0) == 180.0
    assert scan_range(full, math.pi / 2) == 270.0  # left
    assert scan_range(full, -math.pi / 2) == 90.0
    assert scan_range(full, math.pi) == 0.0 and scan_range(full, -math.pi) == 0.0
    assert scan_range(full, math.radians(0.4)) == 180.0
    assert scan_range(full, math.radians(0.6)) == 181.0
    assert scan_range(full, 2 * math.pi) == 180.0  # one turn further
    assert scan_range(full, math.pi - math.radians(0.4)) == 0.0  # wraps to -pi


def test_scan_range_refuses_an_angle_a_partial_scan_does_not_cover():
    """A 90-degree scan ahead: 60 degrees to the side is not in it."""
    front = scan(-math.pi / 4, 91, math.radians(1.0))
    assert scan_range(front, math.pi / 4) == 90.0
    with pytest.raises(ValueError, match='covers'):
        scan_range(front, math.pi / 3)
