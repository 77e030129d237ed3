"""
The head camera's pinhole math, by hand.

The same math is checked against PyBullet's own matrix helpers in
physics/test_camera_physics.py, its parameters in sim/test_camera_sim.py, and
the images and CameraInfo of the node in ros/test_camera_ros.py.
"""

import math

import numpy
import pytest

from r2d2_sim.model import camera


def test_intrinsics_of_a_60_degree_320x240_camera():
    """Focal length fy = 120 / tan(30 deg) = 207.85 px; fx = fy; principal point centred."""
    k = camera.intrinsics(320, 240, 60.0)
    assert k.fy == pytest.approx(120.0 / math.tan(math.radians(30.0)))
    assert k.fy == pytest.approx(207.846, abs=1e-3)
    assert (k.fx, k.cx, k.cy) == (k.fy, 160.0, 120.0)
    assert k.k == [k.fx, 0.0, 160.0, 0.0, k.fy, 120.0, 0.0, 0.0, 1.0]
    assert k.p == [k.fx, 0.0, 160.0, 0.0, 0.0, k.fy, 120.0, 0.0, 0.0, 0.0, 1.0, 0.0]


@pytest.mark.parametrize('fov', [0.0, 180.0, -10.0])
def test_impossible_field_of_view_is_refused(fov):
    """A field of view outside (0, 180) degrees is a ValueError."""
    with pytest.raises(ValueError, match='field of view'):
        camera.intrinsics(320, 240, fov)


def test_projection_and_intrinsics_put_a_point_on_the_same_pixel():
    """A point 2 m ahead, 0.3 m left, 0.2 m up lands where K says (u right, v down)."""
    width, height, fov = 320, 240, 60.0
    k = camera.intrinsics(width, height, fov)
    view = numpy.array(camera.view_matrix((0.0, 0.0, 0.0), (1.0, 0.0, 0.0),
                                          (0.0, 0.0, 1.0))).reshape(4, 4).T
    projection = numpy.array(camera.projection_matrix(width, height, fov, 0.01, 100.0)
                             ).reshape(4, 4).T
    clip = projection @ view @ numpy.array([2.0, 0.3, 0.2, 1.0])
    ndc = clip[:3] / clip[3]
    u_gl, v_gl = (ndc[0] + 1.0) * width / 2.0, (1.0 - ndc[1]) * height / 2.0
    # Optical frame: z forward, x right, y down -> (-0.3, -0.2, 2.0).
    u_k, v_k = k.fx * -0.3 / 2.0 + k.cx, k.fy * -0.2 / 2.0 + k.cy
    assert (u_gl, v_gl) == pytest.approx((u_k, v_k), abs=1e-6)


def test_camera_axes_follow_the_link_and_the_yaw_offset():
    """A link yawed 90 degrees looks along world +y; with offset +90 along -x."""
    q = (0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4))
    forward, up = camera.link_camera_axes(q, 0.0)
    assert forward == pytest.approx((0.0, 1.0, 0.0), abs=1e-12)
    assert up == pytest.approx((0.0, 0.0, 1.0), abs=1e-12)
    forward, _ = camera.link_camera_axes(q, math.pi / 2)
    assert forward == pytest.approx((-1.0, 0.0, 0.0), abs=1e-12)
