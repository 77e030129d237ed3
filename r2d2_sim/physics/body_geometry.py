"""
A body's links as geometry: names and indices, poses, boxes, shapes, contacts.

:class:`BodyGeometry` is mixed into :class:`~r2d2_sim.physics.body.Body`:
the read-only questions about where a body's links are and what they are
made of (forward kinematics now, bounding boxes, collision shapes and mesh
vertices, inertial frames), and what it touches or comes near after a
step. The sensors' mounts, the entities' bounds and a run's watch ask them.
They change nothing and go through the Body's id (``BodyRemoved`` once it is
removed) and the queries it binds once (``_get_base_pose``,
``_get_contact_points``...), all set in ``Body.__init__``.
"""

from typing import List, Optional, Sequence, Tuple

from r2d2_sim.errors import WorldError
from r2d2_sim.model.transforms import rotate_inverse
from r2d2_sim.physics import records
from r2d2_sim.physics.records import (
    Aabb, ClosestPoints, CollisionShape, ContactPoint, Dynamics, LinkState, Vec3, Quat)


class BodyGeometry:
    """The Body's links: where they are, their boxes and shapes, its contacts and near points."""

    def link_index(self, link_name: str) -> int:
        """Return the index of the link named ``link_name`` (-1 for the base)."""
        if link_name == self.base_link_name:
            return -1
        for joint in self.joints.values():
            if joint.link_name == link_name:
                return joint.index
        names = [self.base_link_name] + [j.link_name for j in self.joints.values()]
        raise WorldError(f'no link named {link_name!r}; the robot has: {", ".join(names)}')

    def link_name(self, link: int) -> str:
        """Return the name of link ``link`` (-1: the base link)."""
        if link == -1:
            return self.base_link_name
        for joint in self.joints.values():
            if joint.index == link:
                return joint.link_name
        raise WorldError(f'{self.name} has no link {link}')

    def link_state(self, link: int) -> LinkState:
        """Return a link's world centre of mass and frame (forward kinematics now)."""
        return records.link_state(self._client, self.id, link)

    def link_pose(self, link: int) -> Tuple[Vec3, Quat]:
        """Return the world position and orientation of a link frame (-1: base link)."""
        if link < 0:
            com_position, com_orientation = self._get_base_pose()
            return self._multiply_transforms(com_position, com_orientation,
                                             *self._base_inertial_inverse)
        state = self.link_state(link)
        return state.frame_position, state.frame_orientation

    def aabb(self, link: int) -> Aabb:
        """Return the world bounding box of a link (-1: the base)."""
        return records.aabb(self._client, self.id, link)

    def links(self) -> range:
        """Return every link index of the body, the base (-1) first."""
        return range(-1, len(self.joints))

    def dynamics(self, link: int) -> Dynamics:
        """Return a link's mass, lateral friction and inertial frame (-1: the base)."""
        return records.dynamics(self._client, self.id, link)

    def bounding_box(self) -> Aabb:
        """Return the world bounding box around all of the body's links (``low[2]``: its floor)."""
        lows, highs = zip(*(self.aabb(link) for link in self.links()))
        return Aabb(tuple(map(min, zip(*lows))), tuple(map(max, zip(*highs))))

    def links_spanning_height(self, height_m: float) -> List[int]:
        """Return the links whose bounding box spans ``height_m`` now (a sensor plane)."""
        boxes = ((link, self.aabb(link)) for link in self.links())
        return [link for link, box in boxes if box.low[2] <= height_m <= box.high[2]]

    def link_half_extent_m(self, link: int) -> float:
        """Return half the largest horizontal size of a link's bounding box."""
        low, high = self.aabb(link)
        return max(high[0] - low[0], high[1] - low[1]) / 2.0

    def link_positions_in_base(self, links: Sequence[int]) -> List[Vec3]:
        """Return the link frames' origins expressed in the body frame."""
        base = self.world_state()
        result = []
        for link in links:
            origin = self.link_state(link).frame_position
            offset = tuple(origin[i] - base.position[i] for i in range(3))
            result.append(rotate_inverse(base.orientation, offset))
        return result

    def collision_shapes(self, link: int) -> List[CollisionShape]:
        """Return a link's collision shapes (-1: the base), each in the link's inertial frame."""
        return records.collision_shapes(self._client, self.id, link)

    def contacts(self, ignoring: Sequence['BodyGeometry'] = ()) -> List[ContactPoint]:
        """Return where this body touches others after the last step (it is ``body_a``)."""
        return records.contact_records(self._get_contact_points(),
                                       [body.id for body in ignoring if body.alive])

    def closest_points(self, other: 'BodyGeometry', range_m: float) -> Optional[ClosestPoints]:
        """Return this body's nearest points to ``other`` within ``range_m`` (None: farther)."""
        return records.nearest_points(self._get_closest_points(other.id, range_m))

    def inertial_pose(self, link: int) -> Tuple[Vec3, Quat]:
        """Return the world pose of a link's inertial frame (-1: the base): its shapes' frame."""
        if link < 0:
            position, orientation = self._get_base_pose()
            return tuple(position), tuple(orientation)
        state = self.link_state(link)
        return state.com_position, state.com_orientation

    def mesh_vertices(self, link: int, shape_index: int) -> List[Vec3]:
        """Return a collision mesh's vertices in its link's inertial frame (empty if none)."""
        return records.mesh_vertices(self._client, self.id, link, shape_index)
