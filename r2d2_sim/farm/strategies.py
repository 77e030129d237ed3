"""
Hypothesis strategies for scenarios: the same space as ScenarioSpace.draw, shrinking to simple.

``scenarios(space)`` draws the obstacle list first (a list strategy, from the
space's fewest boxes up), then the start, the goal, the seed and the rest,
each as whole millimetres or milliradians: when a property fails, Hypothesis
shrinks toward fewer boxes first, then toward round numbers near the
ranges' lower ends (its integers shrink toward zero, or the bound nearest it).
Boxes that do not keep out of the start and the goal are left out, as
``draw`` leaves them out.

``farm_settings()`` are the settings that make a property over runs
deterministic: ``derandomize`` (the same examples on every run, chosen from
the test's own name, so a failure is found and shrunk the same way again),
no example database (``derandomize`` implies none), no deadline (a run's
length is simulated time, not the machine's), one failure reported, and no
"explain" phase (more whole runs, to name lines only failures ran).

``R2D2_FARM_REPLAY=case.json`` (a scenario's JSON, as a farm report gives it)
makes every ``scenarios()`` strategy draw just that scenario: the rerun of a
property's failing case (``python -m r2d2_sim.farm rerun``) runs the property
on it alone.
"""

import math
import os
from typing import Any, Dict, Tuple

from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st

from r2d2_sim.farm.scenario import Box, Pose, Scenario, ScenarioError, ScenarioSpace

__all__ = ['scenarios', 'farm_settings', 'REPLAY_ENV']

REPLAY_ENV = 'R2D2_FARM_REPLAY'


def _milli(low: float, high: float) -> st.SearchStrategy:
    """Whole thousandths in [low, high], as floats."""
    lowest, highest = math.ceil(round(low * 1000.0, 6)), math.floor(round(high * 1000.0, 6))
    if highest < lowest:
        return st.just(float(low))
    return st.integers(lowest, highest).map(_thousandths)


def _thousandths(count: int) -> float:
    return count / 1000.0


def _point(area: Tuple[float, float, float, float]) -> st.SearchStrategy:
    x_min, y_min, x_max, y_max = area
    return st.tuples(_milli(x_min, x_max), _milli(y_min, y_max))


def boxes(space: ScenarioSpace) -> st.SearchStrategy:
    """Draw one box of ``space``: its centre in the area, its yaw and sizes in their ranges."""
    return st.builds(box, _point(space.area), _milli(*space.box_yaw),
                     _milli(*space.box_size), _milli(*space.box_size), st.just(space.box_height))


def box(centre: Tuple[float, float], yaw: float, size_x: float, size_y: float,
        height: float) -> Box:
    """Return the box a draw describes (named, so that a falsifying example reads well)."""
    return Box(centre[0], centre[1], yaw, (size_x, size_y, height))


def _scenarios(space: ScenarioSpace) -> st.SearchStrategy:
    # Every part is built once: a strategy made inside a draw is validated again on
    # every draw, which made shrinking ten times slower.
    obstacles = st.lists(boxes(space), min_size=space.obstacles[0], max_size=space.obstacles[1])
    start, start_yaw = _point(space.start_area), _milli(*space.start_yaw)
    goal, seed = _point(space.goal_area), st.integers(0, 2**31 - 1)
    limits = [(name, _milli(low, high)) for name, (low, high) in space.limits]
    noise = _milli(*space.scan_noise_std)

    @st.composite
    def scenario(draw: Any) -> Scenario:
        drawn_obstacles = draw(obstacles)  # first: Hypothesis shrinks it first
        centre = draw(start)
        pose = Pose(centre[0], centre[1], draw(start_yaw))
        goal_point = draw(goal)
        drawn_seed = draw(seed)
        drawn_limits = [(name, draw(value)) for name, value in limits]
        return space.scenario(drawn_obstacles, pose, goal_point, drawn_seed, drawn_limits,
                              draw(noise))
    return scenario()


def scenarios(space: ScenarioSpace) -> st.SearchStrategy:
    """
    Return a strategy of the scenarios of ``space``, or of the replayed one.

    With ``R2D2_FARM_REPLAY`` naming a scenario JSON file, just that scenario
    (ScenarioError, one line, if the file is no scenario).
    """
    replay = os.environ.get(REPLAY_ENV)
    if replay:
        try:
            with open(replay, encoding='utf-8') as source:
                return st.just(Scenario.from_json(source.read()))
        except OSError as exc:
            raise ScenarioError(f'{REPLAY_ENV}={replay}: {exc.strerror}') from None
    return _scenarios(space)


def farm_settings(max_examples: int = 20, **more: Any) -> settings:
    """
    Return settings for a property over simulated runs: deterministic, no deadline.

    ``max_examples`` bounds the runs before shrinking (each example is a
    whole run); ``more`` overrides any other Hypothesis setting.
    """
    # No explain phase: it reruns variations of the failing example (whole runs) to
    # list the lines only failures ran, which says little about a simulated run.
    chosen: Dict[str, Any] = dict(
        max_examples=max_examples, derandomize=True, database=None, deadline=None,
        report_multiple_bugs=False, print_blob=False,
        phases=[p for p in Phase if p is not Phase.explain],
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                               HealthCheck.filter_too_much])
    chosen.update(more)
    return settings(**chosen)
