"""
The old public names of r2d2_sim.deprecations: each works, warns once, and points somewhere.

- Every entry of the table points somewhere, read from the sources without
  importing them: the new module exists and binds the new name; the old module
  path is no module any more (a real one would win over the alias, which would
  then never be used); an old name lives in an alias's view or on a module whose
  ``__getattr__`` asks :func:`~r2d2_sim.deprecations.renamed`. The same check
  finds each kind of fault in a table written for the purpose.
- In a fresh interpreter, every old path gives the new object (the module
  itself, or for a view each name of it), with exactly one ``DeprecationWarning``
  that names the new path and the version that removes the old one, pointing
  at the line that used the old name. ROS is imported there only (old paths of
  the ROS layer load rclpy), so this file runs in the fast tier.
- ``python -m`` on an old path runs the new module; ``import r2d2_sim`` loads
  nothing but the package and its table.
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
from r2d2_sim.deprecations import MOVED, REMOVED_IN

ROOT = Path(REPO)
USED_IN = '<old-names>'  # the file name the child gives the lines that use old names


def _source(module):
    """Return the source file of a dotted module name under ROOT, or None."""
    path = ROOT.joinpath(*module.split('.'))
    for candidate in (path.with_suffix('.py'), path / '__init__.py'):
        if candidate.is_file():
            return candidate
    return None


def _bound_names(path):
    """Return the names a module binds at its top level (defined, assigned or imported)."""
    names = set()
    for node in ast.parse(path.read_text(encoding='utf-8'), str(path)).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split('.')[0] for a in node.names)
    return names


def table_problems(table):
    """Return one line for each entry of ``table`` that points nowhere or can never be used."""
    problems = []
    for old, new in table.items():
        old_module, _, old_name = old.partition(':')
        new_module, _, new_name = new.partition(':')
        if bool(old_name) != bool(new_name):
            problems.append(f'{old} -> {new}: a module and a name')
            continue
        new_source = _source(new_module)
        if new_source is None:
            problems.append(f'{old} -> {new}: no module {new_module}')
        elif new_name and new_name not in _bound_names(new_source):
            problems.append(f'{old} -> {new}: {new_module} has no {new_name}')
        old_source = _source(old_module)
        if not old_name:
            if old_source is not None:
                problems.append(f'{old}: is a module, so the alias is never used')
        elif old_module in table:
            continue  # a name of an alias's view
        elif old_source is None:
            problems.append(f'{old}: no module {old_module}, and no alias of it')
        elif old_name in _bound_names(old_source):
            problems.append(f'{old}: {old_module} binds {old_name}, so the alias is never used')
        elif ('__getattr__' not in _bound_names(old_source)
              or 'renamed(' not in old_source.read_text(encoding='utf-8')):
            problems.append(f'{old}: {old_module} has no __getattr__ that asks renamed()')
    return problems


def _dotted(path):
    return path.replace(':', '.')


def _child_env():
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(p for p in (str(ROOT), env.get('PYTHONPATH')) if p)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    return env


def _run(args):
    return subprocess.run([sys.executable] + args, cwd=ROOT, env=_child_env(),
                          capture_output=True, text=True, timeout=180)


# -- every entry points somewhere ---------------------------------------------------------


def test_every_entry_of_the_table_points_somewhere():
    """Each new path exists and binds its name; each old one is no module any more."""
    assert table_problems(MOVED) == []


def test_the_table_check_finds_each_kind_of_fault():
    """A table with one entry of each fault, and two good ones that are not reported."""
    faulty = {
        'r2d2_sim.gone': 'r2d2_sim.nowhere',
        'r2d2_sim.gone_too': 'r2d2_sim.ros.node',
        'r2d2_sim.gone_too:Thing': 'r2d2_sim.ros.node:NoThing',
        'r2d2_sim.client': 'r2d2_sim.ros.node',
        'r2d2_sim.errors:OldError': 'r2d2_sim.errors:RefusedError',
        'r2d2_sim.errors:StartupError': 'r2d2_sim.errors:StartupError',
        'r2d2_sim.vanished:Name': 'r2d2_sim.errors:RefusedError',
        'r2d2_sim.testing:OldName': 'r2d2_sim.testing:RefusedError',
        'r2d2_sim.half': 'r2d2_sim.errors:RefusedError',
    }
    assert table_problems(faulty) == [
        'r2d2_sim.gone -> r2d2_sim.nowhere: no module r2d2_sim.nowhere',
        'r2d2_sim.gone_too:Thing -> r2d2_sim.ros.node:NoThing: '
        'r2d2_sim.ros.node has no NoThing',
        'r2d2_sim.client: is a module, so the alias is never used',
        'r2d2_sim.errors:OldError: r2d2_sim.errors has no __getattr__ that asks renamed()',
        'r2d2_sim.errors:StartupError: r2d2_sim.errors binds StartupError, '
        'so the alias is never used',
        'r2d2_sim.vanished:Name: no module r2d2_sim.vanished, and no alias of it',
        'r2d2_sim.half -> r2d2_sim.errors:RefusedError: a module and a name',
    ]


# -- every old path works and warns once ----------------------------------------------------


RESOLVE_ALL = textwrap.dedent('''
    import importlib, json, warnings
    from r2d2_sim.deprecations import MOVED

    USED_IN = %r
    results = {}


    def attempt(key, statement, same):
        """Run the statement that uses an old path; record the object and our warnings."""
        space = {}
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter('always')
            try:
                exec(compile(statement, USED_IN, 'exec'), space)
                error, found = None, same(space['alias'])
            except Exception as exc:
                error, found = f'{type(exc).__name__}: {exc}', False
        ours = [[str(w.message), w.filename] for w in caught
                if issubclass(w.category, DeprecationWarning) and 'r2d2_sim' in str(w.message)]
        results[key] = {'error': error, 'same': found, 'warnings': ours}


    def module_is_new(new):
        def same(alias):
            target = importlib.import_module(new)
            return alias is target or all(getattr(alias, name) is getattr(target, name)
                                          for name in dir(target) if not name.startswith('_'))
        return same


    def name_is_new(new):
        module, _, name = new.partition(':')
        return lambda alias: alias is getattr(importlib.import_module(module), name)


    # Modules first: a name of a view is then used with its module already imported.
    for old, new in sorted(MOVED.items(), key=lambda item: ':' in item[0]):
        module, _, name = old.partition(':')
        if name:
            attempt(old, f'from {module} import {name} as alias', name_is_new(new))
        else:
            attempt(old, f'import {old} as alias', module_is_new(new))
    print(json.dumps(results))
''') % USED_IN


@pytest.fixture(scope='module')
def resolved():
    """Use every old path of the table once, in a fresh interpreter; return what each gave."""
    result = _run(['-c', RESOLVE_ALL])
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize('old', sorted(MOVED))
def test_an_old_path_gives_the_new_object_and_warns_once(resolved, old):
    """
    The old path's object is the new one; one warning names the new path, at the user's line.

    A module of the package that used an old path would have imported it before
    the child does: no warning then, and this fails.
    """
    outcome = resolved[old]
    assert outcome['error'] is None, outcome['error']
    assert outcome['same'], f'{old} does not give what {MOVED[old]} is'
    message = (f'{_dotted(old)} is deprecated and goes in r2d2_sim {REMOVED_IN}: '
               f'use {_dotted(MOVED[old])}')
    assert outcome['warnings'] == [[message, USED_IN]]


def test_python_dash_m_on_an_old_path_runs_the_new_module():
    """`python -m` on the old path of the parameter reference runs the new one, and says so."""
    old = _run(['-m', 'r2d2_sim.sim.parameter_docs'])
    new = _run(['-m', MOVED['r2d2_sim.sim.parameter_docs']])
    assert old.returncode == new.returncode == 0, old.stderr[-2000:]
    assert old.stdout == new.stdout and old.stdout.startswith('<!--')
    assert new.stderr == ''
    assert old.stderr.count('DeprecationWarning') == 1, old.stderr
    assert ('r2d2_sim.sim.parameter_docs is deprecated and goes in r2d2_sim '
            f'{REMOVED_IN}: use r2d2_sim.sim.settings.reference') in old.stderr


def test_importing_r2d2_sim_loads_only_the_package_and_its_table():
    """The finder costs one small module: nothing else is imported until an old name is used."""
    script = ('import json, sys; before = set(sys.modules); import r2d2_sim; '
              'print(json.dumps(sorted(set(sys.modules) - before)))')
    result = _run(['-c', script])
    assert result.returncode == 0, result.stderr[-2000:]
    assert json.loads(result.stdout.strip().splitlines()[-1]) == [
        'r2d2_sim', 'r2d2_sim.deprecations']
