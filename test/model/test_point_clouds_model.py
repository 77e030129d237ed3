"""
Point cloud math: a depth image's organised cloud, a multi-ring lidar's beams and ranges.

Pure math against hand-computable geometry: a flat depth gives points on a
plane through each pixel's centre ray; the lidar's rings are numbered from
the lowest, its beams go round from behind, and beams that measured nothing
are NaN.
"""

import math

import numpy
import pytest

from r2d2_sim.model import camera
from r2d2_sim.model.noise import NoiseModel, NoiseSpec
from r2d2_sim.model.sensors import (
    lidar_directions, lidar_ranges, LidarGeometry, SensorConfigError)


def test_a_flat_depth_gives_points_along_each_pixels_ray():
    """4 x 2 pixels, fx = fy = 2, principal point (2, 1): x = (u - 2) / 2 * z, as ROS projects."""
    k = camera.CameraIntrinsics(4, 2, 2.0, 2.0, 2.0, 1.0)
    depth = numpy.full((2, 4), 3.0, dtype=numpy.float32)
    points = camera.depth_points(depth, camera.pixel_rays(k))
    assert points.shape == (2, 4, 3) and points.dtype == numpy.float32
    assert points[0, 0].tolist() == pytest.approx([(0 - 2) / 2 * 3, (0 - 1) / 2 * 3, 3.0])
    assert points[1, 3].tolist() == pytest.approx([(3 - 2) / 2 * 3, (1 - 1) / 2 * 3, 3.0])
    assert numpy.all(points[..., 2] == 3.0)


def test_pixels_without_a_finite_depth_are_nan_points():
    k = camera.intrinsics(3, 1, 60.0)
    depth = numpy.array([[math.inf, -math.inf, math.nan]], dtype=numpy.float32)
    assert numpy.isnan(camera.depth_points(depth, camera.pixel_rays(k))).all()


def test_a_point_projects_back_onto_its_pixel():
    """The cloud and CameraInfo's K describe one camera: K x / z lands on (u, v)."""
    k = camera.image_intrinsics(320, 240, 60.0)
    depth = numpy.random.default_rng(1).uniform(0.5, 5.0, (240, 320)).astype(numpy.float32)
    points = camera.depth_points(depth, camera.pixel_rays(k)).astype(float)
    u = k.fx * points[..., 0] / points[..., 2] + k.cx
    v = k.fy * points[..., 1] / points[..., 2] + k.cy
    assert numpy.allclose(u, numpy.arange(320), atol=1e-3)
    assert numpy.allclose(v, numpy.arange(240)[:, None], atol=1e-3)


def lidar(rings=4, samples=8, low=-0.3, high=0.3, range_min=0.5, range_max=10.0):
    return LidarGeometry(rings, low, high, samples, range_min, range_max)


def test_rings_go_from_the_lowest_up_and_beams_round_from_behind():
    directions = lidar_directions(lidar())
    assert directions.shape == (4, 8, 3)
    assert numpy.allclose(numpy.linalg.norm(directions, axis=-1), 1.0)
    elevations = numpy.arcsin(directions[:, 0, 2])
    assert elevations == pytest.approx([-0.3, -0.1, 0.1, 0.3])
    azimuths = numpy.arctan2(directions[1, :, 1], directions[1, :, 0])
    assert azimuths[1:] == pytest.approx(-math.pi + math.pi / 4 * numpy.arange(1, 8))
    assert directions[0, 4, :2] == pytest.approx([math.cos(-0.3), 0.0])  # azimuth 0: ahead


def test_lidar_ranges_are_nan_without_a_return_or_too_close():
    geometry = lidar(rings=1, samples=4, low=0.0, high=0.0)
    ranges = lidar_ranges([0.5, 1.0, 0.01, 0.2], geometry)
    assert ranges.shape == (1, 4)
    assert ranges[0, 0] == 5.0 and ranges[0, 3] == 2.0
    assert math.isnan(ranges[0, 1]) and math.isnan(ranges[0, 2])


def test_lidar_noise_is_added_rounded_and_clipped_into_the_range():
    geometry = lidar(rings=100, samples=100)
    noise = NoiseModel(NoiseSpec(stddev=0.05, bias_mean=0.1, precision=0.01),
                       numpy.random.default_rng(3))
    ranges = lidar_ranges(numpy.full(10_000, 0.5), geometry, noise)
    errors = ranges.ravel() - 5.0
    assert errors.mean() == pytest.approx(noise.bias[0], abs=0.002)
    assert errors.std() == pytest.approx(0.05, rel=0.03)
    assert numpy.allclose(ranges, numpy.round(ranges / 0.01) * 0.01)
    edge = lidar_ranges(numpy.full(10_000, 0.99999), geometry, noise)
    assert numpy.nanmax(edge) <= 10.0 and not numpy.isnan(edge).any()


@pytest.mark.parametrize('kwargs, message', [
    ({'rings': 0}, 'rings must be an integer >= 1'),
    ({'samples': 2.5}, 'samples must be an integer'),
    ({'low': -2.0}, 'angle_min_rad must be a finite number >= '),
    ({'high': 1.7}, 'angle_max_rad must be at most pi/2'),
    ({'low': 0.2, 'high': 0.2}, 'several rings need'),
    ({'range_min': 20.0}, 'range_max_m must be'),
])
def test_bad_lidar_geometry_is_refused_in_one_line(kwargs, message):
    with pytest.raises(SensorConfigError, match=message):
        lidar(**kwargs)
