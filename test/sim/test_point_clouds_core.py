"""
Point clouds against analytic geometry: the depth camera's wall and floor, the 3D lidar's box.

No ROS. The head camera's cloud, taken to the world through the head's pose
and the optical mount, puts the room's +x wall (its face at x = 2 m) at
2 m and the floor at z = 0, each within a centimetre; the 3D lidar on top
of R2D2 puts every ring's beams that meet a 1 m cube on the cube's face
where the beam's elevation and azimuth say, within a centimetre, and
beams that pass over it measure nothing.
"""

import math

import numpy
import pytest

from common import distance_to_the_room, ROOM
from r2d2_sim.model import camera
from r2d2_sim.model.transforms import apply, compose, rotate, Transform

CM = 0.01


def camera_cloud_in_world(simulation):
    """Return the head camera's cloud as world points, (height * width, 3)."""
    robot = simulation.robot
    head = robot.camera
    _, depth = head.render(depth=True)
    points = camera.depth_points(depth, camera.pixel_rays(head.intrinsics)).reshape(-1, 3)
    position, orientation = robot.body.link_pose(robot.body.link_index(head.link_name))
    optical = compose(Transform(position, orientation), head.optical_mount)
    finite = numpy.isfinite(points).all(axis=1)
    world = numpy.array([apply(optical, p) for p in points[finite].astype(float)])
    return world, finite.sum(), len(points)


def beyond_the_robot(world):
    """Return the points beyond R2D2's own gripper, which reaches into the view."""
    return world[numpy.hypot(world[:, 0], world[:, 1]) > 0.6]


def test_the_depth_cloud_puts_the_wall_and_the_floor_where_they_are(make):
    """Every point within a centimetre of the room: the +x wall's face at 2 m, the floor."""
    simulation = make(world=ROOM, camera_rate=10.0, camera_point_cloud=True, camera_width=160,
                      camera_height=120)
    world, finite, total = camera_cloud_in_world(simulation)
    assert 0 < finite < total  # the room has no ceiling: the top rows see nothing
    world = beyond_the_robot(world)
    on_wall, on_floor = numpy.abs(world[:, 0] - 2.0) < CM, numpy.abs(world[:, 2]) < CM
    assert (on_wall | on_floor).all()  # nothing else is in view
    wall, floor = world[on_wall], world[on_floor]
    assert len(wall) > 1000 and len(floor) > 100
    assert wall[:, 2].max() == pytest.approx(1.0, abs=2 * CM)  # up to the wall's top edge


def test_the_self_filter_leaves_the_robots_own_pixels_without_depth(make):
    """camera_self_filter: the gripper's pixels (4.7 % of the view) read NaN, the rest alike."""
    parameters = {'world': ROOM, 'camera_rate': 10.0, 'camera_point_cloud': True}
    seen = make(**parameters).robot.camera.render(depth=True).depth
    filtered = make(camera_self_filter=True, **parameters)
    depth = filtered.robot.camera.render(depth=True).depth
    own = numpy.isnan(depth)
    assert own.mean() == pytest.approx(0.047, abs=0.002)
    assert numpy.isfinite(seen[own]).all()  # the gripper was in view, near
    assert (depth[~own] == seen[~own]).all()
    world, _, _ = camera_cloud_in_world(filtered)
    assert ((numpy.abs(world[:, 0] - 2.0) < CM) | (numpy.abs(world[:, 2]) < CM)).all()


def test_the_depth_cloud_follows_the_head_as_it_turns(make):
    """Head turned 0.3 rad: every point still on the room (a box now in view), to the left."""
    simulation = make(world=ROOM, camera_rate=10.0, camera_point_cloud=True, camera_width=96,
                      camera_height=72)
    body = simulation.robot.body
    body._client.resetJointState(body.id, body.joint('head_swivel').index, 0.3)
    world = beyond_the_robot(camera_cloud_in_world(simulation)[0])
    assert distance_to_the_room(world).max() < CM
    assert world[:, 1].mean() > 0.3


BOX_X = 3.0  # a 1 m cube: its near face at x = 2.5, sides at y = +-0.5, top at z = 1


def test_the_lidar_rings_hit_a_known_box_where_geometry_says(make):
    """16 rings of 1800 beams (two ray batches): each beam that meets the face, on it."""
    simulation = make(lidar3d_rate=10.0, lidar3d_rings=16, lidar3d_samples=1800,
                      extra_models=[f'cube.urdf {BOX_X} 0 0.5'])
    robot = simulation.robot
    lidar = robot.lidar
    points = lidar.scan().astype(float)
    geometry = lidar.geometry
    assert points.shape == (16, 1800, 3)
    base = robot.body.world_state()
    origin = apply(Transform(base.position, base.orientation), lidar.mount.translation)
    face = 2.5 - origin[0]  # horizontal distance from the lidar to the face, straight ahead
    checked = 0
    for ring, elevation in enumerate(geometry.elevations_rad):
        for beam, azimuth in enumerate(geometry.azimuths_rad):
            if abs(azimuth) > 0.5:
                continue
            y = face * math.tan(azimuth)
            along = face / math.cos(azimuth)
            z = origin[2] + along * math.tan(elevation)
            measured = points[ring, beam]
            if abs(y) < 0.49 and 0.01 < z < 0.99:
                world = numpy.array(origin) + rotate(base.orientation, measured)
                assert world == pytest.approx([2.5, y + origin[1], z], abs=CM), (ring, beam)
                checked += 1
            elif abs(y) < 0.49 and z > 1.01:  # over the cube, and then nothing at all
                assert numpy.isnan(measured).all(), (ring, beam)
    # About 111 beams a ring meet the face ahead; the 8 rings below the horizon do.
    assert checked > 8 * 100


def test_the_lidar_sees_through_its_own_robot_and_not_through_others(make):
    """Two robots 1.5 m apart: each sees the other, neither sees itself."""
    simulation = make(robots=['a', 'b'], lidar3d_rate=10.0, lidar3d_rings=8,
                      lidar3d_samples=360, **{'b.initial_pose': [1.5, 0.0, 0.0]})
    a, b = simulation.robots
    for robot in (a, b):
        points = robot.lidar.scan()
        distances = numpy.linalg.norm(points.astype(float), axis=-1)
        assert numpy.nanmin(distances) > 0.5  # nothing of its own
    ahead = a.lidar.scan()[:, 180]  # azimuth 0: towards b
    assert numpy.nanmin(numpy.linalg.norm(ahead.astype(float), axis=-1)) < 1.5


def test_the_lidar_mount_is_on_top_of_the_robot_unless_set(make):
    robot = make(lidar3d_rate=10.0).robot
    top = robot.body.bounding_box().high[2]
    assert robot.lidar.height_m == pytest.approx(top + 0.05, abs=1e-3)
    assert make(lidar3d_rate=10.0, lidar3d_height=1.5).robot.lidar.height_m == 1.5
