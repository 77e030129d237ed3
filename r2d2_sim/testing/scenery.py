"""
What tests put in the world and read back: boxes (fixed walls or pushable), a scan's range.

Plain functions, no ROS: :func:`box_urdf` writes the URDF text a spawn takes
(``harness.spawn(box_urdf(...))``, or ``SpawnEntity``'s ``resource_string``
from any client), and :func:`scan_range` reads one beam of a
``sensor_msgs/LaserScan`` by its angle.
"""

import math
from typing import Sequence
from xml.sax.saxutils import quoteattr

__all__ = ['box_urdf', 'scan_range']


def box_urdf(size_m: Sequence[float] = (0.2, 0.2, 0.2), *, mass_kg: float = 0.0,
             name: str = 'box', rgba: Sequence[float] = (0.8, 0.5, 0.2, 1.0)) -> str:
    """
    Return the URDF text of a solid box, its base link at its centre.

    ``mass_kg`` 0 (the default) makes it fixed: PyBullet gives a base link of
    mass 0 a fixed base, so robots cannot push it (a wall, a dock, a pillar;
    the standard's ``GetEntityInfo`` reports it as STATIC_OBJECT). A positive
    mass makes it a pushable box with a uniform solid's inertia. ``rgba`` is
    its colour in the camera and the live view.
    """
    x, y, z = (float(v) for v in size_m)
    if not all(math.isfinite(v) and v > 0.0 for v in (x, y, z)):
        raise ValueError(f'a box needs three positive sizes, got {tuple(size_m)}')
    if not (math.isfinite(mass_kg) and mass_kg >= 0.0):
        raise ValueError(f'a box needs a mass >= 0 kg, got {mass_kg}')
    geometry = f'<geometry><box size="{x!r} {y!r} {z!r}"/></geometry>'
    # PyBullet takes a link without <inertial> as 1 kg: a fixed box says mass 0.
    m = mass_kg / 12.0
    inertial = (f'<inertial><mass value="{mass_kg!r}"/><inertia ixx="{m * (y * y + z * z)!r}" '
                f'iyy="{m * (x * x + z * z)!r}" izz="{m * (x * x + y * y)!r}" ixy="0" '
                'ixz="0" iyz="0"/></inertial>')
    colour = ' '.join(repr(float(c)) for c in rgba)
    return (f'<robot name={quoteattr(name)}><link name={quoteattr(name)}>{inertial}'
            f'<collision>{geometry}</collision><visual>{geometry}<material name="colour">'
            f'<color rgba="{colour}"/></material></visual></link></robot>')


def scan_range(scan, angle_rad: float) -> float:
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
