"""
The room world and rays in PyBullet: walls where urdf/room.urdf puts them.

The robot is left out of its own laser's rays but still collides.

Distances are those written in room.urdf's header: inner wall faces at
x = +2.0 and -3.0, y = +2.5 and -2.5; box faces at y = 1.0 (box_a) and
y = -1.3 (box_c). Each world is a DIRECT client of its own.
"""

import math
import os

import numpy
import pybullet
import pybullet_data
from pybullet_utils.bullet_client import BulletClient
import pytest

from common import REPO
from r2d2_sim.physics.raycast import cast_rays, exclude_from_rays, MAX_BATCH_SIZE, RAY_MASK
from r2d2_sim.model.sensors import linearize_depth, ranges_from_hits, ray_endpoints, ScanGeometry

URDF_DIR = os.path.join(REPO, 'urdf')
ROOM_URDF = os.path.join(URDF_DIR, 'room.urdf')
ROBOT_URDF = os.path.join(URDF_DIR, 'r2d2.urdf')
WHEELS = ['left_front_wheel_joint', 'left_back_wheel_joint',
          'right_front_wheel_joint', 'right_back_wheel_joint']
RATE_HZ = 240
LASER_HEIGHT_M = 0.3  # inside R2D2's body cylinder (z 0.17 .. 0.77)
# Beam k points at (k - 180) degrees: beam 0 is -x, 90 is -y, 180 is +x, 270 is +y.
SCAN = ScanGeometry(-math.pi, math.pi, 360, 0.05, 10.0)
# PyBullet's pair filters: a pair collides if (gA & mB) and (gB & mA), or
# (the default) if (gA & mB) or (gB & mA).
AND_FILTER, OR_FILTER = 0, 1
FILTER_MODES = pytest.mark.parametrize('filter_mode', [AND_FILTER, OR_FILTER],
                                       ids=['and_filter', 'or_filter'])


class RoomWorld:
    """Plane, room and (optionally) R2D2 in a DIRECT client, robot settled for 1 s."""

    def __init__(self, *, robot: bool = True, exclude_robot: bool = True,
                 filter_mode: int = OR_FILTER) -> None:
        self.client = BulletClient(connection_mode=pybullet.DIRECT)
        client = self.client
        client.setAdditionalSearchPath(pybullet_data.getDataPath())
        client.setTimeStep(1.0 / RATE_HZ)
        client.setGravity(0.0, 0.0, -9.8)
        client.setPhysicsEngineParameter(collisionFilterMode=filter_mode)
        self.plane_id = client.loadURDF('plane.urdf')
        self.room_id = client.loadURDF(ROOM_URDF, basePosition=(0.0, 0.0, 0.0))
        self.robot_id = None
        if robot:
            self.robot_id = client.loadURDF(
                ROBOT_URDF, basePosition=(0.0, 0.0, 0.5),
                flags=client.URDF_USE_INERTIA_FROM_FILE | client.URDF_USE_IMPLICIT_CYLINDER)
            if exclude_robot:
                exclude_from_rays(client, self.robot_id)
            self.step(RATE_HZ)

    def step(self, steps: int) -> None:
        for _ in range(steps):
            self.client.stepSimulation()

    def robot_pose(self):
        return self.client.getBasePositionAndOrientation(self.robot_id)

    def robot_links(self):
        return range(-1, self.client.getNumJoints(self.robot_id))

    def robot_top_m(self) -> float:
        return max(self.client.getAABB(self.robot_id, link)[1][2] for link in self.robot_links())

    def robot_front_m(self) -> float:
        return max(self.client.getAABB(self.robot_id, link)[1][0] for link in self.robot_links())

    def drive(self, wheel_rad_s: float) -> None:
        """Turn all four wheels at ``wheel_rad_s`` (positive rolls R2D2 forward, +x)."""
        names = {self.client.getJointInfo(self.robot_id, j)[1].decode(): j
                 for j in range(self.client.getNumJoints(self.robot_id))}
        self.client.setJointMotorControlArray(
            self.robot_id, [names[n] for n in WHEELS], pybullet.VELOCITY_CONTROL,
            targetVelocities=[wheel_rad_s] * 4, forces=[10.0] * 4)

    def laser_origin(self):
        (x, y, _), _ = self.robot_pose()
        return (x, y, LASER_HEIGHT_M)

    def scan(self, mask: int = RAY_MASK, orientation=(0.0, 0.0, 0.0, 1.0)) -> numpy.ndarray:
        starts, ends = ray_endpoints(SCAN, self.laser_origin(), orientation)
        return ranges_from_hits(cast_rays(self.client, starts, ends, mask), SCAN)

    def close(self) -> None:
        self.client.disconnect()


@pytest.fixture
def room():
    """Provide the room with R2D2 settled at the origin, left out of rays."""
    world = RoomWorld()
    try:
        yield world
    finally:
        world.close()


def test_room_is_one_static_body_at_the_origin(room):
    client = room.client
    assert client.getDynamicsInfo(room.room_id, -1)[0] == 0.0  # mass 0: fixed base
    assert client.getNumJoints(room.room_id) == 0
    low, high = client.getAABB(room.room_id, -1)
    # Outer faces 0.1 beyond the inner ones (AABBs may be padded by a small margin).
    assert low == pytest.approx((-3.1, -2.6, 0.0), abs=0.05)
    assert high == pytest.approx((2.1, 2.6, 1.0), abs=0.05)


def test_scan_reads_the_walls_and_boxes_from_the_robot_position(room):
    """From the robot's (x0, y0): +x wall 2.0 - x0, -x wall 3.0 + x0, boxes at their faces."""
    x0, y0, _ = room.laser_origin()
    ranges = room.scan()
    assert ranges[180] == pytest.approx(2.0 - x0, abs=1e-3)   # 0 deg
    assert ranges[0] == pytest.approx(3.0 + x0, abs=1e-3)     # 180 deg
    assert ranges[270] == pytest.approx(2.5 - y0, abs=1e-3)   # +90 deg: wall y = 2.5
    assert ranges[90] == pytest.approx(1.3 + y0, abs=1e-3)    # -90 deg: box_c face y = -1.3
    # 50 deg meets box_a's face y = 1.0 at (1.0 - y0) / sin 50 (x there ~0.84, on the face).
    assert ranges[230] == pytest.approx((1.0 - y0) / math.sin(math.radians(50)), abs=1e-3)
    # Nothing is within 0.6 m: the robot, all around the laser, is not seen.
    assert numpy.isfinite(ranges).all() and ranges.min() > 0.6


def test_a_yawed_laser_turns_its_beams_with_it(room):
    """Yawed +90 deg, the laser's forward beam reads the +y wall, its rear the box_c face."""
    x0, y0, _ = room.laser_origin()
    yaw_90 = (0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5))
    ranges = room.scan(orientation=yaw_90)
    assert ranges[180] == pytest.approx(2.5 - y0, abs=1e-3)
    assert ranges[0] == pytest.approx(1.3 + y0, abs=1e-3)
    assert ranges[270] == pytest.approx(3.0 + x0, abs=1e-3)   # left of the laser is world -x


def test_without_the_mask_the_laser_sees_the_robot_around_it(room):
    """The same scan cast with mask -1 (all groups) hits R2D2's own links."""
    ranges = room.scan(mask=-1)
    assert (ranges < 0.6).any()


def test_a_ray_from_inside_the_robot_hits_the_wall_beyond(room):
    x0, y0, z = room.laser_origin()
    start, end = [(x0, y0, z)], [(x0 + 10.0, y0, z)]
    assert cast_rays(room.client, start, end, -1)[0] * 10.0 < 0.3      # the robot's body
    assert cast_rays(room.client, start, end)[0] * 10.0 == pytest.approx(2.0 - x0, abs=1e-3)


def test_the_masked_rays_still_see_the_ground_and_dynamic_bodies(room):
    client = room.client
    box = client.createMultiBody(
        1.0, client.createCollisionShape(client.GEOM_BOX, halfExtents=(0.1, 0.1, 0.1)),
        basePosition=(1.0, 0.0, 0.1))
    room.step(10)
    x0, y0, z = room.laser_origin()
    up = cast_rays(client, [(1.5, -1.5, 0.5), (1.0, 0.0, 1.0), (x0, y0, z)],
                   [(1.5, -1.5, -0.5), (1.0, 0.0, 0.0), (x0, y0, z + 10.0)])
    assert up[0] == pytest.approx(0.5, abs=1e-3)   # the ground plane (static) 0.5 m below
    assert up[1] == pytest.approx(0.8, abs=1e-3)   # the dynamic box's top at z = 0.2
    assert up[2] == 1.0                            # nothing above the robot: no hit
    client.removeBody(box)


@FILTER_MODES
def test_excluded_robot_settles_and_drives_exactly_as_before(filter_mode):
    """The filter change moves nothing: on the open floor both robots follow the same path."""
    poses = []
    for exclude in (False, True):
        world = RoomWorld(exclude_robot=exclude, filter_mode=filter_mode)
        try:
            assert world.robot_pose()[0][2] == pytest.approx(0.47, abs=0.01)  # on its wheels
            world.drive(10.0)  # 0.35 m/s for 2 s: 0.7 m, well short of the wall
            world.step(2 * RATE_HZ)
            poses.append(world.robot_pose())
        finally:
            world.close()
    (p0, q0), (p1, q1) = poses
    assert p1[0] > 0.5
    assert p1 == pytest.approx(p0, abs=1e-9) and q1 == pytest.approx(q0, abs=1e-9)


@FILTER_MODES
def test_excluded_robot_still_holds_up_a_dropped_box(filter_mode):
    room = RoomWorld(filter_mode=filter_mode)
    try:
        check_box_lands_on_robot(room)
    finally:
        room.close()


def check_box_lands_on_robot(room):
    client = room.client
    (x0, y0, _), _ = room.robot_pose()
    top_m = room.robot_top_m()
    box = client.createMultiBody(
        1.0, client.createCollisionShape(client.GEOM_BOX, halfExtents=(0.1, 0.1, 0.1)),
        basePosition=(x0, y0, top_m + 0.3))
    touching_steps = 0
    lowest_m = math.inf
    for _ in range(RATE_HZ // 2):
        room.step(1)
        touching_steps += bool(client.getContactPoints(box, room.robot_id))
        lowest_m = min(lowest_m, client.getBasePositionAndOrientation(box)[0][2] - 0.1)
    assert touching_steps > 0
    assert lowest_m > top_m - 0.01  # it lands on the head instead of falling through


@FILTER_MODES
def test_excluded_robot_is_stopped_by_the_wall_and_the_room_stays_put(filter_mode):
    """Driving at the +x wall for 7 s: contact, no passing x = 2.0, the room unmoved."""
    room = RoomWorld(filter_mode=filter_mode)
    try:
        check_robot_stopped_by_wall(room)
    finally:
        room.close()


def check_robot_stopped_by_wall(room):
    client = room.client
    room.drive(10.0)
    touching_steps = 0
    for _ in range(7 * RATE_HZ):
        room.step(1)
        touching_steps += bool(client.getContactPoints(room.robot_id, room.room_id))
    assert touching_steps > 0
    assert room.robot_front_m() < 2.0 + 0.01
    assert client.getBasePositionAndOrientation(room.room_id) == (
        (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))


def test_cast_rays_in_small_batches_gives_the_same_fractions(room):
    """1000 rays in batches of 7 (143 calls) agree with one batch; bad input is refused."""
    rng = numpy.random.default_rng(5)
    directions = rng.normal(size=(1000, 3))
    directions /= numpy.linalg.norm(directions, axis=1, keepdims=True)
    starts = numpy.tile(room.laser_origin(), (1000, 1))
    ends = starts + 8.0 * directions
    whole = cast_rays(room.client, starts, ends)
    assert numpy.array_equal(cast_rays(room.client, starts, ends, batch_size=7), whole)
    assert ((whole > 0.0) & (whole <= 1.0)).all()
    with pytest.raises(ValueError, match='batch_size'):
        cast_rays(room.client, starts, ends, batch_size=MAX_BATCH_SIZE + 1)
    with pytest.raises(ValueError, match='N x 3'):
        cast_rays(room.client, starts, ends[:10])


def test_pybullet_depth_buffer_linearises_to_the_wall_distance():
    """A camera 0.5 m up at the origin, looking along +x: every wall pixel is 2.0 m deep."""
    world = RoomWorld(robot=False)
    try:
        client = world.client
        near_m, far_m = 0.1, 10.0
        view = client.computeViewMatrix((0.0, 0.0, 0.5), (1.0, 0.0, 0.5), (0.0, 0.0, 1.0))
        projection = client.computeProjectionMatrixFOV(60.0, 64 / 48, near_m, far_m)
        _, _, _, depth_buffer, _ = client.getCameraImage(
            64, 48, view, projection, renderer=pybullet.ER_TINY_RENDERER)
        depth_m = linearize_depth(numpy.reshape(depth_buffer, (48, 64)), near_m, far_m)
    finally:
        world.close()
    # Rows near the centre see the wall (z 0.3 .. 0.7 at 2 m): z-depth is 2.0 across
    # the whole row, not the longer distance along each pixel's ray.
    assert depth_m[20:28, :] == pytest.approx(numpy.full((8, 64), 2.0), abs=1e-3)
    # The top row looks over the 1 m wall into empty space: +inf.
    assert numpy.isposinf(depth_m[0, :]).all()
