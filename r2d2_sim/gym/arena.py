"""
One world for many episodes: its pool of boxes, a state saved once, each episode placed in it.

No ROS. An :class:`Arena` is built once on a
:class:`~r2d2_sim.sim.simulation.Simulation` (in this process, or inside the
simulator node of the ``ros`` backend, under its lock): it spawns the
boxes every episode may need, parked under the ground, and saves the
world's state. Each episode (:meth:`Arena.start`) restores that state
(:meth:`Simulation.restore_state <r2d2_sim.sim.simulation.Simulation.restore_state>`:
no body is loaded again, and a run after it repeats any other run from it
bit for bit), starts the noise streams from the episode's seed, places the
robots and the boxes the episode draws, and watches each robot
(:class:`~r2d2_sim.sim.oracles.RunWatch`: its goal, contacts, a fall). A
world drawn from the farm's scenario space is an :class:`Episode`
(:func:`episode_of`).
"""

import dataclasses
import math
from typing import List, NamedTuple, Optional, Sequence, Tuple

from r2d2_sim.errors import WorldError
from r2d2_sim.farm.scenario import Box, Pose, Scenario, ScenarioSpace
from r2d2_sim.gym.task import Outcome, Reading
from r2d2_sim.model.regions import circle_region, Region
from r2d2_sim.sim.oracles import RunWatch
from r2d2_sim.sim.robots.robot import Measurement
from r2d2_sim.sim.simulation import SavedState, Simulation, SpawnRequest
from r2d2_sim.sim.spawnables import box_urdf

__all__ = ['Arena', 'Episode', 'episode_of', 'placed_scenarios', 'reading_of', 'GOAL',
           'PARKED_DEPTH_M']

# The goal region's name in each robot's watch.
GOAL = 'goal'
# Boxes an episode does not use wait this far under the ground, each 1 m below the last:
# out of every ray's and every body's way (static bodies make no pairs with the ground).
PARKED_DEPTH_M = 10.0
ZERO = (0.0, 0.0, 0.0)


class Episode(NamedTuple):
    """
    One episode's world: where each robot starts and must go, and where the boxes stand.

    One noise for the whole world: every robot's streams start from
    ``noise_seed`` (each its own stream, by its name) and every laser has
    ``scan_noise_std``.
    """

    scenarios: Tuple[Scenario, ...]     # each robot's draw (its seed, as the farm has it)
    starts: Tuple[Pose, ...]            # each robot's start, in its lane
    goals: Tuple[Region, ...]           # each robot's goal (a circle), in its lane
    obstacles: Tuple[Box, ...]          # the boxes placed, box_0, box_1...
    noise_seed: int                     # every noise stream of the episode starts from it
    scan_noise_std: float               # every laser's range noise (m)
    owners: Tuple[int, ...] = ()        # the robot whose draw placed each box (() not known)

    def goal_points(self) -> List[Tuple[float, float]]:
        """Return each robot's goal centre."""
        return [(goal.values[0], goal.values[1]) for goal in self.goals]


def _shifted(box: Box, dy: float) -> Box:
    return Box(box.x, box.y + dy, box.yaw, box.size)


def episode_of(space: ScenarioSpace, seeds: Sequence[int], lanes: Sequence[float]) -> Episode:
    """
    Return the episode of one draw of ``space`` per robot (``seeds``), each in its lane.

    Robot i starts and heads for its draw's start and goal shifted by
    ``lanes[i]`` along y, among its draw's boxes shifted with them; boxes
    that come within the space's ``keep_out`` of any robot's start or goal
    are left out. The first draw's seed and scan noise are the world's noise
    (one world, one noise: :class:`Episode`).
    """
    scenarios = tuple(space.draw(int(seed)) for seed in seeds)
    starts = tuple(Pose(s.start.x, s.start.y + dy, s.start.yaw)
                   for s, dy in zip(scenarios, lanes))
    goals = tuple(circle_region(s.goal.values[0], s.goal.values[1] + dy, s.goal.values[2])
                  for s, dy in zip(scenarios, lanes))
    boxes = [(index, _shifted(box, dy)) for index, (s, dy) in enumerate(zip(scenarios, lanes))
             for box in s.obstacles]
    if len(scenarios) > 1:
        boxes = [(index, box) for index, box in boxes
                 if all(space.clear(box, start, (goal.values[0], goal.values[1]))
                        for start, goal in zip(starts, goals))]
    first = scenarios[0]
    return Episode(scenarios, starts, goals, tuple(box for _, box in boxes), first.seed,
                   first.scan_noise_std, tuple(index for index, _ in boxes))


def placed_scenarios(episode: Episode) -> List[Scenario]:
    """
    Return each robot's lane as the episode placed it: a scenario a one-robot env replays.

    Its draw's start and goal shifted into the lane, the boxes its draw placed
    there (those too near any robot's start or goal left out), and the
    episode's noise: the seed and scan noise every laser ran with. At most the
    space's boxes, so ``R2D2Nav-v0`` made with the same space replays it: this
    robot's task without the other robots and their lanes' boxes. (An episode
    without ``owners`` gives every robot every box.)
    """
    placed = []
    for index, (scenario, start, goal) in enumerate(zip(episode.scenarios, episode.starts,
                                                        episode.goals)):
        boxes = tuple(box for box, owner in zip(episode.obstacles, episode.owners)
                      if owner == index) if episode.owners else episode.obstacles
        placed.append(dataclasses.replace(scenario, start=start, goal=goal, obstacles=boxes,
                                          seed=episode.noise_seed,
                                          scan_noise_std=episode.scan_noise_std))
    return placed


def reading_of(measurement: Optional[Measurement]) -> Reading:
    """Return a robot's reading from the measurement of a control period's last step."""
    frame = measurement.frame if measurement is not None else None
    scan = measurement.scan if measurement is not None else None
    if frame is None or scan is None:
        raise RuntimeError('the control period ended on a step without the state and the scan')
    base = frame.base
    return Reading(scan, base.position, base.orientation, base.linear_velocity,
                   base.angular_velocity)


def _yaw_quaternion(yaw: float) -> Tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))


class Arena:
    """
    The world an environment's episodes run in: the boxes' pool, the saved state, the watches.

    ``simulation`` is the world (its robots loaded at start-up); ``pool``
    boxes of ``box_size`` (x, y, height) are spawned into it, parked, named
    ``box_0``, ``box_1``...; ``tip_angle_rad`` is a fall. Build it, and call
    :meth:`start` and :meth:`outcomes`, where nothing else steps the world.
    """

    def __init__(self, simulation: Simulation, pool: int,
                 box_size: Tuple[float, float, float], tip_angle_rad: float) -> None:
        self.simulation = simulation
        self.box_size = box_size
        self.tip_angle_rad = tip_angle_rad
        self.boxes = [f'box_{i}' for i in range(pool)]
        text = box_urdf(box_size, name='box')
        for index, name in enumerate(self.boxes):
            simulation.spawn(SpawnRequest(name, resource_string=text,
                                          position=self._parked(index)))
        # Each robot stands as start-up put it: an episode keeps that height and lean.
        self._rest = [robot.body.world_state() for robot in simulation.robots]
        self.saved: Optional[SavedState] = simulation.save_state()
        self.watches: List[RunWatch] = []

    @staticmethod
    def _parked(index: int) -> Tuple[float, float, float]:
        return (0.0, 0.0, -PARKED_DEPTH_M - index)

    def start(self, episode: Episode) -> List[Reading]:
        """
        Begin an episode: the saved state back, its noise, its robots and boxes placed; read.

        Returns each robot's reading now (a scan cast at once, the true state),
        as the first observation. ValueError for more boxes than the pool holds
        or more starts than robots.
        """
        simulation = self.simulation
        robots = simulation.robots
        if len(episode.obstacles) > len(self.boxes) or len(episode.starts) != len(robots):
            raise ValueError(f'the episode has {len(episode.obstacles)} boxes and '
                             f'{len(episode.starts)} robots; the world {len(self.boxes)} and '
                             f'{len(robots)}')
        self._close_watches()
        if self.saved is None:
            raise ValueError('the arena is closed')
        try:
            simulation.restore_state(self.saved)
        except WorldError:
            self._rebuild()
        simulation.restart_noise(episode.noise_seed, scan_noise_std=episode.scan_noise_std)
        for robot, start, rest in zip(robots, episode.starts, self._rest):
            yaw = start.yaw - robot.body.body_yaw_offset_rad  # of the URDF's base link
            simulation.set_entity_state(robot.name, '', (start.x, start.y, rest.position[2]),
                                        _yaw_quaternion(yaw), ZERO, ZERO)
        height = self.box_size[2] / 2.0
        for name, box in zip(self.boxes, episode.obstacles):
            simulation.set_entity_state(name, '', (box.x, box.y, height),
                                        _yaw_quaternion(box.yaw), ZERO, ZERO)
        self.watches = [RunWatch(simulation, robot.name, regions={GOAL: goal},
                                 tip_angle_rad=self.tip_angle_rad, clearance=False)
                        for robot, goal in zip(robots, episode.goals)]
        return self.observe()

    def _rebuild(self) -> None:
        """
        Build the world again as at construction, save and restore it: the old state refused.

        A blow-up loads the bodies it broke again (``SimWorld.put_back``),
        and the state saved before then cannot come back. A state reset
        loads every body again in its order, each robot at rest where it
        started and each box parked where it was spawned: the world as
        :meth:`__init__` saved it, and the episodes after it are those of
        a new arena, bit for bit.
        """
        simulation = self.simulation
        if self.saved is not None:
            simulation.forget_state(self.saved)
        self.saved = None
        simulation.reset(state=True)
        self.saved = simulation.save_state()
        simulation.restore_state(self.saved)

    def observe(self) -> List[Reading]:
        """Return every robot's reading now: its laser cast at once, its true state."""
        simulation = self.simulation
        robots = simulation.robots
        requests = [robot.laser.rays() for robot in robots if robot.laser is not None]
        if len(requests) != len(robots):
            raise ValueError('every robot needs its laser (scan_rate > 0)')
        answers = simulation.world.cast_requests(requests)
        readings = []
        for robot, fractions in zip(robots, answers):
            base = robot.body.base_state()
            scan = robot.laser.ranges(fractions)  # type: ignore[union-attr]
            readings.append(Reading(scan, base.position, base.orientation,
                                    base.linear_velocity, base.angular_velocity))
        return readings

    def outcomes(self) -> List[Outcome]:
        """Return what each robot's watch saw since the episode began: goal, contact, fall."""
        return [Outcome(GOAL in watch.reached,
                        watch.contacts[0].other if watch.contacts else '',
                        watch.tipped_ns is not None) for watch in self.watches]

    def _close_watches(self) -> None:
        for watch in self.watches:
            watch.close()
        self.watches = []

    def close(self) -> None:
        """Stop watching and free the saved state; safe to call twice."""
        self._close_watches()
        if self.saved is not None and self.simulation.world.connected:
            self.simulation.forget_state(self.saved)
        self.saved = None
