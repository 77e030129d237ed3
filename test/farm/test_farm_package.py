"""
``r2d2_sim.farm`` itself: cheap to import, and its names where help() and dir() show them.

Its names load their modules when first used (the farm's modules import
rclpy, PyBullet and Hypothesis); ``help(r2d2_sim.farm)`` must still list
them, as it lists any package's.
"""

import os
from pathlib import Path
import pydoc
import subprocess
import sys

import r2d2_sim.farm

REPO = Path(__file__).resolve().parents[2]
HEAVY = ('rclpy', 'pybullet', 'hypothesis', 'matplotlib')
IMPORTED = '''
import sys
import r2d2_sim.farm
print(sorted(m for m in sys.modules if m.startswith('r2d2_sim.farm.') or m in {heavy!r}))
'''


def test_importing_the_farm_loads_none_of_its_modules():
    """A fresh interpreter: the package alone, no farm module and nothing heavy."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (str(REPO), os.environ.get('PYTHONPATH')) if p))
    done = subprocess.run([sys.executable, '-c', IMPORTED.format(heavy=set(HEAVY))], env=env,
                          capture_output=True, text=True, timeout=60)
    assert done.stdout.strip() == '[]', done.stdout + done.stderr


def test_every_name_is_where_the_package_says():
    """Each name of __all__ is its module's own, and dir() lists it; each lazy name is in it."""
    assert sorted(r2d2_sim.farm.__all__) == sorted(r2d2_sim.farm._HOMES)
    for name in r2d2_sim.farm.__all__:
        value = getattr(r2d2_sim.farm, name)
        assert value is getattr(sys.modules[f'r2d2_sim.farm.{r2d2_sim.farm._HOMES[name]}'],
                                name)
    assert set(r2d2_sim.farm.__all__) <= set(dir(r2d2_sim.farm))


def test_help_lists_every_name():
    """help(r2d2_sim.farm): each class, function and constant of __all__ has its entry."""
    text = pydoc.render_doc(r2d2_sim.farm, renderer=pydoc.plaintext)
    entries = {line.split('(')[0].split(' = ')[0].replace('class ', '').strip()
               for line in text.splitlines()
               if line.startswith('    ') and not line.startswith('     ')}
    missing = [name for name in r2d2_sim.farm.__all__ if name not in entries]
    assert not missing, missing
