"""
Pinhole camera math for the head camera: intrinsics, OpenGL matrices, depth to points.

No ROS and no PyBullet here (numpy for the point cloud). The matrices are
column-major 4x4 lists, the layout ``getCameraImage`` takes (and ``computeViewMatrix`` /
``computeProjectionMatrixFOV`` return); the intrinsics are those a ROS
``CameraInfo`` carries for the same image, so both describe one camera.
"""

from dataclasses import dataclass
import math
from typing import List, Sequence, Tuple

import numpy

from r2d2_sim.model.transforms import Quaternion, rotate

Vec3 = Tuple[float, float, float]


@dataclass(frozen=True)
class CameraIntrinsics:
    """Image size and pinhole parameters in pixels (square pixels, no distortion)."""

    width_px: int
    height_px: int
    fx: float
    fy: float
    cx: float
    cy: float

    @property
    def k(self) -> List[float]:
        """Return the row-major 3x3 camera matrix K."""
        return [self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0]

    @property
    def p(self) -> List[float]:
        """Return the row-major 3x4 projection matrix P of a monocular camera."""
        return [self.fx, 0.0, self.cx, 0.0, 0.0, self.fy, self.cy, 0.0, 0.0, 0.0, 1.0, 0.0]


IDENTITY_3X3 = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]

# Where PyBullet's ER_TINY_RENDERER samples pixel (u, v) of the image it returns
# (top row first), in the frustum's continuous coordinates (top-left corner 0,
# pixels 1 wide): at (u + 0, v + 1), OpenGL's integer pixel coordinates with
# the rows flipped. Measured: a depth image's cloud built on pixel centres
# (u + 0.5, v + 0.5) lies 0.5-3 cm off the room's walls, boxes and floor; built
# on these samples, within 0.1 mm (test/sim/test_camera_info_samples.py).
TINY_RENDERER_SAMPLE_PX = (0.0, 1.0)


def intrinsics(width_px: int, height_px: int, vertical_fov_deg: float) -> CameraIntrinsics:
    """
    Return the intrinsics of an ideal camera with the given vertical field of view.

    fy = (h / 2) / tan(fov / 2); fx = fy (square pixels); the principal point
    is the image centre, as OpenGL's symmetric frustum has it.
    """
    if not 0.0 < vertical_fov_deg < 180.0:
        raise ValueError(f'vertical field of view must be in (0, 180) degrees, '
                         f'got {vertical_fov_deg}')
    fy = (height_px / 2.0) / math.tan(math.radians(vertical_fov_deg) / 2.0)
    return CameraIntrinsics(width_px=width_px, height_px=height_px, fx=fy, fy=fy,
                            cx=width_px / 2.0, cy=height_px / 2.0)


def image_intrinsics(width_px: int, height_px: int, vertical_fov_deg: float
                     ) -> CameraIntrinsics:
    """
    Return the intrinsics of the images ER_TINY_RENDERER renders, in ROS's pixel convention.

    ROS (CameraInfo, image_geometry, depth_image_proc) puts pixel (u, v)'s
    ray at (u - cx) / fx, (v - cy) / fy; the renderer samples that pixel
    :data:`TINY_RENDERER_SAMPLE_PX` from the corner, so the principal point
    is the frustum's centre less that: (w / 2, h / 2 - 1).
    """
    k = intrinsics(width_px, height_px, vertical_fov_deg)
    du, dv = TINY_RENDERER_SAMPLE_PX
    return CameraIntrinsics(width_px=k.width_px, height_px=k.height_px, fx=k.fx, fy=k.fy,
                            cx=k.cx - du, cy=k.cy - dv)


def projection_matrix(width_px: int, height_px: int, vertical_fov_deg: float,
                      near_m: float, far_m: float) -> List[float]:
    """Return the OpenGL perspective projection (column-major), as gluPerspective."""
    y_scale = 1.0 / math.tan(math.radians(vertical_fov_deg) / 2.0)
    x_scale = y_scale * height_px / width_px
    depth = near_m - far_m
    return [x_scale, 0.0, 0.0, 0.0,
            0.0, y_scale, 0.0, 0.0,
            0.0, 0.0, (far_m + near_m) / depth, -1.0,
            0.0, 0.0, 2.0 * far_m * near_m / depth, 0.0]


def _normalized(v: Sequence[float]) -> Vec3:
    norm = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if norm == 0.0:
        raise ValueError('cannot normalise a zero vector')
    return (v[0] / norm, v[1] / norm, v[2] / norm)


def _cross(a: Sequence[float], b: Sequence[float]) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a: Sequence[float], b: Sequence[float]) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def view_matrix(eye: Sequence[float], forward: Sequence[float],
                up: Sequence[float]) -> List[float]:
    """Return the OpenGL view matrix (column-major) of a camera at ``eye``, as gluLookAt."""
    f = _normalized(forward)
    s = _normalized(_cross(f, up))
    u = _cross(s, f)
    return [s[0], u[0], -f[0], 0.0,
            s[1], u[1], -f[1], 0.0,
            s[2], u[2], -f[2], 0.0,
            -_dot(s, eye), -_dot(u, eye), _dot(f, eye), 1.0]


def link_camera_axes(link_orientation: Quaternion,
                     yaw_offset_rad: float) -> Tuple[Vec3, Vec3]:
    """
    Return the world (forward, up) directions of a camera fixed to a link.

    The camera looks along the link's x axis turned by ``yaw_offset_rad``
    about its z (the REP-103 forward of a robot whose URDF is not x-forward)
    and keeps the link's z axis up.
    """
    forward_in_link = (math.cos(yaw_offset_rad), math.sin(yaw_offset_rad), 0.0)
    return (rotate(link_orientation, forward_in_link),
            rotate(link_orientation, (0.0, 0.0, 1.0)))


def pixel_rays(k: CameraIntrinsics) -> Tuple[numpy.ndarray, numpy.ndarray]:
    """
    Return each pixel's (x / z, y / z) in the optical frame, shaped (height, width), float64.

    ``k`` in ROS's convention, as CameraInfo carries it (:func:`image_intrinsics`):
    x / z = (u - cx) / fx, y / z = (v - cy) / fy (x right, y down, z forward),
    as depth_image_proc projects a depth image.
    """
    u = (numpy.arange(k.width_px) - k.cx) / k.fx
    v = (numpy.arange(k.height_px) - k.cy) / k.fy
    return numpy.broadcast_to(u, (k.height_px, k.width_px)), \
        numpy.broadcast_to(v[:, None], (k.height_px, k.width_px))


def depth_points(depth_m: numpy.ndarray, rays: Tuple[numpy.ndarray, numpy.ndarray]
                 ) -> numpy.ndarray:
    """
    Return the organised point cloud of a REP-118 depth image: (height, width, 3) float32.

    Each pixel's point is its depth along the optical axis times its ray
    (:func:`pixel_rays`), in the optical frame. A pixel without a finite
    depth (+inf: nothing within range, -inf: too close, NaN) is a point of
    NaNs, as depth_image_proc makes it, so the cloud keeps its rows and
    columns.
    """
    z = numpy.asarray(depth_m, dtype=numpy.float64)
    z = numpy.where(numpy.isfinite(z), z, numpy.nan)
    x_over_z, y_over_z = rays
    return numpy.stack([x_over_z * z, y_over_z * z, z], axis=-1).astype(numpy.float32)
