"""
A world's map for a farm's picture: the boxes of its collision shapes, seen from above.

The world is read as the simulator reads its ``world`` parameter (a URDF,
a world manifest, an SDF world: :func:`r2d2_sim.farm.places.read`),
and each of its models' URDF as text: every ``<collision>`` whose geometry
is a ``<box>`` becomes a :class:`~r2d2_sim.farm.scenario.Box` at its link's
origin, placed by the model's pose (joints and rotations other than yaw are
not followed, which covers walls and boxes of one static link). Other
shapes are left out of the map, not out of the physics.
"""

import math
from typing import List, Sequence
import xml.etree.ElementTree as ElementTree

from r2d2_sim.farm.places import read
from r2d2_sim.farm.scenario import Box, ScenarioError
from r2d2_sim.model.transforms import yaw_of

__all__ = ['world_boxes']


def _numbers(text: str, count: int) -> List[float]:
    values = [float(v) for v in (text or '').split()]
    return values if len(values) == count else [0.0] * count


def world_boxes(world: str) -> List[Box]:
    """Return the boxes of ``world`` (as the ``world`` parameter takes it; '' none)."""
    if not world:
        return []
    try:
        read_back = read(world)
    except ScenarioError as exc:  # 'world X: ...', as the simulator says it
        raise ScenarioError(f'cannot read the {exc}') from None
    try:  # an SDF world's models are generated files, deleted with the world
        return [box for model in read_back.models
                for box in _model_boxes(model.path, model.position, yaw_of(model.orientation))]
    finally:
        read_back.close()


def _model_boxes(path: str, position: Sequence[float], yaw: float) -> List[Box]:
    """Return a model's box collisions, its origin at ``position`` turned by ``yaw``."""
    try:
        root = ElementTree.parse(path).getroot()
    except (OSError, ElementTree.ParseError) as exc:
        raise ScenarioError(f'cannot read the world model {path}: {exc}') from None
    c, s = math.cos(yaw), math.sin(yaw)
    boxes = []
    for collision in root.iter('collision'):
        box = collision.find('geometry/box')
        if box is None:
            continue
        origin = collision.find('origin')
        xyz = _numbers(origin.get('xyz', '') if origin is not None else '', 3)
        rpy = _numbers(origin.get('rpy', '') if origin is not None else '', 3)
        sx, sy, sz = _numbers(box.get('size', ''), 3)
        if all(math.isfinite(v) and v > 0.0 for v in (sx, sy, sz)):
            boxes.append(Box(position[0] + c * xyz[0] - s * xyz[1],
                             position[1] + s * xyz[0] + c * xyz[1], yaw + rpy[2], (sx, sy, sz)))
    return boxes
