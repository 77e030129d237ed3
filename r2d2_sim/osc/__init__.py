"""
OpenSCENARIO 2 scenarios through scenario_execution: r2d2_sim's simulations and its library.

Above the farm (it may import every layer, and the conformance kit's
discovery); nothing imports it. Needs the ``scenarios`` extra
(``pip install r2d2_sim[scenarios]``: scenario_execution 1.8.0). By role:

- :mod:`~r2d2_sim.osc.in_process`: :class:`R2D2Simulation`, the step-based
  simulation of ``scenario_execution --simulation r2d2_sim.osc:R2D2Simulation``:
  the core in the scenario's process, no ROS;
- :mod:`~r2d2_sim.osc.over_ros`: :class:`StandardSimulation`, the same over ROS
  against any simulator of the simulation standard, found by type, stepped in
  lockstep;
- :mod:`~r2d2_sim.osc.actions` and ``lib_osc/r2d2.osc``: the library
  ``osc.r2d2`` (osc.sim's eight actions, drive, wait and check), installed
  through scenario_execution's entry points;
- :mod:`~r2d2_sim.osc.parameters`: a scenario's parameters as the farm's Scenario;
- :mod:`~r2d2_sim.osc.port`: the one seam the actions use, and the pure
  decisions both sides share;
- :mod:`~r2d2_sim.osc.variations`: a multi-document parameter file, each
  scenario run per document in a process pool; one JUnit file and the
  farm's report; ``python -m r2d2_sim.osc``.

Importing this package imports neither scenario_execution nor rclpy; the
names below load their modules when first used.
"""

import importlib
from typing import Tuple

_HOMES = {'R2D2Simulation': 'in_process', 'StandardSimulation': 'over_ros',
          'run_variations': 'variations', 'read_documents': 'variations',
          'read_parameters': 'parameters'}

__all__ = list(_HOMES) + ['library']


def library() -> Tuple[str, str]:
    """Return where osc.r2d2 lives, as scenario_execution's osc_libraries entry point asks."""
    return 'r2d2_sim.osc', 'r2d2.osc'


def __getattr__(name: str) -> object:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    return getattr(importlib.import_module(f'{__name__}.{home}'), name)


def __dir__() -> list:
    return sorted(set(globals()) | set(_HOMES))
