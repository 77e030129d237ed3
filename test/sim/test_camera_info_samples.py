"""
The head camera's CameraInfo says where each pixel looks, as ROS projects it.

depth_image_proc (and image_geometry) put pixel (u, v)'s ray at
((u - cx) / fx, (v - cy) / fy). PyBullet's ER_TINY_RENDERER samples pixel
(u, v) at u from the frustum's left edge and v + 1 from its top, so the
principal point is (w / 2, h / 2 - 1), not the frustum's centre (w / 2,
h / 2) that CameraInfo published before: with that, a cloud made from the
depth image and its CameraInfo lay 1-4 cm off the room's walls, boxes and
floor. Checked here by projecting every pixel as ROS does and measuring
each point's distance to the room's analytic surfaces.
"""

import numpy
import pytest

from common import distance_to_the_room, ROOM
from r2d2_sim.model.transforms import apply, compose, Transform


def projected_as_ros_does(simulation):
    """Return the depth image's points in the world, each pixel projected with CameraInfo's K."""
    robot = simulation.robot
    head = robot.camera
    _, depth = head.render(depth=True)
    k = head.intrinsics  # what CameraInfo publishes
    v, u = numpy.mgrid[0:k.height_px, 0:k.width_px]
    seen = numpy.isfinite(depth)
    z, u, v = depth[seen].astype(float), u[seen], v[seen]
    points = numpy.stack([(u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z], axis=-1)
    position, orientation = robot.body.link_pose(robot.body.link_index(head.link_name))
    optical = compose(Transform(position, orientation), head.optical_mount)
    world = numpy.array([apply(optical, p) for p in points])
    return world[numpy.hypot(world[:, 0], world[:, 1]) > 0.6]  # R2D2's own gripper left out


@pytest.mark.parametrize('size', [(160, 120), (64, 48)])
@pytest.mark.parametrize('yaw', [0.0, 0.6, -0.9, 2.5])
def test_camera_info_projects_every_pixel_onto_the_room(make, size, yaw):
    width, height = size
    simulation = make(world=ROOM, camera_rate=10.0, camera_depth=True, camera_width=width,
                      camera_height=height, initial_pose=[0.0, 0.0, yaw])
    k = simulation.robot.camera.intrinsics
    assert (k.cx, k.cy) == (width / 2.0, height / 2.0 - 1.0)
    distance = distance_to_the_room(projected_as_ros_does(simulation))
    assert len(distance) > width * height / 4
    assert numpy.percentile(distance, 99) < 1e-3
    assert numpy.median(distance) < 1e-4
