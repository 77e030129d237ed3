"""
Shrinking a farm's failure with Hypothesis, on this machine: search wide on a cluster, shrink here.

A farm finds a failing seed among many, in parallel; Hypothesis then makes
its scenario as small as it still fails, one run after another, which is
sequential by nature: it runs here, in the runner's process, never on the
cluster.

Hypothesis shrinks examples it generated itself. The failing scenario came
from :meth:`ScenarioSpace.draw` (numpy), so :func:`choices_of` writes it
as the choices :func:`~r2d2_sim.farm.strategies.scenarios` would have made
to draw it (each box's whole millimetres, with the list's continue flags as
``st.lists`` draws them, then the start, the goal, the seed, the limits, the
noise: the strategy's order), checks the strategy draws the same scenario
from them (else it says it could not express the scenario), and an
example database that holds only those choices (:class:`_Seeded`, as an
example not shrunk yet) hands them to Hypothesis: its reuse phase runs the
scenario again, it fails, and
its shrink phase takes it toward fewer boxes and rounder numbers, as for a
property of the pytest farm. Deterministic: Hypothesis's random generator is
seeded, and runs repeat bit for bit.

The result: the shrunk scenario, its verdict and its recording, written to
``shrunk-<seed>.json`` and ``recordings/shrunk-<seed>.mcap`` in the report's
directory.
"""

import math
from pathlib import Path
from typing import Any, Dict, Iterable, List, Optional, Sequence

from r2d2_sim.farm.job import FarmJob, Item
from r2d2_sim.farm.scenario import Box, Scenario, ScenarioSpace

__all__ = ['choices_of', 'replay', 'shrink_failure', 'CannotExpress', 'MAX_SHRINKS']

# Runs Hypothesis may make while shrinking (each a whole simulated run).
MAX_SHRINKS = 200


def _milli(value: float, low: float, high: float) -> List[int]:
    """Return the choice of a value drawn as whole thousandths in [low, high] (none if fixed)."""
    lowest, highest = math.ceil(round(low * 1000.0, 6)), math.floor(round(high * 1000.0, 6))
    if highest < lowest:
        return []
    return [min(max(round(value * 1000.0), lowest), highest)]


class CannotExpress(ValueError):
    """A scenario the strategy's choices cannot draw (so Hypothesis cannot shrink it)."""


def choices_of(space: ScenarioSpace, scenario: Scenario) -> tuple:
    """
    Return the choices ``scenarios(space)`` makes to draw ``scenario`` (one of ``space``'s).

    A named start or goal stands for the drawn one: its draw is the area's
    lowest corner (the strategy drops it as ``draw`` does). The box list is
    written as Hypothesis's ``st.lists`` draws it (``many``): a list of a fixed
    size draws no continue flags; another draws a flag before each box and a
    last one to stop, forced (below the fewest, at the most) but a choice all
    the same. Boxes ``draw`` left out (none kept out of the start and the goal)
    are drawn as boxes the strategy leaves out too, up to the fewest;
    :class:`CannotExpress` when the space has no such box.
    """
    variable = space.obstacles[0] != space.obstacles[1]
    choices: List[Any] = []
    boxes = list(scenario.obstacles)
    if len(boxes) < space.obstacles[0]:
        boxes += [_left_out(space, scenario)] * (space.obstacles[0] - len(boxes))
    for box in boxes:
        choices += [True] if variable else []
        choices += [*_milli(box.x, space.area[0], space.area[2]),
                    *_milli(box.y, space.area[1], space.area[3]),
                    *_milli(box.yaw, *space.box_yaw), *_milli(box.size[0], *space.box_size),
                    *_milli(box.size[1], *space.box_size)]
    choices += [False] if variable else []
    start_x, start_y, start_yaw = ((space.start_area[0], space.start_area[1],
                                    space.start_yaw[0]) if space.start_pose else
                                   (scenario.start.x, scenario.start.y, scenario.start.yaw))
    goal_x, goal_y = ((space.goal_area[0], space.goal_area[1]) if space.goal_pose
                      else scenario.goal_point)
    choices += [*_milli(start_x, space.start_area[0], space.start_area[2]),
                *_milli(start_y, space.start_area[1], space.start_area[3]),
                *_milli(start_yaw, *space.start_yaw),
                *_milli(goal_x, space.goal_area[0], space.goal_area[2]),
                *_milli(goal_y, space.goal_area[1], space.goal_area[3]), scenario.seed]
    limits = dict(scenario.limits)
    for name, (low, high) in space.limits:
        choices += _milli(limits[name], low, high)
    choices += _milli(scenario.scan_noise_std, *space.scan_noise_std)
    return tuple(choices)


def _left_out(space: ScenarioSpace, scenario: Scenario) -> Box:
    """Return a box of ``space`` that does not keep out of the scenario's start or goal."""
    x_min, y_min, x_max, y_max = space.area
    for x, y in ((scenario.start.x, scenario.start.y), scenario.goal_point):
        box = Box(min(max(x, x_min), x_max), min(max(y, y_min), y_max), space.box_yaw[0],
                  (space.box_size[1], space.box_size[1], space.box_height))
        if not space.clear(box, scenario.start, scenario.goal_point):
            return box
    raise CannotExpress(f'it has {len(scenario.obstacles)} of the space\'s fewest '
                        f'{space.obstacles[0]} boxes, and no box of its area stands in the way '
                        'of its start or goal to be left out in their place')


def replay(space: ScenarioSpace, choices: Sequence[Any]) -> Optional[Scenario]:
    """Return the scenario ``scenarios(space)`` draws from ``choices``; None if it cannot."""
    from hypothesis.control import BuildContext
    from hypothesis.errors import StopTest
    from hypothesis.internal.conjecture.data import ConjectureData
    from r2d2_sim.farm.strategies import scenarios
    data = ConjectureData.for_choices(tuple(choices))
    try:
        with BuildContext(data, wrapped_test=replay):  # a test to name: none runs
            drawn: Scenario = data.draw(scenarios(space))
    except StopTest:  # ran out of choices
        return None
    return drawn if data.misaligned_at is None else None


class _Seeded:
    """An example database holding one example: the choices of the failure found by the farm."""

    def __new__(cls, choices: tuple) -> Any:
        from hypothesis.database import choices_to_bytes, ExampleDatabase

        class Seeded(ExampleDatabase):
            def __init__(self) -> None:
                super().__init__()
                self.example = choices_to_bytes(choices)

            def fetch(self, key: bytes) -> Iterable[bytes]:
                # As a secondary example (one not shrunk yet): a primary one that fails
                # again is taken as shrunk already, and Hypothesis would not shrink it.
                if key.endswith(b'.secondary'):
                    yield self.example

            def save(self, key: bytes, value: bytes) -> None:
                """Keep nothing: the shrunk example is reported, not stored."""

            def delete(self, key: bytes, value: bytes) -> None:
                """Keep nothing."""

            def move(self, src: bytes, dest: bytes, value: bytes) -> None:
                """Keep nothing."""

        return Seeded()


def shrink_failure(job: FarmJob, item: Item, directory: Path,
                   max_shrinks: int = MAX_SHRINKS) -> Optional[Dict[str, Any]]:
    """
    Shrink the failing variation ``item`` of ``job`` here; record and write what it shrank to.

    Returns ``first`` and ``shrunk`` (scenarios' JSON), ``reason``,
    ``recording``, ``runs`` and a one-line ``summary``; None for a farm of
    listed scenarios (no space to shrink within).
    """
    if job.listed:
        return None
    from hypothesis import given, HealthCheck, Phase, seed, settings
    from hypothesis.control import current_build_context
    from r2d2_sim.farm.run import reached_safely, run_scenario
    from r2d2_sim.farm.strategies import scenarios
    space: ScenarioSpace = job.space  # type: ignore[assignment]
    verdict = job.verdict or reached_safely
    first = job.scenario(item)
    found: Dict[str, Any] = {'runs': 0}
    try:
        choices = choices_of(space, first)
        if replay(space, choices) != first:
            raise CannotExpress('the strategy draws another scenario from its choices')
    except CannotExpress as exc:
        return {'first': first.to_json(), 'shrunk': None, 'runs': 0,
                'summary': f'seed {item.seed}: could not express the scenario as the choices of '
                           f'the Hypothesis strategy ({exc}): nothing shrunk'}

    # The seed under given, the settings above: @seed alone would drop the database.
    @settings(database=_Seeded(choices), phases=[Phase.reuse, Phase.shrink],
              max_examples=max_shrinks, deadline=None, report_multiple_bugs=False,
              print_blob=False, suppress_health_check=list(HealthCheck))
    @given(scenario=scenarios(space))
    @seed(0)
    def fails(scenario: Scenario) -> None:
        found['runs'] += 1
        outcome = run_scenario(scenario, job.controller, seconds=job.seconds,
                               parameters=job.parameters, verdict=verdict)
        if current_build_context().is_final:
            found['shrunk'] = scenario
        assert outcome.passed, outcome.reason

    try:
        fails()
    except AssertionError:
        pass
    shrunk = found.get('shrunk')
    if shrunk is None:
        return {'first': first.to_json(), 'shrunk': None, 'runs': found['runs'],
                'summary': f'seed {item.seed}: Hypothesis did not see the failure again, '
                           'nothing shrunk (a run that reads the wall clock?)'}
    folder = directory / 'recordings'
    folder.mkdir(parents=True, exist_ok=True)
    recording = folder / f'shrunk-{item.key}.mcap'
    recording.unlink(missing_ok=True)
    outcome = run_scenario(shrunk, job.controller, seconds=job.seconds,
                           parameters=job.parameters, verdict=verdict, record=str(recording))
    result = {'first': first.to_json(), 'shrunk': shrunk.to_json(), 'reason': outcome.reason,
              'recording': str(recording), 'runs': found['runs'],
              'summary': (f'seed {item.seed} shrunk by Hypothesis, here, in {found["runs"]} '
                          f'runs: from {_boxes(first)} to {_boxes(shrunk)}: {outcome.reason}; '
                          f'{directory / f"shrunk-{item.key}.json"}, recording {recording}')}
    import json
    (directory / f'shrunk-{item.key}.json').write_text(json.dumps(result, indent=1) + '\n',
                                                       encoding='utf-8')
    return result


def _boxes(scenario: Scenario) -> str:
    count = len(scenario.obstacles)
    return f'{count} box' if count == 1 else f'{count} boxes'
