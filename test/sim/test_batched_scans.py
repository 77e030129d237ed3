"""
Every robot's rays of a step cast together give each robot the scan it would get alone.

The simulation now collects all robots' laser and 3D lidar rays of a step
and casts them together (a call per robot, its laser and lidar sharing it);
before, each sensor's scan was a call of its own (``LaserScanner.scan``,
kept). On the same world, right after the step that measured them, the
batched scans must equal the per-sensor ones bit for bit: robots close
enough to see each other, and some far from the rest.
"""

import numpy

ROOM = 'package://r2d2_sim/urdf/room.urdf'
POSES = {'a': [0.0, 0.0, 0.0], 'b': [1.0, 1.5, 2.0], 'c': [-1.5, -1.0, -0.5],
         'd': [40.0, 0.0, 1.0], 'e': [0.0, 45.0, 3.0], 'f': [42.0, 1.0, 0.0]}


def fleet(**extra):
    parameters = {'world': ROOM, 'robots': list(POSES), **extra}
    parameters.update({f'{name}.initial_pose': pose for name, pose in POSES.items()})
    return parameters


def scans_step(simulation):
    """Step until scans are due; return that step's measurements."""
    while True:
        result = simulation.step()
        if result is not None and any(m is not None and m.scan is not None
                                      for m in result.measurements):
            return result.measurements


def test_batched_scans_are_the_per_robot_scans_bit_for_bit(make):
    simulation = make(**fleet(cmd_vel_timeout=0.0))
    for robot in simulation.robots:
        robot.command(0.3, 0.5)
    for _ in range(3):  # three scan steps, the robots moving between them
        measurements = scans_step(simulation)
        for robot, measurement in zip(simulation.robots, measurements):
            alone = robot.laser.scan()  # a call of its own, as every scan was before
            assert measurement.scan.tobytes() == alone.tobytes(), robot.name
            # In the room, or near another robot, a robot sees something.
            assert numpy.isfinite(alone).any() == (robot.name != 'e'), robot.name


def test_batched_lidar_points_are_the_per_robot_points_bit_for_bit(make):
    simulation = make(**fleet(lidar3d_rate=10.0, lidar3d_rings=8, lidar3d_samples=180))
    measurements = scans_step(simulation)
    for robot, measurement in zip(simulation.robots, measurements):
        assert measurement.lidar.tobytes() == robot.lidar.scan().tobytes(), robot.name


def test_scans_cast_on_two_threads_are_the_scans_on_one_bit_for_bit(make, monkeypatch):
    """ray_threads 2 against 1 (the core's auto), the same drive: every scan and lidar alike."""
    extra = dict(cmd_vel_timeout=0.0, lidar3d_rate=10.0, lidar3d_rings=4, lidar3d_samples=90)
    one, two = make(**fleet(**extra)), make(**fleet(ray_threads=2, **extra))
    assert (one.world.ray_threads, two.world.ray_threads) == (1, 2)
    threads = {}  # each world's calls: (rays, numThreads), as PyBullet was asked
    for name, simulation in (('one', one), ('two', two)):
        client, calls = simulation.world.client, threads.setdefault(name, [])

        def noted(starts, ends, *, _cast=client.rayTestBatch, _calls=calls, **kwargs):
            _calls.append((len(starts), kwargs.get('numThreads', 1)))
            return _cast(starts, ends, **kwargs)
        monkeypatch.setattr(client, 'rayTestBatch', noted)
    for simulation in (one, two):
        for robot in simulation.robots:
            robot.command(0.3, 0.5)
    for _ in range(3):
        for a, b in zip(scans_step(one), scans_step(two)):
            assert a.scan.tobytes() == b.scan.tobytes()
            assert a.lidar.tobytes() == b.lidar.tobytes()
    # A call per robot and step (its laser's 360 rays and its lidar's 360): two threads each.
    assert threads['one'] == [(720, 1)] * 18 and threads['two'] == [(720, 2)] * 18
