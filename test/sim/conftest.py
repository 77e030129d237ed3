"""
The core's fixture for this folder: simulations built from parameter dicts, closed after.

No ROS. A test module may set ``SIMULATION_DEFAULTS`` (a dict of parameters
that its calls override), as its own defaults.
"""

import pytest


@pytest.fixture
def make(request):
    """
    Provide a builder of simulations from parameters, each closed after the test.

    ``make(errors=None, warnings=None, **parameters)`` returns a Simulation.
    Parameters as ``sim_node`` takes them (``robots`` and ``NAME.parameter``
    too); ``errors`` and ``warnings``, lists, receive the simulation's one-line
    error and warning reports.
    """
    from r2d2_sim.sim.settings.robots import parse_world
    from r2d2_sim.sim.simulation import Simulation
    defaults = getattr(request.module, 'SIMULATION_DEFAULTS', {})
    made = []

    def build(errors=None, warnings=None, **parameters):
        config, robots = parse_world({**defaults, **parameters})
        error = errors.append if errors is not None else (lambda text: None)
        warn = warnings.append if warnings is not None else (lambda text: None)
        simulation = Simulation(config, robots, warn=warn, error=error)
        made.append(simulation)
        return simulation
    yield build
    for simulation in made:
        simulation.close()
