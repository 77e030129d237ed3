"""
The demo's pictures: odometry against ground truth with the last laser scan, and a camera snapshot.

Plain matplotlib ``Figure`` objects on an Agg canvas (no pyplot): they need no
display and leave matplotlib's global backend alone. matplotlib is imported
only when a picture is drawn.
"""

import math
import os
from pathlib import Path
from typing import Any, List, Sequence, Tuple, TYPE_CHECKING, Union

from r2d2_sim.client import Pose2D

if TYPE_CHECKING:  # matplotlib is imported only when a picture is drawn
    from matplotlib.figure import Figure

__all__ = ['scan_points_xy', 'write_trajectory_plot', 'write_camera_snapshot']

Point = Tuple[float, float]


def scan_points_xy(scan: Any, pose: Pose2D, laser_offset_xy: Point = (0.0, 0.0)
                   ) -> List[Point]:
    """
    Return a LaserScan's finite returns as world x-y points, seen from ``pose`` (the base's).

    ``laser_offset_xy`` is the laser's position in the base frame. Readings
    of +-inf (REP-117: no return, too close) have no point.
    """
    cos_yaw, sin_yaw = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    origin_x = pose.x_m + cos_yaw * laser_offset_xy[0] - sin_yaw * laser_offset_xy[1]
    origin_y = pose.y_m + sin_yaw * laser_offset_xy[0] + cos_yaw * laser_offset_xy[1]
    points = []
    for i, r in enumerate(scan.ranges):
        if math.isfinite(r):
            angle = pose.yaw_rad + scan.angle_min + i * scan.angle_increment
            points.append((origin_x + r * math.cos(angle), origin_y + r * math.sin(angle)))
    return points


def _figure(**kwargs: Any) -> 'Figure':
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    figure = Figure(**kwargs)
    FigureCanvasAgg(figure)
    return figure


def write_trajectory_plot(path: Union[str, os.PathLike[str]], odom_xy: Sequence[Point],
                          truth_xy: Sequence[Point], scan_xy: Sequence[Point] = ()) -> Path:
    """
    Plot odometry against ground truth in the x-y plane as a PNG; return its path.

    ``scan_xy`` (the last laser scan, in the world frame) is drawn as dots.
    """
    path = Path(path)
    figure = _figure(figsize=(6.4, 7.0), dpi=100, layout='constrained')
    axes = figure.add_subplot()
    if scan_xy:
        axes.plot([p[0] for p in scan_xy], [p[1] for p in scan_xy], '.', color='tab:green',
                  markersize=3, label='last laser scan')
    for points, label, style, colour in ((truth_xy, 'ground truth (world)', '-', 'tab:blue'),
                                         (odom_xy, 'wheel odometry (odom)', '--', 'tab:orange')):
        if not points:
            continue
        xs = [p[0] for p in points]
        ys = [p[1] for p in points]
        axes.plot(xs, ys, style, color=colour, linewidth=2, label=label)
        axes.plot(xs[:1], ys[:1], 'o', color=colour, markersize=8)
        axes.plot(xs[-1:], ys[-1:], 's', color=colour, markersize=8)
    # Marker legend entries, drawn off-data so they only label the symbols.
    axes.plot([], [], 'o', color='grey', label='start')
    axes.plot([], [], 's', color='grey', label='end')
    axes.set_aspect('equal', adjustable='datalim')
    axes.set_xlabel('x (m)')
    axes.set_ylabel('y (m)')
    axes.set_title('R2D2 demo in the room: wheel odometry vs ground truth')
    axes.grid(True, alpha=0.4)
    axes.legend(loc='upper center', bbox_to_anchor=(0.5, -0.1), ncols=2)
    figure.savefig(path, format='png')
    return path


def write_camera_snapshot(path: Union[str, os.PathLike[str]], image: Any) -> Path:
    """Write an rgb8 ``sensor_msgs/Image`` as a PNG of its own size and return its path."""
    from matplotlib.image import imsave  # draws on its own Agg Figure, no pyplot
    import numpy
    if image.encoding != 'rgb8':
        raise ValueError(f'expected an rgb8 image, got {image.encoding!r}')
    rows = numpy.frombuffer(bytes(image.data), dtype=numpy.uint8)
    pixels = rows.reshape(image.height, image.step)[:, :image.width * 3]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    imsave(path, pixels.reshape(image.height, image.width, 3), format='png')
    return path
