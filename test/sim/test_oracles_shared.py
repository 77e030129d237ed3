"""
What the farm added to the run oracles, each checked against a plain computation.

One contact reading for the watch and the contacts topic, a trajectory on a
fixed grid of simulated time, and a clearance still exact when cheaper.

As in test_oracles.py: 0.2 m boxes, commands at once (no acceleration limit),
R2D2's gripper 0.515 m ahead of its base link.
"""

import math

import pytest

from r2d2_sim.sim.oracles import RunWatch, touching
from r2d2_sim.sim.simulation import SpawnRequest
from r2d2_sim.sim.spawnables import box_urdf

SIMULATION_DEFAULTS = {'scan_rate': 0.0, 'imu_rate': 0.0, 'cmd_vel_timeout': 0.0,
                       'max_linear_acceleration': 0.0, 'max_angular_acceleration': 0.0}


def place_box(simulation, name, x, y=0.0, sizes=(0.2, 0.2, 0.2)):
    """Spawn a fixed box standing at (x, y)."""
    return simulation.spawn(SpawnRequest(
        name, resource_string=box_urdf(sizes, name=name), position=(x, y, sizes[2] / 2)))


def run(simulation, steps):
    for _ in range(steps):
        simulation.step()


def test_the_trajectory_is_where_the_base_was_every_period(make):
    """At 0.3 m/s along x, sampled every 0.1 s: the start, then 0.03 m further each time."""
    simulation = make()
    run(simulation, 10)  # the watch starts at a time that is no multiple of the period
    start_ns = simulation.time_ns
    with RunWatch(simulation, trajectory_period_s=0.1) as watch:
        simulation.robot.command(0.3, 0.0)
        run(simulation, 240)
    times = [point.time_ns for point in watch.trajectory]
    assert times == [start_ns + simulation.clock.time_ns(24 * k) for k in range(11)]
    xs = [point.x_m for point in watch.trajectory]
    assert xs[0] == pytest.approx(0.0, abs=1e-3)
    assert xs[10] - xs[5] == pytest.approx(0.15, abs=0.01)  # 0.5 s at speed
    assert xs == sorted(xs)
    assert all(abs(point.yaw_rad) < 0.01 and abs(point.y_m) < 0.01 for point in watch.trajectory)


@pytest.mark.parametrize('period_s', [0.0, -1.0, math.nan])
def test_a_trajectory_period_that_is_none_is_refused(make, period_s):
    """A period of 0, below 0 or NaN: a ValueError naming it."""
    with pytest.raises(ValueError, match='trajectory_period_s'):
        RunWatch(make(), trajectory_period_s=period_s)


def test_the_watch_and_touching_read_contacts_alike(make):
    """At the step a contact starts, touching() names the same body, links and point."""
    simulation = make()
    place_box(simulation, 'wall', 1.115 + 0.1, sizes=(0.2, 2.0, 1.0))
    robot = simulation.robot
    seen = []
    simulation.watch_steps(lambda time_ns: seen.append(
        (time_ns, touching(simulation.world, robot.body))))
    with RunWatch(simulation) as watch:
        robot.command(0.3, 0.0)
        run(simulation, 720)
    contact = watch.contacts[0]
    at_start = dict(seen)[contact.start_ns]
    assert [touch.other for touch in at_start] == ['wall']
    touch = at_start[0]
    assert (touch.link, touch.other_link, touch.position) == (
        contact.robot_link, contact.other_link, contact.position)
    assert 0.0 < touch.normal_force_n <= contact.max_normal_force_n  # the largest comes later
    assert all(touches == [] for time_ns, touches in seen if time_ns < contact.start_ns)


def test_the_clearance_is_the_smallest_of_every_step_over_the_whole_range(make):
    """Driving past two boxes: the watch's clearance equals a brute-force minimum per step."""
    simulation = make()
    place_box(simulation, 'near', 1.2, 0.55)
    place_box(simulation, 'far', 2.0, -0.9)
    robot = simulation.robot
    others = [(name, body) for name, body in simulation.world.bodies.items()
              if name in ('near', 'far')]
    brute = []

    def every_body(time_ns):
        for name, body in others:
            nearest = robot.body.closest_points(body, 2.0)
            if nearest is not None:
                brute.append((nearest.distance_m, time_ns, name))
    simulation.watch_steps(every_body)
    with RunWatch(simulation) as watch:
        robot.command(0.3, 0.0)
        run(simulation, 1200)
    distance, time_ns, name = min(brute)
    assert watch.clearance == (distance, name, time_ns)
    assert 0.0 < distance < 0.3 and name == 'near'


def test_contacts_are_measured_with_each_state_only_when_asked(make):
    """publish_contacts: each frame's measurement carries what the robot touches."""
    quiet = make()
    measured = [quiet.step() for _ in range(5)]
    assert all(m.measurements[0].contacts is None for m in measured)
    simulation = make(publish_contacts=True, publish_rate=60.0)
    place_box(simulation, 'wall', 1.115 + 0.1, sizes=(0.2, 2.0, 1.0))
    simulation.robot.command(0.3, 0.0)
    results = [r for r in (simulation.step() for _ in range(720)) if r is not None]
    contacts = [r.measurements[0].contacts for r in results if r.state_due]
    assert len(contacts) == 180 and contacts[0] == ()
    touched = [c for c in contacts if c]
    assert touched and all(c[0].other == 'wall' for c in touched)
    assert all(m.contacts is None for r in results if not r.state_due
               for m in r.measurements if m is not None)
