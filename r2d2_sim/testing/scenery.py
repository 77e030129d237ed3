"""
What tests read back from the world: a scan's range at an angle.

A plain function, no ROS: :func:`scan_range` reads one beam of a
``sensor_msgs/LaserScan`` by its angle. (What tests put in the world, a box
to spawn, is :func:`r2d2_sim.sim.spawnables.box_urdf`.)
"""

import math
from typing import Any

__all__ = ['scan_range']


def scan_range(scan: Any, angle_rad: float) -> float:
    """
    Return the range (m) of the beam of ``scan`` nearest ``angle_rad`` (rad, 0 ahead, CCW +).

    ``scan`` is a ``sensor_msgs/LaserScan``. The beam is found from
    ``angle_min`` and ``angle_increment``, the angle wrapped into the scan's
    span; ValueError for an angle the scan does not cover. Nothing in range
    is ``inf`` (REP-117).
    """
    count, step = len(scan.ranges), scan.angle_increment
    if not count or not step > 0.0:
        raise ValueError('the scan has no beams in increasing angles')
    offset = (angle_rad - scan.angle_min) % (2.0 * math.pi)
    index = round(offset / step)
    if index >= count and 2.0 * math.pi - offset <= step / 2.0:
        index = 0  # just before angle_min, the long way round
    if index >= count:
        raise ValueError(f'the scan covers {scan.angle_min:.3f} to {scan.angle_max:.3f} rad, '
                         f'not {angle_rad:.3f}')
    return float(scan.ranges[index])
