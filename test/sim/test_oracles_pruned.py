"""
A watch that passes far bodies over reads what one asking about every body reads, bit for bit.

Seeded drives among fixed and loose boxes, with a fixed box put in the
robot's way, one spawned beside it and one deleted while they run: two
watches each (pruned, and ``prune=False``), with and without the clearance,
see the same contacts, clearance, regions and fall. And R2D2's reach holds
its links with its gripper and head anywhere in their limits.
"""

import math
import random

import pybullet
import pytest

from r2d2_sim.model.regions import box_region, circle_region, polygon_region
from r2d2_sim.model.transforms import yaw_of
from r2d2_sim.physics.body import Body
from r2d2_sim.sim.oracles import RunWatch
from r2d2_sim.sim.simulation import SpawnRequest
from r2d2_sim.sim.spawnables import box_urdf

SIMULATION_DEFAULTS = {'scan_rate': 0.0, 'imu_rate': 0.0, 'cmd_vel_timeout': 0.0}
UPRIGHT = (0.0, 0.0, 0.0, 1.0)
ZERO = (0.0, 0.0, 0.0)


def place_box(simulation, name, x, y, size=0.3, mass_kg=0.0):
    simulation.spawn(SpawnRequest(name, resource_string=box_urdf((size, size, size),
                                                                 mass_kg=mass_kg, name=name),
                                  position=(x, y, size / 2)))


def readings(watch):
    return (watch.contacts, watch.clearance, watch.reached, watch.tipped_ns, watch.steps)


def drive(make, seed, prune):
    """Run a seeded drive among boxes; return two watches' readings and the points asked."""
    rng = random.Random(seed)
    simulation = make()
    place_box(simulation, 'wall', 1.6, 0.0, size=0.4)  # every drive meets something
    for index in range(6):
        place_box(simulation, f'box_{index}', rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0),
                  mass_kg=rng.choice((0.0, 0.0, 2.0)))
    goal = {'goal': circle_region(1.0, 0.5, 0.3)}
    watches = [RunWatch(simulation, regions=goal, prune=prune, clearance=clearance,
                        clearance_range_m=1.5) for clearance in (True, False)]
    for second in range(8):
        simulation.robot.command(rng.uniform(-0.2, 0.6), rng.uniform(-1.0, 1.0))
        if second == 3:  # a fixed box jumps against the robot's gripper
            (x, y, _), orientation = simulation.robot.body.world_pose()
            yaw = yaw_of(orientation)
            simulation.set_entity_state('box_0', '', (x + 0.55 * math.cos(yaw),
                                                      y + 0.55 * math.sin(yaw), 0.15),
                                        UPRIGHT, ZERO, ZERO)
        if second == 5:
            x, y, _ = simulation.robot.body.world_pose()[0]
            place_box(simulation, 'late', x - 0.6, y)
            simulation.delete_entity('box_1')
        for _ in range(240):
            simulation.step()
    return [readings(watch) for watch in watches]


@pytest.mark.parametrize('seed', range(4))
def test_a_pruned_watch_reads_what_asking_every_body_reads(make, seed, monkeypatch):
    """Eight simulated seconds among moving and moved boxes, pruned and not: the same readings."""
    asked = []
    closest = Body.closest_points

    def counted(body, other, range_m):
        asked.append(other.name)
        return closest(body, other, range_m)
    monkeypatch.setattr(Body, 'closest_points', counted)
    pruned = drive(make, seed, prune=True)
    pruned_asked, asked[:] = len(asked), []
    every = drive(make, seed, prune=False)
    assert pruned == every
    contacts, clearance = pruned[0][0], pruned[0][1]
    assert contacts, 'the drive touched nothing: the test shows nothing'
    assert clearance.distance_m < 1.5
    assert pruned_asked < len(asked)  # and far boxes were passed over


def test_r2d2s_reach_holds_its_links_in_any_joint_state(make):
    """
    Gripper, grippers and head anywhere in their limits, the robot turned any way.

    A probe just outside the reach, in any direction, is never within PyBullet's
    closest points; one at half the reach now and then is.
    """
    simulation = make()
    body = simulation.robot.body
    reach = body.reach_m()
    assert reach is not None and 0.515 < reach < 1.0  # the gripper's tip is 0.515 m ahead
    place_box(simulation, 'probe', 10.0, 10.0, size=0.02)
    probe = simulation.world.bodies['probe']
    client, rng = body._client, random.Random(7)
    near = 0
    for _ in range(60):
        body.set_base_state((0.0, 0.0, 2.0), pybullet.getQuaternionFromEuler(
            [rng.uniform(-math.pi, math.pi) for _ in range(3)]))
        for joint in body.joints.values():
            if joint.index in body.movable_indices:
                low, high = ((joint.lower_limit, joint.upper_limit)
                             if joint.lower_limit <= joint.upper_limit else (-math.pi, math.pi))
                client.resetJointState(body.id, joint.index, rng.uniform(low, high))
        com = client.getBasePositionAndOrientation(body.id)[0]
        for _ in range(30):
            direction = [rng.gauss(0.0, 1.0) for _ in range(3)]
            norm = math.sqrt(sum(v * v for v in direction))
            for distance, outside in ((reach + 0.02, True), (0.5 * reach, False)):
                client.resetBasePositionAndOrientation(
                    probe.id, [c + distance * v / norm for c, v in zip(com, direction)], UPRIGHT)
                touching = body.closest_points(probe, 0.0) is not None
                if outside:
                    assert not touching, (distance, direction)
                else:
                    near += touching
    assert near > 0  # inside the reach, the probe does meet the robot now and then


# A slider whose arm's inertial frame is turned a quarter turn: PyBullet gives the joint's
# axis in that frame ((0, -1, 0) here), which the reach must turn back to the world's x.
TURNED_SLIDER = (
    '<robot name="slider"><link name="base"><inertial><mass value="5"/>'
    '<inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>'
    '<collision><geometry><box size="0.3 0.3 0.1"/></geometry></collision></link>'
    '<link name="arm"><inertial><origin rpy="0 0 1.5707963"/><mass value="0.1"/>'
    '<inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>'
    '<collision><geometry><box size="0.05 0.05 0.05"/></geometry></collision></link>'
    '<joint name="slide" type="prismatic"><parent link="base"/><child link="arm"/>'
    '<origin xyz="1 0 0.2"/><axis xyz="1 0 0"/>'
    '<limit lower="0" upper="2" effort="100" velocity="1"/></joint></robot>')


def test_a_slider_with_a_turned_inertial_frame_is_seen_reaching_a_wall(make):
    """
    The arm slides 2 m out along the base's x into a wall: both watches see it touch.

    Its reach holds the arm at its upper limit (x = 3.03 m), and the pruned watch
    reads what the one asking every body reads.
    """
    simulation = make(robot_description=TURNED_SLIDER, left_wheel_names=[],
                      right_wheel_names=[])
    simulation.spawn(SpawnRequest('wall', resource_string=box_urdf(
        (0.2, 1.0, 1.0), name='wall'), position=(2.6, 0.0, 0.5)))
    body = simulation.robot.body
    slide = body.joints['slide'].index
    reach = body.reach_m()
    pruned, every = RunWatch(simulation, clearance=False), RunWatch(
        simulation, clearance=False, prune=False)
    body.set_joint_velocities([slide], [1.0], [100.0])  # out at 1 m/s, into the wall
    for _ in range(480):
        simulation.step()
    assert [contact.other for contact in every.contacts] == ['wall']
    assert pruned.contacts == every.contacts
    assert reach is not None and reach > 3.0  # the arm's far face at x 3.025 from x 0


def test_moving_a_fixed_box_is_seen_at_once(make):
    """A fixed box 3 m away put against the robot's front between two steps: touching then."""
    simulation = make()
    place_box(simulation, 'far', 3.0, 0.0, size=0.8)
    with RunWatch(simulation, clearance=False) as watch:
        for _ in range(24):
            simulation.step()
        x, y, _ = simulation.robot.body.world_pose()[0]
        simulation.set_entity_state('far', '', (x + 0.55, y, 0.4), UPRIGHT, ZERO, ZERO)
        simulation.step()
    assert watch.touched() == ['far']
    assert watch.contacts[0].start_ns == simulation.time_ns


@pytest.mark.parametrize('rate, speed', [(100.0, 40.0), (60.0, 25.0), (100.0, -40.0)])
def test_a_robot_leaving_or_hitting_a_wall_fast_is_seen_touching_it(make, rate, speed):
    """
    Faster than the margin in one step (below the blow-up bound): the contact still counts.

    Bullet finds a step's contacts before it moves the bodies, so the robot that leaves
    the wall at 40 m/s touched it in the step that took it away (speed > 0); one that
    flies at the wall from 0.5 m (speed < 0) touches it in a step it ends far from it.
    """
    def run(prune):
        simulation = make(physics_rate=rate)
        simulation.spawn(SpawnRequest('wall', resource_string=box_urdf(
            (0.4, 2.0, 1.0), name='wall'), position=(0.75, 0.0, 0.5)))
        watch = RunWatch(simulation, prune=prune, clearance=False)
        for _ in range(5):
            simulation.step()
        position, orientation = simulation.robot.body.world_pose()
        start = position[0] + (0.045 if speed > 0 else -0.5)
        simulation.set_entity_state('r2d2', '', (start, position[1], position[2]), orientation,
                                    (-speed, 0.0, 0.0), ZERO)
        for _ in range(6):
            simulation.step()
        assert simulation.blow_ups == 0
        return watch.contacts
    pruned = run(True)
    assert pruned and pruned[0].other == 'wall'
    assert pruned == run(False)


def test_contacts_count_where_the_robot_stood_before_the_step(make):
    """
    Contacts found before a step's motion count, however far the robot then went.

    The step's motion is played by hand: the robot rests against the wall, the physics
    steps (finding the contact), and the robot is then carried 1 m away behind the
    watch's back (PyBullet's own call, as a fast step would) before the watch looks.
    """
    readings = []
    for prune in (True, False):
        simulation = make()
        simulation.spawn(SpawnRequest('wall', resource_string=box_urdf(
            (0.4, 2.0, 1.0), name='wall'), position=(0.75, 0.0, 0.5)))
        body = simulation.robot.body
        position, orientation = body.world_pose()
        simulation.set_entity_state('r2d2', '', (position[0] + 0.045, position[1], position[2]),
                                    orientation, ZERO, ZERO)
        watch = RunWatch(simulation, prune=prune, clearance=False)
        simulation.step()  # the watch knows where the robot stands
        simulation.world.step(1)  # the contact found, then the robot carried away
        com, com_orientation = body._client.getBasePositionAndOrientation(body.id)
        body._client.resetBasePositionAndOrientation(body.id, (com[0] - 1.0, com[1], com[2]),
                                                     com_orientation)
        watch.observe(simulation.time_ns)
        readings.append(watch.contacts)
    assert readings[0] and readings[0][0].other == 'wall'
    assert readings[0] == readings[1]


@pytest.mark.parametrize('clearance_range_m', [None, 0.4])
def test_fixed_boxes_approached_from_afar_are_touched_together(make, clearance_range_m):
    """
    Every body fixed and far at first, then two touched at once: pruned, the same readings.

    The watch stops looking at fixed bodies one by one while its centre of mass
    is farther from all of them than it has moved since it last did; driving
    straight at a pair of pillars, it must look again in time, and ask both.
    """
    def run(prune):
        simulation = make()
        place_box(simulation, 'left', 2.4, 0.24, size=0.3)
        place_box(simulation, 'right', 2.4, -0.24, size=0.3)
        place_box(simulation, 'aside', -3.0, 3.0)
        watch = RunWatch(simulation, prune=prune, clearance=clearance_range_m is not None,
                         clearance_range_m=clearance_range_m or 2.0)
        simulation.robot.command(0.5, 0.0)
        for _ in range(240 * 7):
            simulation.step()
        return watch.contacts, watch.clearance
    contacts, clearance = run(True)
    assert {contact.other for contact in contacts} == {'left', 'right'}
    first, second = sorted(contacts, key=lambda contact: contact.start_ns)[:2]
    assert first.end_ns is None or second.start_ns < first.end_ns  # touching both at once
    assert (contacts, clearance) == run(False)


# A body whose centre of mass is neither at nor turned like its link frame: the watch reads
# regions and tipping at the body frame, which only a few of its steps work out exactly.
OFFSET_BODY = (
    '<robot name="skewed"><link name="skewed"><inertial>'
    '<origin xyz="0.12 0.05 -0.03" rpy="0.4 0.2 0.9"/><mass value="1.0"/>'
    '<inertia ixx="0.02" iyy="0.03" izz="0.04" ixy="0" ixz="0" iyz="0"/></inertial>'
    '<collision><geometry><box size="0.6 0.4 0.12"/></geometry></collision></link></robot>')


@pytest.mark.parametrize('spin', [(6.0, 0.0, 0.0), (0.0, -6.0, 0.0), (-4.0, -4.0, 0.0)])
def test_regions_and_tipping_are_read_at_the_body_frame(make, spin):
    """
    A flung body skidding through small regions and tumbling: what reading its pose says.

    The reference reads the body frame's pose (``world_pose``) after every step;
    the watch reads the centre of mass's and works the frame out only near a
    region or near the tipping angle: the same entry times and the same fall.
    The regions lie along the path of a first run (the same physics again); the
    fall goes three ways, for the body frame's up to lean first, or the inertial frame's.
    """
    def fling(simulation, steps=(60, 240, 240)):
        body = simulation.world.bodies['skewed']
        for _ in range(steps[0]):
            yield
        body.set_base_state(linear_velocity=(3.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 2.0))
        for _ in range(steps[1]):
            yield
        body.set_base_state(linear_velocity=(0.0, 0.0, 2.0), angular_velocity=spin)
        for _ in range(steps[2]):
            yield

    def spawned():
        simulation = make()
        simulation.spawn(SpawnRequest('skewed', resource_string=OFFSET_BODY,
                                      position=(0.0, 3.0, 0.3)))
        return simulation

    simulation = spawned()
    path = []
    for _ in fling(simulation):
        simulation.step()
        path.append(simulation.world.bodies['skewed'].world_pose()[0])
    rng = random.Random(3)
    regions = {}
    for index, (x, y, _) in enumerate(path[60::9]):
        x, y = x + rng.uniform(-0.02, 0.02), y + rng.uniform(-0.02, 0.02)
        regions[f'circle_{index}'] = circle_region(x, y, rng.uniform(0.005, 0.03))
        regions[f'box_{index}'] = box_region(x - 0.01, y, x + 0.01, y + 0.02)
        regions[f'polygon_{index}'] = polygon_region([(x, y), (x + 0.02, y), (x, y - 0.02)])

    simulation = spawned()
    body = simulation.world.bodies['skewed']
    tip_angle_rad = math.radians(30.0)
    watch = RunWatch(simulation, 'skewed', regions=regions, tip_angle_rad=tip_angle_rad,
                     clearance=False)
    reached, tipped = {}, []

    def reference(time_ns):
        (x, y, _), orientation = body.world_pose()
        for name, region in regions.items():
            if name not in reached and region.contains(x, y):
                reached[name] = time_ns
        if not tipped and 1.0 - 2.0 * (orientation[0] ** 2 + orientation[1] ** 2) < math.cos(
                tip_angle_rad):
            tipped.append(time_ns)
    simulation.watch_steps(reference)
    for _ in fling(simulation):
        simulation.step()
    # Most regions entered, some not, and a fall: the test shows what it compares.
    assert len(regions) // 2 <= len(reached) < len(regions) and tipped
    assert watch.reached == reached
    assert watch.tipped_ns == tipped[0]


def test_a_region_far_from_the_origin_is_entered_with_the_body_frame(make):
    """
    At x = 40 m the body frame's x (float32 in PyBullet) is up to 2e-6 m from the centre of mass.

    A box region whose edge lies exactly at the body frame's x after a step is
    entered when reading the frame every step says.
    """
    start = 40.0 + 1.5e-6
    simulation = make(initial_pose=[start, 0.0, 0.0])
    body = simulation.robot.body
    for _ in range(3):
        simulation.step()
    com_x, frame_x = body.com_pose()[0][0], body.world_pose()[0][0]
    assert abs(frame_x - com_x) > 1e-6  # the rounding the test is about
    region = (box_region(frame_x, -1.0, frame_x + 1.0, 1.0) if frame_x > com_x
              else box_region(frame_x - 1.0, -1.0, frame_x, 1.0))
    simulation = make(initial_pose=[start, 0.0, 0.0])
    body, entered = simulation.robot.body, []

    def reference(time_ns):
        (x, y, _), _ = body.world_pose()
        if not entered and region.contains(x, y):
            entered.append(time_ns)
    simulation.watch_steps(reference)
    with RunWatch(simulation, regions={'edge': region}, clearance=False) as watch:
        for _ in range(5):
            simulation.step()
    assert entered and watch.reached == {'edge': entered[0]}


def test_leaning_within_float32_of_a_wide_tip_angle_is_read_at_the_body_frame(make):
    """
    Past 90 degrees the leaning read from the centre of mass's orientation is 1e-6 off.

    A fixed box set at an orientation where the two readings differ most, the
    tip angle between them: tipped at the first step, as the body frame says.
    """
    from r2d2_sim.sim.oracles import _up_cos, _up_cos_of, _z_axis
    simulation = make()
    place_box(simulation, 'leaner', 3.0, 3.0)
    body = simulation.world.bodies['leaner']
    axis, rng, widest = _z_axis(body.com_to_body[1]), random.Random(5), (0.0, None, 0.0)
    for _ in range(20000):
        q = [rng.gauss(0.0, 1.0) for _ in range(4)]
        norm = math.sqrt(sum(v * v for v in q))
        q = [v / norm for v in q]
        simulation.set_entity_state('leaner', '', (3.0, 3.0, 1.0), q, ZERO, ZERO)
        com, orientation = body.com_pose()
        exact = _up_cos(body.pose_of_com(com, orientation)[1])
        gap = _up_cos_of(orientation, axis) - exact
        if gap > widest[0]:
            widest = (gap, q, exact)
    gap, q, exact = widest
    assert gap > 1e-6  # wider than the slack this watch once had
    simulation.set_entity_state('leaner', '', (3.0, 3.0, 1.0), q, ZERO, ZERO)
    # The limit between the two, farther than 1e-6 from the centre of mass's reading.
    with RunWatch(simulation, 'leaner', tip_angle_rad=math.acos(exact + (gap - 1e-6) / 2),
                  clearance=False) as watch:
        simulation.step()
    assert watch.tipped_ns == simulation.time_ns


def test_a_watchs_regions_are_read_only(make):
    """Regions are fixed when the watch is made: adding one later is refused, not ignored."""
    simulation = make()
    with RunWatch(simulation, regions={'goal': circle_region(1.0, 0.0, 0.2)}) as watch:
        with pytest.raises(TypeError):
            watch.regions['late'] = circle_region(0.0, 0.0, 1.0)
        assert list(watch.regions) == ['goal']
