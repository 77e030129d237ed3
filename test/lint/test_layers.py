"""
The package's folders are its layers: each imports from its own layer or lower ones only.

From the lowest up: ``errors`` (with ``memory`` and ``files``), ``recording``, ``model``,
``physics``, ``sim``, ``client``, ``ros``, ``testing``, ``apps``, ``farm`` (above the
executables: none of them imports it), ``gym`` (the learning environments, on the farm's
scenario spaces), then ``pytest_plugin`` and ``__main__``, then ``conformance``, and on
top ``osc``, which uses the kit's discovery; the package's own ``__init__`` imports
nothing of it but ``deprecations``, the table of old names, which imports nothing of
the package (it imports a new module by name when an old name is used). Two checks:

- in a fresh interpreter, importing every module of ``model``, ``physics``,
  ``sim`` and ``recording`` loads no rclpy (and ``model`` and ``recording`` no
  PyBullet either);
- every import of the package in every module of it (at the top or inside a
  function, absolute or relative) names a module of the same layer or a lower
  one: read with ``ast``, nothing is imported.

Both checkers are also run on a small package written for the purpose, with a
module of each kind of fault, to prove that they find what they look for.
This file imports no ROS, so it runs in the fast tier (``./run.sh test fast``).
"""

import ast
import json
import os
from pathlib import Path
import subprocess
import sys
import textwrap

import pytest

from common import REPO

PACKAGE = 'r2d2_sim'
# Each folder or top-level module of the package, by height; a module imports only
# from its own height or below. The package's root __init__ sits below them all, with
# the table of old names it installs.
ROOT_RANK = -1
RANK = {'deprecations': ROOT_RANK, 'errors': 0, 'memory': 0, 'files': 0, 'model': 1,
        'recording': 2, 'physics': 3, 'sim': 4, 'client': 5, 'ros': 6, 'testing': 7, 'apps': 8,
        'farm': 9, 'gym': 10, 'pytest_plugin': 11, '__main__': 11, 'conformance': 12, 'osc': 13}
# What importing all of a ROS-free layer must not load.
MUST_NOT_LOAD = {'model': ['rclpy', 'pybullet'], 'physics': ['rclpy'], 'sim': ['rclpy'],
                 'recording': ['rclpy', 'pybullet']}

IMPORT_ALL = '''
import importlib, json, sys
for name in json.loads(sys.argv[1]):
    importlib.import_module(name)
print(json.dumps(sorted(m for m in json.loads(sys.argv[2]) if m in sys.modules)))
'''


def module_names(root: Path, package: str, layer: str) -> list:
    """Return the dotted names of every module of ``package.layer`` (a folder or one file)."""
    folder = root / package / layer
    if not folder.is_dir():
        return [f'{package}.{layer}']
    names = []
    for path in sorted(folder.rglob('*.py')):
        parts = path.relative_to(root).with_suffix('').parts
        names.append('.'.join(parts[:-1] if parts[-1] == '__init__' else parts))
    return names


def loaded_by_importing(root: Path, package: str, layer: str, watched: list) -> list:
    """Import every module of ``package.layer`` in a new interpreter; return ``watched`` loaded."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(root), env.get('PYTHONPATH')) if p)
    result = subprocess.run(
        [sys.executable, '-c', IMPORT_ALL, json.dumps(module_names(root, package, layer)),
         json.dumps(watched)], cwd=root, env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


def layer_of(module: str, package: str):
    """Return the rank of a dotted module name of ``package``: its first part below the package."""
    parts = module.split('.')
    if len(parts) == 1:
        return ROOT_RANK
    return RANK.get(parts[1])


def from_module(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    """Return the absolute name of the module a ``from ... import`` in ``module`` names."""
    base = node.module or ''
    if node.level:
        parts = module.split('.') if is_package else module.split('.')[:-1]
        parts = parts[:len(parts) - (node.level - 1)]
        base = '.'.join(parts + ([base] if base else []))
    return base


def imported_modules(node: ast.AST, module: str, is_package: bool) -> list:
    """Return the absolute names one Import or ImportFrom node imports (relative ones resolved)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    base = from_module(node, module, is_package)
    # "from pkg import name": name may be a module of pkg; its layer is pkg's, or lower.
    return [f'{base}.{alias.name}' if base.count('.') == 0 else base for alias in node.names]


def layer_violations(root: Path, package: str) -> list:
    """Return 'file:line: module imports target' for each import of a higher layer's module."""
    found = []
    for path in sorted((root / package).rglob('*.py')):
        relative = path.relative_to(root)
        parts = relative.with_suffix('').parts
        is_package = parts[-1] == '__init__'
        module = '.'.join(parts[:-1] if is_package else parts)
        source_rank = layer_of(module, package)
        if source_rank is None:
            found.append(f'{relative}: not in any layer')
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'), str(path))):
            if not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            for target in imported_modules(node, module, is_package):
                if target != package and not target.startswith(package + '.'):
                    continue
                target_rank = layer_of(target, package)
                if target_rank is None or target_rank > source_rank:
                    found.append(f'{relative}:{node.lineno}: {module} imports {target}')
    return found


def import_graph(root: Path, package: str) -> dict:
    """
    Return each module of ``package`` and the modules of it that it imports, anywhere in it.

    Imports under ``if TYPE_CHECKING:`` count too: never run, they still tie
    a part to the whole that composes it (the part names a seam instead, a
    ``Protocol`` of what it uses, in a module both import).
    """
    paths = {}
    for path in sorted((root / package).rglob('*.py')):
        parts = path.relative_to(root).with_suffix('').parts
        paths['.'.join(parts[:-1] if parts[-1] == '__init__' else parts)] = path
    graph = {}
    for module, path in paths.items():
        is_package = path.name == '__init__.py'
        targets = set()
        tree = ast.parse(path.read_text(encoding='utf-8'), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                targets.update(alias.name for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = from_module(node, module, is_package)
                # "from pkg import name": the module pkg.name when there is one, else pkg.
                targets.update(f'{base}.{alias.name}' if f'{base}.{alias.name}' in paths
                               else base for alias in node.names)
        graph[module] = sorted(t for t in targets if t in paths and t != module)
    return graph


def import_circles(root: Path, package: str) -> list:
    """Return each set of modules of ``package`` that import one another round (sorted names)."""
    graph = import_graph(root, package)
    reaches = {}
    for start in graph:
        seen, todo = set(), list(graph[start])
        while todo:
            module = todo.pop()
            if module not in seen:
                seen.add(module)
                todo.extend(graph[module])
        reaches[start] = seen
    # A module on a circle reaches itself; its circle is every module it reaches that reaches it.
    circles = {tuple(sorted({start} | {m for m in reaches[start] if start in reaches[m]}))
               for start in graph if start in reaches[start]}
    return sorted(list(circle) for circle in circles)


# -- the package itself ----------------------------------------------------------------


@pytest.mark.parametrize('layer', sorted(MUST_NOT_LOAD))
def test_the_ros_free_layers_load_no_ros(layer):
    """Importing all of model, physics, sim or recording loads none of MUST_NOT_LOAD's modules."""
    watched = MUST_NOT_LOAD[layer]
    assert module_names(Path(REPO), PACKAGE, layer)
    assert loaded_by_importing(Path(REPO), PACKAGE, layer, watched) == []


def test_every_import_goes_to_the_same_layer_or_a_lower_one():
    """
    Each import of r2d2_sim in r2d2_sim, top-level or in a function, points down or across.

    A module outside every layer (a new folder or top-level module) is reported too.
    """
    assert layer_violations(Path(REPO), PACKAGE) == []


def test_no_modules_import_one_another_round():
    """
    No import circle, top-level, in a function or for the type checker only.

    A function's import hides a circle, not ends it, and so does one under
    ``if TYPE_CHECKING:``. The farm's places and scenario were one (each
    needed ScenarioError of the other); the kit's Target and its parts, the
    harnesses and their robot handles were others (each part now names a
    Protocol of what it uses: conformance.calls, testing.robots' hosts).
    """
    assert import_circles(Path(REPO), PACKAGE) == []


# -- each check can fail ---------------------------------------------------------------


FAULTY = {
    'fakepkg/__init__.py': '',
    'fakepkg/errors.py': '',
    'fakepkg/model/__init__.py': '',
    'fakepkg/model/math_ok.py': 'from fakepkg.errors import *\nimport fakepkg.model\n',
    'fakepkg/model/uses_engine.py': 'import pybullet\n',
    'fakepkg/model/reaches_up.py': 'from fakepkg.ros import node\n',
    'fakepkg/physics/__init__.py': '',
    'fakepkg/physics/relative.py': 'from ..ros.node import thing\nfrom . import engine\n',
    'fakepkg/physics/engine.py': 'import pybullet\n',
    'fakepkg/sim/__init__.py': '',
    'fakepkg/sim/core.py': textwrap.dedent('''\
        from fakepkg.physics import engine


        def later():
            from fakepkg import apps
            return apps
        '''),
    'fakepkg/recording/__init__.py': '',
    'fakepkg/recording/sink.py': 'import rclpy\n',
    'fakepkg/ros/__init__.py': '',
    'fakepkg/ros/node.py': 'import rclpy\nthing = 1\n',
    'fakepkg/apps/__init__.py': '',
    'fakepkg/gadgets.py': '',
    # A circle of three in one layer: absolute, relative, and inside a function.
    'fakepkg/apps/one.py': 'from fakepkg.apps import two\n',
    'fakepkg/apps/two.py': 'from .three import thing\n',
    'fakepkg/apps/three.py': 'thing = 1\n\n\ndef later():\n    import fakepkg.apps.one\n',
    # A part that names the whole it belongs to, for the checker only: a circle still.
    'fakepkg/apps/whole.py': 'from fakepkg.apps.part import Part\n',
    'fakepkg/apps/part.py': ('from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n'
                             '    from fakepkg.apps.whole import Whole\nPart = 1\n'),
    # A part that names a seam both import: no circle.
    'fakepkg/apps/seam.py': 'from typing import Protocol\nclass Host(Protocol): ...\n',
    'fakepkg/apps/host.py': 'from fakepkg.apps.seam import Host\nfrom fakepkg.apps import piece\n',
    'fakepkg/apps/piece.py': 'from fakepkg.apps.seam import Host\n',
    # Stand-ins, so that the fresh interpreter finds these names without loading the real ones.
    'rclpy.py': '',
    'pybullet.py': '',
}


@pytest.fixture
def faulty(tmp_path):
    """Write a small package with one module of each kind of fault; return its parent folder."""
    for name, text in FAULTY.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    return tmp_path


def test_the_import_check_names_each_layer_that_loads_what_it_must_not(faulty):
    """The faulty model loads PyBullet and rclpy, recording rclpy, sim PyBullet; errors none."""
    assert loaded_by_importing(faulty, 'fakepkg', 'model', ['rclpy', 'pybullet']) == [
        'pybullet', 'rclpy']  # rclpy through model/reaches_up.py -> ros/node.py
    assert loaded_by_importing(faulty, 'fakepkg', 'recording', ['rclpy']) == ['rclpy']
    assert loaded_by_importing(faulty, 'fakepkg', 'sim', ['pybullet']) == ['pybullet']
    assert loaded_by_importing(faulty, 'fakepkg', 'errors', ['rclpy', 'pybullet']) == []


def test_the_static_check_names_each_import_that_goes_up(faulty):
    """Absolute, relative and in-function imports of a higher layer; a module of no layer."""
    assert layer_violations(faulty, 'fakepkg') == [
        'fakepkg/gadgets.py: not in any layer',
        'fakepkg/model/reaches_up.py:1: fakepkg.model.reaches_up imports fakepkg.ros',
        'fakepkg/physics/relative.py:1: fakepkg.physics.relative imports fakepkg.ros.node',
        'fakepkg/sim/core.py:5: fakepkg.sim.core imports fakepkg.apps',
    ]


def test_the_circle_check_names_modules_that_import_one_another_round(faulty):
    """One, two and three import one another round, and a part its whole for the checker."""
    assert import_circles(faulty, 'fakepkg') == [
        ['fakepkg.apps.one', 'fakepkg.apps.three', 'fakepkg.apps.two'],
        ['fakepkg.apps.part', 'fakepkg.apps.whole']]
