"""
run.sh keeps the installed requirements in the user's cache; a new checkout's venv links them.

The two functions of run.sh (``venv_to_cache``, ``venv_from_cache``) are taken
from the script itself and run with bash on two checkouts in a temporary
home: the first's venv goes to the cache as hard links, the second's comes
from it with its scripts naming its own interpreter, while the cached files
keep theirs; other requirements find nothing cached.
"""

import os
from pathlib import Path
import re
import subprocess
import sys

from common import REPO


def run_sh_functions():
    """Return run.sh's venv cache functions (from VENV_CACHE= to setup_venv), as bash text."""
    text = (Path(REPO) / 'run.sh').read_text(encoding='utf-8')
    found = re.search(r'^VENV_CACHE=.*?(?=^setup_venv\(\))', text, re.S | re.M)
    assert found, 'run.sh no longer keeps its venv in a cache'
    return found.group(0)


def call(checkout: Path, home: Path, function: str) -> subprocess.CompletedProcess:
    """Run one of the functions in ``checkout`` as run.sh does (VENV=.venv), home in ``home``."""
    script = f'set -euo pipefail\nVENV=.venv\n{run_sh_functions()}\n{function}\n'
    env = {**os.environ, 'XDG_CACHE_HOME': str(home / 'cache')}
    return subprocess.run(['bash', '-c', script], cwd=checkout, env=env, capture_output=True,
                          text=True, timeout=60)


def checkout(root: Path, name: str, requirements: str) -> Path:
    """Make a checkout with a requirements file."""
    path = root / name
    path.mkdir()
    (path / 'requirements.txt').write_text(requirements)
    return path


def test_a_second_checkout_links_the_first_ones_venv_with_its_own_scripts(tmp_path):
    first = checkout(tmp_path, 'first', 'numpy\n')
    subprocess.run([sys.executable, '-m', 'venv', '--without-pip', str(first / '.venv')],
                   check=True, timeout=120)
    tool = first / '.venv' / 'bin' / 'tool'
    tool.write_text(f'#!{first}/.venv/bin/python\nprint("tool")\n')
    tool.chmod(0o755)
    library = first / '.venv' / 'lib' / 'module.py'
    library.write_text('x = 1\n')
    result = call(first, tmp_path, 'venv_to_cache')
    assert result.returncode == 0, result.stderr
    (cached,) = (tmp_path / 'cache' / 'r2d2_sim').glob('venv-*')

    second = checkout(tmp_path, 'second', 'numpy\n')
    result = call(second, tmp_path, 'venv_from_cache')
    assert result.returncode == 0, result.stderr
    venv = second / '.venv'
    assert (venv / 'bin' / 'tool').read_text().splitlines()[0] == f'#!{second}/.venv/bin/python'
    assert os.access(venv / 'bin' / 'tool', os.X_OK)
    assert (cached / 'bin' / 'tool').read_text().splitlines()[0] == f'#!{first}/.venv/bin/python'
    # Linked, not copied; and its interpreter runs.
    assert (venv / 'lib' / 'module.py').stat().st_ino == library.stat().st_ino
    ran = subprocess.run([str(venv / 'bin' / 'python'), '-c', 'import sys; print(sys.prefix)'],
                         capture_output=True, text=True, check=True, timeout=60)
    assert ran.stdout.strip() == str(venv)
    # Installed as of now: run.sh does not install the requirements again.
    assert (venv / '.installed').stat().st_mtime >= (second / 'requirements.txt').stat().st_mtime
    assert not (venv / '.origin').exists() and not Path(f'{venv}.new').exists()

    other = checkout(tmp_path, 'other', 'numpy\nscipy\n')
    assert call(other, tmp_path, 'venv_from_cache').returncode == 1
    assert not (other / '.venv').exists()
