"""
A world's map for a farm's picture: the boxes of its collision shapes, seen from above.

A world model (``room.urdf``) is read as text: every ``<collision>`` whose
geometry is a ``<box>`` becomes a :class:`~r2d2_sim.farm.scenario.Box` at
its link's origin (worlds are loaded at the origin; joints and rotations
other than yaw are not followed, which covers walls and boxes of one static
link). Other shapes are left out of the map, not out of the physics.
"""

import math
from typing import List
import xml.etree.ElementTree as ElementTree

from r2d2_sim.farm.scenario import Box, ScenarioError
from r2d2_sim.physics.description import DescriptionError, resolve_description_path

__all__ = ['world_boxes']


def _numbers(text: str, count: int) -> List[float]:
    values = [float(v) for v in (text or '').split()]
    return values if len(values) == count else [0.0] * count


def world_boxes(world: str) -> List[Box]:
    """Return the boxes of ``world`` (a URDF reference as the ``world`` parameter takes it)."""
    if not world:
        return []
    try:
        path = resolve_description_path(world)
        root = ElementTree.parse(path).getroot()
    except (DescriptionError, OSError, ElementTree.ParseError) as exc:
        raise ScenarioError(f'cannot read the world {world}: {exc}') from None
    boxes = []
    for collision in root.iter('collision'):
        box = collision.find('geometry/box')
        if box is None:
            continue
        origin = collision.find('origin')
        xyz = _numbers(origin.get('xyz') if origin is not None else '', 3)
        rpy = _numbers(origin.get('rpy') if origin is not None else '', 3)
        size = _numbers(box.get('size'), 3)
        if all(math.isfinite(v) and v > 0.0 for v in size):
            boxes.append(Box(xyz[0], xyz[1], rpy[2], tuple(size)))
    return boxes
