"""A world's map for the farm's picture: the same walls whatever the world's format."""

import pytest

from r2d2_sim.farm.maps import world_boxes
from r2d2_sim.farm.scenario import Box, ROOM, ScenarioError

MOVED_ROOM = """\
r2d2_sim_world: 1
name: moved
models:
  - uri: package://r2d2_sim/urdf/room.urdf
    position: [10.0, 0.0, 0.0]
    yaw: 1.5707963267948966
"""


def test_the_room_as_urdf_and_as_manifest_has_the_same_walls_and_boxes():
    """room.urdf: four walls and three boxes; room.world.yaml loads it at the origin."""
    urdf = world_boxes(ROOM)
    assert len(urdf) == 7
    assert world_boxes('package://r2d2_sim/urdf/room.world.yaml') == urdf
    assert Box(1.0, 1.2, 0.0, (0.4, 0.4, 0.4)) in urdf  # one of the boxes the manifest names


def test_a_model_placed_by_its_world_is_drawn_where_it_stands(tmp_path):
    """The room at (10, 0) turned 90 degrees: the box at (1.0, 1.2) stands at (8.8, 1.0)."""
    world = tmp_path / 'moved.world.yaml'
    world.write_text(MOVED_ROOM)
    moved = world_boxes(str(world))
    assert len(moved) == 7
    box = min(moved, key=lambda b: (b.x - 8.8) ** 2 + (b.y - 1.0) ** 2)
    assert (box.x, box.y) == pytest.approx((8.8, 1.0), abs=1e-9)
    assert world_boxes('') == []
    with pytest.raises(ScenarioError, match='cannot read the world'):
        world_boxes(str(tmp_path / 'none.world.yaml'))
