"""
SimProcess without the interface build in the test's process: its verbs say what to build.

A new user's pip-only venv, ``tools/build_interfaces.sh`` not run:
``spawn``, ``step_physics``, ``entities`` and ``reset_world`` (through
``SimProcess.standard``) and ``lookup_transform`` raised a bare
``ModuleNotFoundError``. Now each raises
:class:`~r2d2_sim.testing.MissingInterfaceError` (a HarnessError) in one line
naming the package and ``tools/build_interfaces.sh VENV``. The imports are
made to fail in this process only (the simulator's own process has them);
nothing is uninstalled.
"""

import pytest

from common import assert_says_build, block_package
from r2d2_sim.testing import HarnessError


def test_the_world_verbs_and_lookups_name_the_missing_package(r2d2_sim_process, monkeypatch):
    block_package(monkeypatch, 'tf2_msgs')
    block_package(monkeypatch, 'simulation_interfaces')
    sim = r2d2_sim_process(start_paused=True)  # starts: they are optional
    verbs = {'spawn': lambda: sim.spawn('cube.urdf', position=(3, 0, 1)),
             'step_physics': lambda: sim.step_physics(10), 'entities': sim.entities,
             'reset_world': sim.reset_world, 'standard': lambda: sim.standard}
    for name, verb in verbs.items():
        with pytest.raises(HarnessError) as error:
            verb()
        assert_says_build(error, 'simulation_interfaces')
    with pytest.raises(HarnessError) as error:
        sim.lookup_transform('odom', 'base_link')
    assert_says_build(error, 'tf2_msgs')
    sim.step(1)  # its own services work
