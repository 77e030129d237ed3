"""
A body whose URDF sets its own collision group can be invisible to a robot's rays: said once.

No ROS. Each robot's laser and 3D lidar pass through a collision group of the
robot's own (4, 8, ... 2^30). A wall whose URDF puts its link in that group
alone (``<collision group="4">``) is passed through by the robot's rays while
the robot collides with it; one whose mask leaves out group 1, which PyBullet
casts every ray in, is never tested. Either is said in one warning line, when
the body comes in or when a robot takes the group it hides in, once.
"""

import numpy
import pytest

from r2d2_sim.sim.simulation import SpawnRequest

R2D2 = 'package://r2d2_sim/urdf/r2d2.urdf'
SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'imu_rate': 0.0, 'scan_rate': 10.0}
HIDDEN = ("wall is invisible to robot r2d2's laser and 3D lidar, though the robot collides with "
          "it: its URDF puts link base in collision group 4, the one those rays pass through (a "
          "group with another bit, such as 1, is seen)")


def wall(filters):
    """Return a fixed wall 2 m wide whose <collision> has the attributes ``filters``."""
    return (f'<robot name="wall"><link name="base"><inertial><mass value="0"/><inertia ixx="0" '
            'ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>'
            f'<collision {filters}><geometry><box size="0.1 2 1"/></geometry></collision>'
            '</link></robot>')


def range_ahead(simulation):
    """Return the range of the robot's beam nearest straight ahead in its next scan."""
    robot = simulation.robot
    beam = int(numpy.argmin(numpy.abs(robot.laser.geometry.angles_rad)))
    while True:
        result = simulation.step()
        if result is not None and result.measurements[0].scan is not None:
            return float(result.measurements[0].scan[beam])


@pytest.mark.parametrize('filters, seen', [
    ('group="4" mask="-1"', False), ('group="1" mask="-1"', True), ('group="12"', True),
    ('group="4.7"', False),  # PyBullet reads it with C's atof, as 4
])
def test_a_start_up_wall_in_the_robots_ray_group_is_said_to_be_invisible(
        make, tmp_path, filters, seen):
    """1 m ahead: seen at 0.95 m without a word, or not seen and said once."""
    path = tmp_path / 'wall.urdf'
    path.write_text(wall(filters))
    warnings = []
    simulation = make(warnings=warnings, extra_models=[f'{path} 1.0 0.0 0.5'])
    assert simulation.robot.ray_group == 4
    if seen:
        assert warnings == [] and range_ahead(simulation) == pytest.approx(0.95, abs=0.01)
    else:
        assert warnings == [HIDDEN] and range_ahead(simulation) == float('inf')
    simulation.reset(time=True, state=True, spawned=True)
    assert len(warnings) == (0 if seen else 1)  # once


def test_a_spawned_wall_and_a_robot_taking_its_group_are_said_to_hide_it(make):
    """A wall in group 8 is seen by the first robot, not by a second one (group 8)."""
    warnings = []
    simulation = make(warnings=warnings)
    simulation.spawn(SpawnRequest('wall', resource_string=wall('group="8"'),
                                  position=(1.0, 0.0, 0.5)))
    assert warnings == []
    simulation.spawn(SpawnRequest('second', uri=R2D2, namespace='second',
                                  position=(-2.0, 0.0, 0.48)))
    assert simulation.robots[1].ray_group == 8
    assert warnings == [HIDDEN.replace("r2d2's", "second's").replace('group 4', 'group 8')]
    simulation.spawn(SpawnRequest('ghost', resource_string=wall('mask="2"').replace(
        '"wall"', '"ghost"'), position=(0.0, 3.0, 0.5)))
    assert warnings[1:] == [
        f"ghost is invisible to robot {name}'s laser and 3D lidar, though the robot collides "
        "with it: its URDF gives link base the collision mask 2, without group 1, which rays "
        "are cast in" for name in ('r2d2', 'second')]
