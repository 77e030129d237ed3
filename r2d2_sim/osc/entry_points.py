"""
osc.r2d2's entry points for scenario_execution, the one table of them.

``setup.py`` reads this file (without importing the package) to install
them; :func:`ensure_registered` gives a source checkout the same, through a
small ``.dist-info`` directory put on ``sys.path``, since scenario_execution
finds libraries and actions by entry point only. No imports of the package.
"""

import os
import sys
import tempfile
from typing import Dict, List

# scenario_execution's entry point groups and what r2d2_sim registers in each.
ENTRY_POINTS: Dict[str, List[str]] = {
    'scenario_execution.osc_libraries': ['r2d2 = r2d2_sim.osc:library'],
    'scenario_execution.actions': [
        f'{name} = r2d2_sim.osc.actions:{cls}' for name, cls in (
            ('delete_entity', 'DeleteEntity'), ('load_world', 'LoadWorld'),
            ('reset_simulation', 'ResetSimulation'), ('set_entity_state', 'SetEntityState'),
            ('set_simulation_state', 'SetSimulationState'), ('spawn_entity', 'SpawnEntity'),
            ('step_simulation', 'StepSimulation'), ('unload_world', 'UnloadWorld'),
            ('drive', 'Drive'), ('drive_to', 'DriveTo'),
            ('wait_until_in_region', 'WaitUntilInRegion'),
            ('wait_until_at_pose', 'WaitUntilAtPose'), ('assert_no_contact', 'AssertNoContact'),
            ('assert_min_clearance', 'AssertMinClearance'),
            ('assert_not_tipped', 'AssertNotTipped'))],
}
# The distribution a source checkout's entry points are registered under.
SHIM = 'r2d2_sim_osc_source'


def entry_points_text() -> str:
    """Return ``entry_points.txt`` as pip writes it for :data:`ENTRY_POINTS`."""
    return ''.join(f'[{group}]\n' + ''.join(f'{line}\n' for line in lines) + '\n'
                   for group, lines in ENTRY_POINTS.items())


def registered() -> bool:
    """Return True when scenario_execution can find osc.r2d2 (installed, or shimmed)."""
    from importlib.metadata import entry_points
    return any(ep.value == 'r2d2_sim.osc:library'
               for ep in entry_points(group='scenario_execution.osc_libraries'))


def write_shim(directory: str) -> str:
    """Write a ``.dist-info`` holding :data:`ENTRY_POINTS` into ``directory``; return it."""
    info = os.path.join(directory, f'{SHIM}-0.dist-info')
    os.makedirs(info, exist_ok=True)
    with open(os.path.join(info, 'METADATA'), 'w', encoding='utf-8') as out:
        out.write(f'Metadata-Version: 2.1\nName: {SHIM}\nVersion: 0\n')
    with open(os.path.join(info, 'entry_points.txt'), 'w', encoding='utf-8') as out:
        out.write(entry_points_text())
    return directory


def ensure_registered() -> str:
    """
    Make osc.r2d2 findable in this process and its children; return the path added ('' none).

    Installed (pip, colcon), nothing is done. From a source checkout, a shim
    is written to a temporary directory, put first on ``sys.path`` and on
    ``PYTHONPATH`` (so that a scenario_execution child finds it too).
    """
    if registered():
        return ''
    directory = write_shim(tempfile.mkdtemp(prefix='r2d2_sim_osc_'))
    sys.path.insert(0, directory)
    os.environ['PYTHONPATH'] = os.pathsep.join(
        p for p in (directory, os.environ.get('PYTHONPATH')) if p)
    import importlib
    importlib.invalidate_caches()
    return directory
