"""
``./run.sh`` puts setup.py's executables in ``.venv/bin``, each running this checkout.

A new user found ``sim_conformance`` on PATH only after a pip install, never in
``./run.sh``'s tree. Any ``./run.sh`` command now writes a small wrapper into
``.venv/bin`` for every ``console_scripts`` entry of setup.py: this test runs
``./run.sh sim --help``, then each wrapper's ``--help`` from another directory
with no PYTHONPATH. The names come from setup.py itself, so a new executable
without a wrapper fails here. A pip install's own script is never overwritten.
"""

import os
import subprocess
import sys

import pytest

from common import REPO, setup_py_console_scripts

VENV_BIN = os.path.join(REPO, '.venv', 'bin')
TOOL = os.path.join(REPO, 'tools', 'console_scripts.py')


def setup_py_executables():
    """Return the console_scripts names of setup.py (read here, not by the tool under test)."""
    return [entry.split('=')[0].strip() for entry in setup_py_console_scripts()]


EXECUTABLES = setup_py_executables()


@pytest.fixture(scope='module')
def run_sh_ran():
    """Run one ./run.sh command (the quickest: the simulator's --help)."""
    if not os.path.isfile(os.path.join(VENV_BIN, 'python')):
        pytest.skip('no .venv in this checkout (./run.sh makes it)')
    result = subprocess.run(['./run.sh', 'sim', '--help'], cwd=REPO, capture_output=True,
                            text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]


def test_setup_py_has_the_executables_a_user_reads_about():
    assert {'sim_node', 'sim_conformance', 'demo', 'drive', 'replay'} <= set(EXECUTABLES)


@pytest.mark.parametrize('name', EXECUTABLES)
def test_after_run_sh_each_executable_runs_this_checkout(run_sh_ran, name, tmp_path):
    path = os.path.join(VENV_BIN, name)
    assert os.access(path, os.X_OK), f'./run.sh wrote no {path}'
    env = {k: v for k, v in os.environ.items() if k != 'PYTHONPATH'}
    result = subprocess.run([path, '--help'], cwd=tmp_path, env=env, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.startswith(f'usage: {name} '), result.stdout[:200]


def test_a_pip_installs_own_script_is_left_alone(tmp_path):
    (tmp_path / 'bin').mkdir()
    pip_script = '#!/usr/bin/python\n# pip\'s script\n'
    (tmp_path / 'bin' / 'demo').write_text(pip_script)
    result = subprocess.run([sys.executable, '-S', TOOL, str(tmp_path)], capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / 'bin' / 'demo').read_text() == pip_script
    assert sorted(os.listdir(tmp_path / 'bin')) == sorted(EXECUTABLES)
    wrapper = (tmp_path / 'bin' / 'sim_conformance')
    written = wrapper.stat().st_mtime_ns
    subprocess.run([sys.executable, '-S', TOOL, str(tmp_path)], check=True, timeout=60)
    assert wrapper.stat().st_mtime_ns == written  # unchanged: not written again
