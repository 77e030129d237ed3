"""
Scenarios: one variation of a world (obstacles, start, goal, seed, limits) as plain data.

No ROS, no physics. A :class:`Scenario` is frozen and serializes to JSON and
back exactly (floats as Python writes them, which read back to the same
bits), so a report's line is the scenario itself. A :class:`ScenarioSpace`
says what varies and within which ranges; :meth:`ScenarioSpace.draw` turns a
seed into one scenario with numpy's ``Generator`` (PCG64): the same seed
gives the same scenario on any machine with the same numpy. The Hypothesis
strategies drawing from the same space are in :mod:`r2d2_sim.farm.strategies`.

Lengths are in metres, angles in radians, in the world frame. Drawn values
are whole millimetres and milliradians: short in a report, and what
Hypothesis shrinks toward round numbers.

A start or a goal may be a named pose of the scenario's world (the
simulation standard's: a manifest's ``named_poses``, an SDF world's
``<frame>`` s): :meth:`Scenario.named` and the space's ``start_pose`` and
``goal_pose`` take names. The scenario keeps the numbers the name stood for
(its JSON replays without the world file) and the name beside them
(``start_name``, ``goal_name``) for the report. Names are read from the
world file by :mod:`r2d2_sim.farm.places`, imported only then.
"""

from dataclasses import dataclass, field
import json
import math
from typing import Any, Dict, Iterator, Mapping, Sequence, Tuple

import numpy

from r2d2_sim.errors import ScenarioError
from r2d2_sim.model.regions import box_region, circle_region, Region

__all__ = ['Box', 'Pose', 'Scenario', 'ScenarioSpace', 'ScenarioError', 'ROOM', 'LIMITS',
           'footprint_distance']

# The package's own room: four walls and three boxes (urdf/room.urdf).
ROOM = 'package://r2d2_sim/urdf/room.urdf'
# The robot limits a scenario may set: simulator parameters of the same names.
LIMITS = ('max_linear_velocity', 'max_angular_velocity', 'max_linear_acceleration',
          'max_angular_acceleration')
# Version of the JSON written; read back only when it matches.
FORMAT = 1
# The largest laser range noise (m) the simulator takes (its scan_noise_std parameter).
MAX_SCAN_NOISE_STD = 10.0
# Random positions are tried this often per obstacle before it is left out.
PLACEMENT_ATTEMPTS = 50
# The most boxes a scenario may have: each is a body in the world (and a learning
# environment spawns its most, times its robots, once); more is a typo, not a design.
MAX_OBSTACLES = 1000


def _finite(name: str, *values: float) -> Tuple[float, ...]:
    numbers = tuple(float(v) for v in values)
    if not all(math.isfinite(v) for v in numbers):
        raise ScenarioError(f'{name} must be finite numbers, got {values}')
    return numbers


def _size(values: Sequence[Any]) -> Tuple[float, float, float]:
    """Return a box's size read from JSON: three numbers (ScenarioError otherwise)."""
    try:
        x, y, z = (float(v) for v in values)
    except (TypeError, ValueError):
        raise ScenarioError(f'a box size is three numbers, not {values!r:.60}') from None
    return x, y, z


@dataclass(frozen=True)
class Pose:
    """Where the robot starts: x, y (m) and yaw (rad, 0 along +x) in the world."""

    x: float
    y: float
    yaw: float = 0.0

    def __post_init__(self) -> None:
        _finite('a pose', self.x, self.y, self.yaw)


@dataclass(frozen=True)
class Box:
    """A fixed box standing on the ground: centre x, y, yaw, and size (x, y, height)."""

    x: float
    y: float
    yaw: float
    size: Tuple[float, float, float]

    def __post_init__(self) -> None:
        _finite('a box', self.x, self.y, self.yaw, *self.size)
        if len(self.size) != 3 or min(self.size) <= 0.0:
            raise ScenarioError(f'a box needs three sizes > 0, got {self.size}')
        object.__setattr__(self, 'size', tuple(float(v) for v in self.size))

    def corners(self) -> Tuple[Tuple[float, float], ...]:
        """Return the footprint's four corners, counter-clockwise."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        hx, hy = self.size[0] / 2.0, self.size[1] / 2.0
        return tuple((self.x + c * dx - s * dy, self.y + s * dx + c * dy)
                     for dx, dy in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy)))


def footprint_distance(box: Box, x: float, y: float) -> float:
    """Return the distance (m) from (x, y) to the box's footprint; 0 inside it."""
    dx, dy = x - box.x, y - box.y
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    local_x, local_y = c * dx + s * dy, -s * dx + c * dy
    return math.hypot(max(abs(local_x) - box.size[0] / 2.0, 0.0),
                      max(abs(local_y) - box.size[1] / 2.0, 0.0))


@dataclass(frozen=True)
class Scenario:
    """
    One variation: what stands where, where the robot starts and must go, and its seed.

    - ``obstacles``: fixed boxes, spawned ``box_0``, ``box_1``... in this order;
    - ``start``: the robot's initial pose; ``goal``: a region of
      :mod:`r2d2_sim.model.regions` (a circle around a goal point is a pose
      with a position tolerance);
    - ``seed``: the simulator's ``noise_seed`` and the seed of anything random
      in the run (a controller may draw from it), 0 to 2**31 - 1;
    - ``world``: the simulator's ``world`` (a URDF such as ``ROOM``, a world
      manifest, an SDF world), '' none;
    - ``limits``: robot limits, (name, value) pairs of :data:`LIMITS`
      (simulator parameters), others left at the simulator's defaults;
    - ``scan_noise_std``: the laser's range noise (m);
    - ``start_name``, ``goal_name``: the world's named poses the start and
      the goal were taken from ('' none), for the reader only: the run uses
      the numbers.
    """

    obstacles: Tuple[Box, ...] = ()
    start: Pose = Pose(0.0, 0.0, 0.0)
    goal: Region = field(default_factory=lambda: circle_region(1.0, 0.0, 0.2))
    seed: int = 0
    world: str = ''
    limits: Tuple[Tuple[str, float], ...] = ()
    scan_noise_std: float = 0.0
    start_name: str = ''
    goal_name: str = ''

    @classmethod
    def named(cls, world: str, start: str = '', goal: str = '', goal_tolerance: float = 0.3,
              **others: Any) -> 'Scenario':
        """
        Return a scenario in ``world`` whose start and goal are its named poses.

        ``start``: the robot stands at that pose, facing its way; ``goal``: a
        circle of ``goal_tolerance`` (m) around that pose. Either may be left
        out (``start`` then defaults to ``Pose()``, ``goal`` to the default
        goal) or given as numbers in ``others``. ScenarioError (one line) for
        a name the world does not have, listing those it has.
        """
        if start:
            others['start'] = Pose(*_named(world, start))
            others['start_name'] = start
        if goal:
            x, y, _ = _named(world, goal)
            others['goal'] = circle_region(x, y, goal_tolerance)
            others['goal_name'] = goal
        return cls(world=world, **others)

    def __post_init__(self) -> None:
        object.__setattr__(self, 'obstacles', tuple(self.obstacles))
        if not all(isinstance(b, Box) for b in self.obstacles):
            raise ScenarioError('obstacles must be Box objects')
        if not isinstance(self.start, Pose):
            raise ScenarioError(f'start must be a Pose, got {self.start!r}')
        if not isinstance(self.goal, Region) or self.goal.kind not in ('box', 'circle'):
            raise ScenarioError(f'goal must be a box_region or circle_region, got {self.goal!r}')
        if not (isinstance(self.seed, int) and 0 <= self.seed <= 2**31 - 1):
            raise ScenarioError(f'seed must be an integer in 0..2**31-1, got {self.seed!r}')
        limits = tuple(sorted((str(k), float(v)) for k, v in dict(self.limits).items()))
        for name, value in limits:
            if name not in LIMITS or not (math.isfinite(value) and value >= 0.0):
                raise ScenarioError(f'limits: {name}={value} is not one of {", ".join(LIMITS)} '
                                    '>= 0')
        object.__setattr__(self, 'limits', limits)
        _finite('scan_noise_std', self.scan_noise_std)
        if not (isinstance(self.start_name, str) and isinstance(self.goal_name, str)):
            raise ScenarioError('start_name and goal_name must be strings')

    @property
    def goal_point(self) -> Tuple[float, float]:
        """Return the goal region's centre: where a controller would head."""
        values = self.goal.values
        if self.goal.kind == 'circle':
            return values[0], values[1]
        return (values[0] + values[2]) / 2.0, (values[1] + values[3]) / 2.0

    def parameters(self) -> Dict[str, Any]:
        """Return the simulator parameters this scenario sets (pose, seed, world, limits)."""
        parameters: Dict[str, Any] = {
            'initial_pose': _initial_pose(self.world, self.start),
            'noise_seed': self.seed, 'world': self.world,
            'scan_noise_std': self.scan_noise_std}
        parameters.update(self.limits)
        return parameters

    # -- JSON ------------------------------------------------------------------------

    def to_dict(self) -> Dict[str, Any]:
        """Return the scenario as JSON-ready data (see :meth:`from_dict`)."""
        return {'format': FORMAT, 'seed': self.seed, 'world': self.world,
                'start': {'x': self.start.x, 'y': self.start.y, 'yaw': self.start.yaw},
                'goal': {'kind': self.goal.kind, 'values': list(self.goal.values)},
                'obstacles': [{'x': b.x, 'y': b.y, 'yaw': b.yaw, 'size': list(b.size)}
                              for b in self.obstacles],
                'limits': dict(self.limits), 'scan_noise_std': self.scan_noise_std,
                **{key: name for key, name in (('start_name', self.start_name),
                                               ('goal_name', self.goal_name)) if name}}

    def to_json(self) -> str:
        """Return the scenario as one line of JSON; :meth:`from_json` reads it back equal."""
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> 'Scenario':
        """Read :meth:`to_dict`'s data; ScenarioError (one line) for anything else."""
        try:
            if data.get('format') != FORMAT:
                raise ScenarioError(f'scenario format {data.get("format")!r}, expected {FORMAT}')
            goal = data['goal']
            values = [float(v) for v in goal['values']]
            region = (box_region(*values) if goal['kind'] == 'box'
                      else circle_region(*values[:3]))
            start = data['start']
            return cls(obstacles=tuple(Box(float(b['x']), float(b['y']), float(b['yaw']),
                                           _size(b['size']))
                                       for b in data['obstacles']),
                       start=Pose(float(start['x']), float(start['y']), float(start['yaw'])),
                       goal=region, seed=data['seed'], world=str(data['world']),
                       limits=tuple(dict(data['limits']).items()),
                       scan_noise_std=float(data['scan_noise_std']),
                       start_name=data.get('start_name', ''), goal_name=data.get('goal_name', ''))
        except ScenarioError:
            raise
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ScenarioError(f'not a scenario: {type(exc).__name__} {exc}') from None

    @classmethod
    def from_json(cls, text: str) -> 'Scenario':
        """Read :meth:`to_json`'s text; ScenarioError (one line) for anything else."""
        try:
            data = json.loads(text)
        except ValueError as exc:
            raise ScenarioError(f'not JSON: {exc}') from None
        if not isinstance(data, dict):
            raise ScenarioError('not a scenario: a JSON object expected')
        return cls.from_dict(data)


def _range(name: str, values: Sequence[float], count: int) -> Tuple[float, ...]:
    numbers = _finite(name, *values)
    if len(numbers) != count:
        raise ScenarioError(f'{name} needs {count} numbers, got {len(numbers)}')
    return numbers


@dataclass(frozen=True)
class ScenarioSpace:
    """
    What varies between scenarios, and within which ranges (a farm's design).

    - ``obstacles``: how many boxes, (fewest, most), at most :data:`MAX_OBSTACLES`;
    - ``area``: where their centres go, (x_min, y_min, x_max, y_max);
    - ``box_size``: each footprint side, (smallest, largest); ``box_yaw``
      (lowest, highest); ``box_height``;
    - ``start_area`` and ``start_yaw`` (lowest, highest): the robot's start;
    - ``goal_area``: where the goal's centre goes; ``goal_tolerance``: the
      goal circle's radius;
    - ``keep_out``: no box's footprint comes nearer than this to the start or
      the goal's centre (the robot must fit, the goal must be reachable);
    - ``world`` (read when the space is made: a world the simulator would
      refuse is a ScenarioError here), ``limits`` ((name, (low, high)) pairs,
      drawn each), ``scan_noise_std`` (low, high; within 0 and 10 m, as
      the simulator takes it);
    - ``start_pose``, ``goal_pose``: named poses of ``world`` standing for
      the drawn start (``start_area``, ``start_yaw``) and goal centre
      (``goal_area``; the circle keeps ``goal_tolerance``). The areas are
      still drawn from, and the draws dropped, so the other draws keep their
      order; boxes keep out of the named poses.

    Anything else (a range not a pair, a NaN or infinite number, a negative
    ``keep_out``) is a ScenarioError of one line when the space is made.
    """

    obstacles: Tuple[int, int] = (0, 5)
    area: Tuple[float, float, float, float] = (0.5, -1.5, 2.5, 1.5)
    box_size: Tuple[float, float] = (0.2, 0.6)
    box_yaw: Tuple[float, float] = (-math.pi / 2, math.pi / 2)
    box_height: float = 0.5
    start_area: Tuple[float, float, float, float] = (-0.2, -0.2, 0.2, 0.2)
    start_yaw: Tuple[float, float] = (-0.3, 0.3)
    goal_area: Tuple[float, float, float, float] = (3.0, -1.0, 3.5, 1.0)
    goal_tolerance: float = 0.3
    keep_out: float = 0.6
    world: str = ''
    limits: Tuple[Tuple[str, Tuple[float, float]], ...] = ()
    scan_noise_std: Tuple[float, float] = (0.0, 0.0)
    start_pose: str = ''
    goal_pose: str = ''

    def __post_init__(self) -> None:
        if self.world:
            _check_world(self.world)  # a missing world fails here, once, not in every run
        if self.start_pose:
            _named(self.world, self.start_pose)  # and so does a wrong name
        if self.goal_pose:
            _named(self.world, self.goal_pose)
        counts = self.obstacles
        if not (isinstance(counts, (tuple, list)) and len(counts) == 2
                and all(isinstance(c, int) and not isinstance(c, bool) for c in counts)
                and 0 <= counts[0] <= counts[1] <= MAX_OBSTACLES):
            raise ScenarioError(f'obstacles must be (fewest, most), 0 <= fewest <= most <= '
                                f'{MAX_OBSTACLES}, got {self.obstacles!r}')
        for name in ('area', 'start_area', 'goal_area'):
            x_min, y_min, x_max, y_max = _range(name, getattr(self, name), 4)
            if x_min > x_max or y_min > y_max:
                raise ScenarioError(f'{name} must be (x_min, y_min, x_max, y_max), got '
                                    f'{getattr(self, name)}')
        for name in ('box_size', 'box_yaw', 'start_yaw', 'scan_noise_std'):
            lowest, highest = _range(name, getattr(self, name), 2)
            if lowest > highest:
                raise ScenarioError(f'{name} must be (lowest, highest), got '
                                    f'{getattr(self, name)}')
        for name in ('box_height', 'goal_tolerance', 'keep_out'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ScenarioError(f'{name} must be a finite number, got {value!r}')
        if self.box_size[0] <= 0.0 or self.box_height <= 0.0 or self.goal_tolerance <= 0.0:
            raise ScenarioError('box_size, box_height and goal_tolerance must be > 0')
        if self.keep_out < 0.0:
            raise ScenarioError(f'keep_out must be >= 0, got {self.keep_out}')
        if not 0.0 <= self.scan_noise_std[0] <= self.scan_noise_std[1] <= MAX_SCAN_NOISE_STD:
            raise ScenarioError(f'scan_noise_std must be (lowest, highest) within 0 and '
                                f'{MAX_SCAN_NOISE_STD:g} m (the simulator\'s), got '
                                f'{self.scan_noise_std}')
        if not isinstance(self.limits, (tuple, list)):
            raise ScenarioError(f'limits must be (name, (low, high)) pairs, got '
                                f'{type(self.limits).__name__} {self.limits!r:.80}')
        for limit in self.limits:
            try:
                name, (lowest, highest) = limit
                bad = name not in LIMITS or not 0.0 <= lowest <= highest < math.inf
            except (TypeError, ValueError):
                bad = True
            if bad:
                raise ScenarioError(f'limits: {limit!r:.60} is not (name, (low, high)) with a '
                                    f'name of {", ".join(LIMITS)} and 0 <= low <= high, finite')

    def clear(self, box: Box, start: Pose, goal: Tuple[float, float]) -> bool:
        """Return True when ``box`` keeps ``keep_out`` from the start and the goal's centre."""
        return (footprint_distance(box, start.x, start.y) >= self.keep_out
                and footprint_distance(box, *goal) >= self.keep_out)

    def scenario(self, obstacles: Sequence[Box], start: Pose, goal: Tuple[float, float],
                 seed: int, limits: Sequence[Tuple[str, float]] = (),
                 scan_noise_std: float = 0.0) -> Scenario:
        """
        Return the scenario of these draws: the boxes that keep out of start and goal.

        A named ``start_pose`` or ``goal_pose`` stands for the drawn ``start`` or ``goal``.
        """
        start, goal = self._named_ends(start, goal)
        return Scenario(obstacles=tuple(b for b in obstacles if self.clear(b, start, goal)),
                        start=start, goal=circle_region(goal[0], goal[1], self.goal_tolerance),
                        seed=seed, world=self.world, limits=tuple(limits),
                        scan_noise_std=scan_noise_std, start_name=self.start_pose,
                        goal_name=self.goal_pose)

    def _named_ends(self, start: Pose, goal: Tuple[float, float]
                    ) -> Tuple[Pose, Tuple[float, float]]:
        """Return the start and the goal's centre, the named poses standing for the drawn."""
        if self.start_pose:
            start = Pose(*_named(self.world, self.start_pose))
        if self.goal_pose:
            goal = _named(self.world, self.goal_pose)[:2]
        return start, goal

    def draw(self, seed: int) -> Scenario:
        """
        Return the scenario of ``seed`` (0 to 2**31 - 1): the same seed, the same scenario.

        Start and goal first, then the number of boxes and each box, each
        tried up to 50 times to keep out of the start and the goal (a box
        that never does is left out).
        """
        if not (isinstance(seed, int) and 0 <= seed <= 2**31 - 1):
            raise ScenarioError(f'seed must be an integer in 0..2**31-1, got {seed!r}')
        rng = numpy.random.default_rng(seed)
        start, goal = self._named_ends(Pose(*_point(rng, self.start_area),
                                            _milli(rng, *self.start_yaw)),
                                       _point(rng, self.goal_area))
        count = int(rng.integers(self.obstacles[0], self.obstacles[1] + 1))
        boxes = []
        for _ in range(count):
            for _ in range(PLACEMENT_ATTEMPTS):
                box = Box(*_point(rng, self.area), _milli(rng, *self.box_yaw),
                          (_milli(rng, *self.box_size), _milli(rng, *self.box_size),
                           self.box_height))
                if self.clear(box, start, goal):
                    boxes.append(box)
                    break
        limits = [(name, _milli(rng, low, high)) for name, (low, high) in self.limits]
        return self.scenario(boxes, start, goal, seed, limits,
                             _milli(rng, *self.scan_noise_std))

    def seeds(self, count: int, first: int = 0) -> Iterator[Scenario]:
        """Yield the scenarios of seeds ``first`` .. ``first + count - 1``."""
        for seed in range(first, first + count):
            yield self.draw(seed)


def _milli(rng: numpy.random.Generator, low: float, high: float) -> float:
    """Draw a whole number of thousandths in [low, high] (uniform)."""
    lowest, highest = math.ceil(round(low * 1000.0, 6)), math.floor(round(high * 1000.0, 6))
    if highest < lowest:
        return float(low)
    return int(rng.integers(lowest, highest + 1)) / 1000.0


def _point(rng: numpy.random.Generator, area: Sequence[float]) -> Tuple[float, float]:
    x_min, y_min, x_max, y_max = area
    return _milli(rng, x_min, x_max), _milli(rng, y_min, y_max)


# Worlds are read (by r2d2_sim.farm.places) when a scenario names one; each raises
# ScenarioError (one line) for a world or a name the simulator would refuse. places is
# imported only then: it brings the simulator's world readers (about 0.3 s), which a
# scenario without a world never needs.

def _check_world(world: str) -> None:
    from r2d2_sim.farm.places import world_poses
    world_poses(world)


def _named(world: str, name: str) -> Tuple[float, float, float]:
    from r2d2_sim.farm.places import world_poses
    return world_poses(world).pose(name)


def _initial_pose(world: str, start: Pose) -> list:
    if not world:
        return [start.x, start.y, start.yaw]
    from r2d2_sim.farm.places import initial_pose  # the world's start pose moves the origin
    return initial_pose(world, start.x, start.y, start.yaw)
