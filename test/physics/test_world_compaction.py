"""
A world built again in place after many removals: every body exactly as it was, memory back.

PyBullet keeps a loaded URDF's shapes after ``removeBody`` until
``resetSimulation``; ``SimWorld`` compacts itself after
``COMPACT_AFTER_REMOVALS`` removals. A compacted world holds the same body
objects with new ids, each in its state (base pose and twist, joints,
motors) to the last bit, and the runs that follow repeat bit for bit.
"""

import pytest

from r2d2_sim.physics.body import Motor
from r2d2_sim.physics.description import default_urdf_path
from r2d2_sim.physics.world import COMPACT_AFTER_REMOVALS, SimWorld

CUBE = 'cube_small.urdf'  # pybullet_data's
BOX = """<robot name="box"><link name="base"><collision><geometry><box size="0.2 0.2 0.2"/>
</geometry></collision><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"
ixy="0" ixz="0" iyz="0"/></inertial></link></robot>"""


@pytest.fixture
def world():
    """Provide a world with its ground plane; closed after the test."""
    with SimWorld() as built:
        yield built


def driving_robot(world):
    """Load R2D2 and set its wheels turning (velocity motors), as a drive does."""
    robot = world.load_robot(default_urdf_path(), (0.0, 0.0, 0.0))
    wheels = [j.index for j in robot.joints.values() if 'wheel' in j.name]
    robot.set_joint_velocities(wheels, [5.0] * len(wheels), [100.0] * len(wheels))
    return robot


def churn(world, removals):
    """Load and remove a small cube ``removals`` times, stepping once each time."""
    for index in range(removals):
        cube = world.load(CUBE, (3.0, 3.0, 0.5), name=f'churn_{index}')
        world.step()
        world.remove(cube)


def run(world, robot, steps=240):
    """Step ``steps`` times; return the robot's (world state, joint states) at the end."""
    world.step(steps)
    return robot.world_state(), robot.joint_states(robot.movable_indices)


def test_compaction_puts_every_body_back_as_it_was_to_the_last_bit(world, monkeypatch):
    """After the 64th removal: the world rebuilt, the same states and motors; wheels turning."""
    client, rebuilt = world.client, []
    reset_simulation = client.resetSimulation
    monkeypatch.setattr(client, 'resetSimulation', lambda: rebuilt.append(1) or reset_simulation())
    robot = driving_robot(world)
    world.step(120)
    churn(world, COMPACT_AFTER_REMOVALS - 1)
    assert world.removed_since_built == COMPACT_AFTER_REMOVALS - 1
    names_before = set(world.bodies)
    cube = world.load(CUBE, (3.0, 3.0, 0.5), name='last')
    world.step()
    before = robot.moment()
    wheels = [j.index for j in robot.joints.values() if 'wheel' in j.name]
    assert [before[1][i] for i in wheels] == [Motor(5.0, 100.0)] * len(wheels)
    world.remove(cube)  # the 64th: compacted
    assert world.removed_since_built == 0 and rebuilt == [1]
    assert set(world.bodies) == names_before
    state, motors = robot.moment()
    assert (state.com, state.twist, motors) == (before[0].com, before[0].twist, before[1])
    # Joint positions and velocities exactly; efforts are what a step applies: the next one's.
    assert (state.joints.positions, state.joints.velocities) == before[0].joints[:2]
    start = robot.world_state().position
    world.step(240)
    assert robot.world_state().position != start  # the motors drove on


def test_a_moment_holds_the_motor_last_set_on_each_joint(world):
    """Velocity motors, a brake and velocity motors again, on joints overlapping: the last."""
    robot = world.load_robot(default_urdf_path(), (0.0, 0.0, 0.0))
    wheels = [j.index for j in robot.joints.values() if 'wheel' in j.name]
    head = robot.joint('head_swivel').index
    robot.set_joint_velocities(wheels, [5.0] * len(wheels), [100.0] * len(wheels))
    robot.set_joint_velocities(wheels, [3.0] * len(wheels), [90.0] * len(wheels))
    robot.set_joint_velocities([head, wheels[0]], [1.0, 2.0], [10.0, 20.0])
    robot.hold_joints(wheels[1:2], [50.0], [0.25])
    robot.set_joint_velocities(wheels[2:3], [4.0], [40.0])
    _, motors = robot.moment()
    assert len(wheels) == 4 and motors == {
        head: Motor(1.0, 10.0), wheels[0]: Motor(2.0, 20.0), wheels[1]: Motor(0.0, 50.0, 0.25),
        wheels[2]: Motor(4.0, 40.0), wheels[3]: Motor(3.0, 90.0)}


def test_runs_with_compaction_repeat_bit_for_bit():
    """Two worlds, the same steps and removals (one compaction each): the same end."""
    ends = []
    for _ in range(2):
        with SimWorld() as world:
            robot = driving_robot(world)
            churn(world, COMPACT_AFTER_REMOVALS + 5)
            ends.append(run(world, robot))
    assert ends[0] == ends[1]


def test_a_body_whose_file_is_gone_stops_compaction_and_stays(world, tmp_path):
    """A body could not come back from a deleted file: the world is left as it is."""
    urdf = tmp_path / 'box.urdf'
    urdf.write_text(BOX)
    kept = world.load(str(urdf), (1.0, 1.0, 0.5), name='kept')
    urdf.unlink()
    churn(world, COMPACT_AFTER_REMOVALS)
    assert world.removed_since_built == COMPACT_AFTER_REMOVALS  # not rebuilt
    assert kept.alive and not kept.reloadable()
    assert world.compact() is False


def test_motors_a_reset_dropped_are_not_brought_back_by_compaction(world):
    """Wheels at 5 rad/s, then a reset (no motors but the file's): compaction keeps it parked."""
    robot = driving_robot(world)
    world.step(24)
    world.reset()
    parked = robot.world_state().position
    churn(world, COMPACT_AFTER_REMOVALS)
    assert world.removed_since_built == 0  # compacted
    world.step(240)
    moved = max(abs(a - b) for a, b in zip(robot.world_state().position, parked))
    assert moved < 0.005, f'moved {moved:.3f} m'


def test_braked_wheels_are_braked_again_at_the_angles_they_held(world):
    """A brake (hold_joints) comes back from compaction as it was: the same angles held."""
    robot = driving_robot(world)
    wheels = [j.index for j in robot.joints.values() if 'wheel' in j.name]
    world.step(120)
    robot.hold_joints(wheels, [100.0] * len(wheels))
    world.step(240)
    _, before = robot.moment()
    parked = robot.world_state().position
    churn(world, COMPACT_AFTER_REMOVALS)
    assert world.removed_since_built == 0  # compacted
    _, motors = robot.moment()
    assert motors == before and all(motors[i].held is not None for i in wheels)
    world.step(240)
    moved = max(abs(a - b) for a, b in zip(robot.world_state().position, parked))
    assert moved < 1e-4, f'moved {moved * 1e3:.3f} mm'
