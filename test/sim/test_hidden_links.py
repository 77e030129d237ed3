"""
A robot alone with rays hides its own links from every ray: the same scans, no test of them.

PyBullet drops a robot's hits on its own links after testing each of them
(R2D2's laser sits inside its body: two thirds of a scan in an empty
world). A link whose collision mask lacks the rays' group (1) is never
tested, by any ray; so while a robot is the only one casting rays, its own
links in its laser's plane are hidden so (``SimWorld.exclude_from_rays``).
Every scan must be what it was, bit for bit, and every other ray must still
see the robot: a second robot with a laser, and a cast of the world's
(``SimWorld.cast_rays``) whose mask takes the robot's group.
"""

import math

import numpy

from r2d2_sim.physics.raycast import RAY_MASK
from r2d2_sim.sim.simulation import SpawnRequest

ROOM = 'package://r2d2_sim/urdf/room.urdf'
R2D2 = 'package://r2d2_sim/urdf/r2d2.urdf'
SIMULATION_DEFAULTS = {'cmd_vel_timeout': 0.0, 'scan_rate': 10.0}


def scan_steps(simulation, count, command=(0.4, 0.6)):
    """Drive; return each robot's scans of the next ``count`` scan steps, and its last pose."""
    for robot in simulation.robots:
        robot.command(*command)
    scans = []
    while len(scans) < count:
        result = simulation.step()
        if result is not None and result.measurements[0] is not None \
                and result.measurements[0].scan is not None:
            scans.append([m.scan.tobytes() for m in result.measurements])
    return scans, [robot.body.world_state() for robot in simulation.robots]


def ahead(robot, scan):
    """Return the range of the robot's beam nearest straight ahead in a scan's bytes."""
    beam = int(numpy.argmin(numpy.abs(robot.laser.geometry.angles_rad)))
    return numpy.frombuffer(scan, dtype=numpy.float32)[beam]


def test_a_lone_robot_hides_its_own_links_and_scans_as_before(make):
    """Hidden against shown (a cast that sees the group shows them): every scan and pose alike."""
    hidden, shown = make(world=ROOM), make(world=ROOM)
    robot = hidden.robot
    assert robot.body.hidden_ray_groups == robot.ray_group == 4
    assert robot.laser.excluded_links  # its base and legs cross the scan plane
    # A ray that may hit the robot's group sees it: its links are shown first.
    laser_z = robot.laser.rays().starts[0][2]
    start, end = numpy.array([[1.0, 0.0, laser_z]]), numpy.array([[-1.0, 0.0, laser_z]])
    seen = shown.world.cast_rays(start, end, mask=-1)
    assert shown.robot.body.hidden_ray_groups == 0
    assert 0.25 < seen[0] < 0.5  # R2D2's body, 0.5-1 m from the start
    assert hidden.world.cast_rays(start, end, mask=RAY_MASK)[0] == 1.0  # through it, as before
    assert robot.body.hidden_ray_groups == 4  # that cast could not see it: still hidden
    assert scan_steps(hidden, 12) == scan_steps(shown, 12)


def test_robots_that_start_together_hide_nothing_and_see_each_other(make):
    """Two robots with lasers 1.5 m apart, facing each other: each scan ahead meets the other."""
    simulation = make(robots=['a', 'b'], **{'b.initial_pose': [1.5, 0.0, math.pi]})
    assert [r.body.hidden_ray_groups for r in simulation.robots] == [0, 0]
    scans, _ = scan_steps(simulation, 1, command=(0.0, 0.0))
    for robot, scan in zip(simulation.robots, scans[0]):
        assert ahead(robot, scan) < 1.5, robot.name  # the other robot's body: nothing else


def test_a_second_robot_spawned_sees_the_first(make):
    """The first robot's hidden links are shown before the second robot's rays are cast."""
    simulation = make()
    first = simulation.robot
    assert first.body.hidden_ray_groups == 4
    simulation.spawn(SpawnRequest('c', uri=R2D2, namespace='c', position=(1.5, 0.0, 0.48),
                                  orientation=(0.0, 0.0, 1.0, 0.0)))  # base yaw pi: faces -x
    assert [r.body.hidden_ray_groups for r in simulation.robots] == [0, 0]
    scans, _ = scan_steps(simulation, 1, command=(0.0, 0.0))
    for robot, scan in zip(simulation.robots, scans[0]):
        assert ahead(robot, scan) < 1.5, robot.name


def test_a_deleted_second_robot_leaves_the_first_shown_and_a_reset_repeats_the_run(make):
    """Shown stays shown (hiding again would move it in Bullet's order); runs still repeat."""
    simulation = make(world=ROOM)
    simulation.spawn(SpawnRequest('c', uri=R2D2, namespace='c', position=(1.5, 0.0, 0.48)))
    simulation.delete_entity('c')
    assert simulation.robot.body.hidden_ray_groups == 0
    first = scan_steps(simulation, 6)
    simulation.reset(state=True)
    assert scan_steps(simulation, 6) == first
