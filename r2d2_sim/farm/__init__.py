"""
The scenario farm: many seeded variations of a world, each a verdict with its evidence.

It may import every layer below; only the learning environments above it
(:mod:`r2d2_sim.gym`, which draw their episodes from its scenario spaces)
import it. What it holds, by role:

- :mod:`~r2d2_sim.farm.scenario`: :class:`Scenario` (obstacles, start, goal,
  seed, world, limits; JSON exactly) and :class:`ScenarioSpace`, whose
  ``draw(seed)`` gives the same scenario for the same seed;
- :mod:`~r2d2_sim.farm.strategies`: Hypothesis strategies of the same spaces
  (``scenarios(space)``), shrinking to fewer boxes and rounder numbers, and
  ``farm_settings()`` that make a property over runs deterministic;
- :mod:`~r2d2_sim.farm.run`: ``run_scenario`` (a fresh in-process
  simulator, the user's controller in lockstep, a
  :class:`~r2d2_sim.sim.oracles.RunWatch`) and its :class:`Outcome`;
  a failing run is run again to record it, and must repeat exactly;
- :mod:`~r2d2_sim.farm.report`: report.md, report.json, trajectories.png;
- :mod:`~r2d2_sim.farm.maps`: a world's walls and boxes for the picture;
- :mod:`~r2d2_sim.farm.pytest_plugin`: the ``r2d2_farm`` fixture, outcomes
  from every xdist worker, the report at the end (opt-in);
- :mod:`~r2d2_sim.farm.runner`: ``run_farm`` (a :class:`FarmJob`'s variations
  as tasks of an executor, :mod:`~r2d2_sim.farm.executors`: local processes,
  Ray, Dask), with :mod:`~r2d2_sim.farm.job` (the job, the task),
  :mod:`~r2d2_sim.farm.shm` (segments killed tasks left), :mod:`~r2d2_sim.farm.shards`,
  :mod:`~r2d2_sim.farm.progress` and :mod:`~r2d2_sim.farm.shrink`;
- ``python -m r2d2_sim.farm``: run a farm; rerun a case from its report, recording it.

Importing this package imports no rclpy, PyBullet or Hypothesis; the names
below load their modules when first used.
"""

import importlib

# Each public name and the module it lives in: the package's names (__all__), loaded
# when first used, and what dir() and help() list.
_HOMES = {'Box': 'scenario', 'Pose': 'scenario', 'Scenario': 'scenario',
          'ScenarioSpace': 'scenario', 'ScenarioError': 'scenario', 'ROOM': 'scenario',
          'LIMITS': 'scenario', 'scenarios': 'strategies', 'farm_settings': 'strategies',
          'run_scenario': 'run', 'Outcome': 'run', 'reached_safely': 'run', 'safe': 'run',
          'DeterminismError': 'run', 'world_boxes': 'maps', 'write_report': 'report',
          'FarmJob': 'job', 'JobSource': 'job', 'run_farm': 'runner', 'FarmRun': 'runner',
          'FarmError': 'runner'}

__all__ = list(_HOMES)


def __getattr__(name: str) -> object:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    return getattr(importlib.import_module(f'{__name__}.{home}'), name)


def __dir__() -> list[str]:
    # help() and dir() list what dir() gives: the lazy names too (help then loads them).
    # No typing import here: it alone would cost more than this package (10 ms cold).
    return sorted(set(globals()) | set(_HOMES))
