"""
Running one scenario: a fresh simulator, the user's controller, a verdict with its measures.

:func:`run_scenario` builds a :class:`~r2d2_sim.testing.SimHarness` for the
scenario (the robot at the start, ``noise_seed`` the scenario's seed, the
world, the limits), spawns the obstacles as fixed boxes, lets the user's
``controller(harness, scenario)`` add its nodes (the harness then runs in
lockstep with them), watches the run (:class:`~r2d2_sim.sim.oracles.RunWatch`:
contacts, clearance, the goal region, tipping, the trajectory) and advances
until the goal is reached or the time is up. The :class:`Outcome` holds the
verdict and the measures, and serializes to JSON.

Runs repeat bit for bit, so a failing run's evidence costs nothing until it
fails: with ``record_failure`` a failed run is run again recording an MCAP
file, and the rerun must give the same outcome. If it does not, that is a
determinism bug, raised as :class:`DeterminismError` with the first
difference.
"""

from dataclasses import dataclass, fields, replace
import json
import time
from typing import Any, Callable, Dict, Mapping, Optional, Tuple

from r2d2_sim.farm.scenario import Scenario, ScenarioError
from r2d2_sim.sim.oracles import Contact, TrajectoryPoint
from r2d2_sim.testing import box_urdf, SimHarness

__all__ = ['Outcome', 'run_scenario', 'reached_safely', 'safe', 'DeterminismError',
           'DEFAULT_PARAMETERS', 'TRAJECTORY_RATE_HZ', 'GOAL']

# The simulator's parameters under every run, before the scenario's and the caller's:
# a command holds until the next one (as in the r2d2_sim fixture), what the robot
# touches is published on contacts, so that a failure's recording shows it, and the
# scans are cast on one thread (a farm runs a variation per core).
DEFAULT_PARAMETERS: Mapping[str, Any] = {'cmd_vel_timeout': 0.0, 'publish_contacts': True,
                                         'ray_threads': 1}
# The base's trajectory is kept at this rate (simulated Hz).
TRAJECTORY_RATE_HZ = 10.0
# The goal region's name in the run's watch.
GOAL = 'goal'


class DeterminismError(AssertionError):
    """A scenario run twice gave two outcomes: the promise of bit-identical runs is broken."""


@dataclass(frozen=True, repr=False)
class Outcome:
    """
    What one run of a scenario did, and its verdict.

    ``passed`` and ``reason`` (empty when passed) are the verdict's;
    ``seconds`` the simulated time allowed; ``time_to_goal_s`` when the base
    first stood in the goal region (None: never); ``clearance_m`` the
    smallest distance to any other body (negative: overlapping), to
    ``closest`` at ``closest_s``; ``contacts`` every body touched (see
    :class:`~r2d2_sim.sim.oracles.Contact`); ``tipped_s`` when it tipped over
    (None: never); ``trajectory`` the base at 10 Hz (time_ns, x, y, yaw);
    ``steps`` the physics steps run; ``wall_s`` the wall time of the whole
    run (start-up included); ``recording`` the MCAP file of the run, if kept.

    Every time counts from the start of the run, when the controller's nodes
    were added (what it advanced before is not the run's): contacts' and the
    trajectory's too, so that they and the reasons agree. A recording keeps
    the simulation's own clock.
    """

    scenario: Scenario
    passed: bool
    reason: str
    seconds: float
    time_to_goal_s: Optional[float]
    clearance_m: float
    closest: Optional[str]
    closest_s: Optional[float]
    contacts: Tuple[Contact, ...]
    tipped_s: Optional[float]
    trajectory: Tuple[TrajectoryPoint, ...]
    steps: int
    wall_s: float = 0.0
    recording: Optional[str] = None

    def __repr__(self) -> str:
        # Short: pytest shows it in a failed assert (the trajectory alone is hundreds of points).
        verdict = 'passed' if self.passed else f'failed: {self.reason}'
        goal = ('never' if self.time_to_goal_s is None else f'{self.time_to_goal_s:.3f} s')
        return (f'Outcome(seed {self.scenario.seed}, {verdict}; goal {goal}, clearance '
                f'{self.clearance_m:.3f} m to {self.closest}; recording {self.recording})')

    def measures(self) -> Dict[str, Any]:
        """Return what the run did, as JSON data, without what may differ between reruns."""
        data = self.to_dict()
        del data['wall_s'], data['recording']
        return data

    def to_dict(self) -> Dict[str, Any]:
        """Return the outcome as JSON-ready data (see :meth:`from_dict`)."""
        data = {f.name: getattr(self, f.name) for f in fields(self)}
        data['scenario'] = self.scenario.to_dict()
        data['contacts'] = [c._asdict() for c in self.contacts]
        data['trajectory'] = [list(p) for p in self.trajectory]
        return data

    def to_json(self) -> str:
        """Return the outcome as one line of JSON."""
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> 'Outcome':
        """Read :meth:`to_dict`'s data; ScenarioError (one line) for anything else."""
        try:
            values = dict(data)
            values['scenario'] = Scenario.from_dict(data['scenario'])
            values['contacts'] = tuple(
                Contact(**dict(c, position=tuple(c['position']))) for c in data['contacts'])
            values['trajectory'] = tuple(TrajectoryPoint(*p) for p in data['trajectory'])
            return cls(**{f.name: values[f.name] for f in fields(cls)})
        except ScenarioError:
            raise
        except (KeyError, TypeError, ValueError) as exc:
            raise ScenarioError(f'not an outcome: {type(exc).__name__} {exc}') from None


Verdict = Callable[[Outcome], str]
Controller = Callable[[SimHarness, Scenario], Any]


def safe(outcome: Outcome) -> str:
    """Judge a run by safety alone: no contact, never tipped; return the reason it failed."""
    if outcome.contacts:
        first = outcome.contacts[0]
        return (f'touched {first.other} at {first.start_ns / 1e9:.3f} s '
                f'({first.robot_link}, {first.max_normal_force_n:.0f} N)')
    if outcome.tipped_s is not None:
        return f'tipped over at {outcome.tipped_s:.3f} s'
    return ''


def reached_safely(outcome: Outcome) -> str:
    """Judge a run (the default): the goal reached, no contact, never tipped; '' if so."""
    unsafe = safe(outcome)
    if unsafe:
        return unsafe
    if outcome.time_to_goal_s is None:
        return f'goal not reached in {outcome.seconds:g} s'
    return ''


def run_scenario(scenario: Scenario, controller: Controller, *, seconds: float,
                 record: Optional[str] = None, parameters: Optional[Mapping[str, Any]] = None,
                 verdict: Verdict = reached_safely,
                 record_failure: Optional[str] = None) -> Outcome:
    """
    Run ``scenario`` for up to ``seconds`` of simulated time; return its :class:`Outcome`.

    ``controller(harness, scenario)`` adds the user's nodes to the harness
    (``harness.add_node(...)``: lockstep) or commands it otherwise; the run
    ends when the base reaches the goal or the time is up. ``parameters``
    are simulator parameters on top of the scenario's (``publish_rate``...).
    ``record`` records the run into that MCAP file (it must not exist).
    ``verdict(outcome)`` returns why the run failed, '' when it passed
    (default :func:`reached_safely`; TypeError for anything but a str).
    ``record_failure``: if the run fails, run it again recording into that
    file, and check the two outcomes are the same (:class:`DeterminismError`
    if not); the outcome then names the file.
    """
    if not (0.0 < seconds < float('inf')):
        raise ValueError(f'seconds must be > 0 and finite, got {seconds}')
    settings = dict(DEFAULT_PARAMETERS)
    settings.update(scenario.parameters())
    settings.update(parameters or {})
    if record is not None:
        settings['record'] = str(record)
    started = time.perf_counter()
    with SimHarness(**settings) as harness:
        for index, box in enumerate(scenario.obstacles):
            harness.spawn(box_urdf(box.size), name=f'box_{index}',
                          position=(box.x, box.y, box.size[2] / 2.0), yaw=box.yaw)
        controller(harness, scenario)
        with harness.watch(regions={GOAL: scenario.goal},
                           trajectory_period_s=1.0 / TRAJECTORY_RATE_HZ) as watch:
            harness.advance_until(lambda: GOAL in watch.reached, timeout_s=seconds)
    wall_s = time.perf_counter() - started
    start_ns = watch.start_ns

    # Every time of the outcome counts from the watch's start (the controller may have
    # advanced the simulation before): the watch keeps the simulation's own times.
    def since(time_ns: Optional[int]) -> Optional[float]:
        return None if time_ns is None else (time_ns - start_ns) / 1e9

    contacts = tuple(c._replace(start_ns=c.start_ns - start_ns,
                                end_ns=None if c.end_ns is None else c.end_ns - start_ns)
                     for c in watch.contacts)
    trajectory = tuple(p._replace(time_ns=p.time_ns - start_ns) for p in watch.trajectory)
    outcome = Outcome(
        scenario=scenario, passed=True, reason='', seconds=float(seconds),
        time_to_goal_s=since(watch.reached.get(GOAL)),
        clearance_m=watch.clearance.distance_m, closest=watch.clearance.other,
        closest_s=since(watch.clearance.time_ns), contacts=contacts,
        tipped_s=since(watch.tipped_ns), trajectory=trajectory,
        steps=watch.steps, wall_s=wall_s, recording=record)
    reason = verdict(outcome)
    if not isinstance(reason, str):  # a bool would pass as True ("it was fine") and fail
        name = getattr(verdict, '__qualname__', type(verdict).__name__)
        raise TypeError(f'the verdict {name} returned {type(reason).__name__} {reason!r:.60}: '
                        'a verdict returns a str, why the run failed (\'\' when it passed)')
    outcome = replace(outcome, passed=not reason, reason=reason)
    if outcome.passed or record_failure is None:
        return outcome
    again = run_scenario(scenario, controller, seconds=seconds, record=record_failure,
                         parameters=parameters, verdict=verdict)
    check_same(outcome, again)
    return replace(outcome, recording=again.recording)


def check_same(first: Outcome, second: Outcome) -> None:
    """Raise DeterminismError naming the first measure two runs of one scenario disagree on."""
    a, b = first.measures(), second.measures()
    for name in a:
        if a[name] != b[name]:
            raise DeterminismError(
                f'DETERMINISM BROKEN: scenario seed {first.scenario.seed} run twice gave two '
                f'outcomes; first difference in {name}: {_short(a[name])} then '
                f'{_short(b[name])}. Please report it with the scenario: '
                f'{first.scenario.to_json()}')


def _short(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) < 200 else text[:200] + '...'
