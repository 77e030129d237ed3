"""
The types are checked, not only written: mypy over the whole package, with setup.cfg's settings.

Every layer is held at zero errors: the typed seams between translation and the core
mean something only while a checker holds the code to them, and the package ships
``py.typed``, so the testing API's signatures are what users' checkers see. A file
written for the purpose proves that the check finds what it looks for. Imports no
ROS: part of the fast tier.
"""

import os
from pathlib import Path
import re
import subprocess
import sys
import textwrap

from common import REPO

SUMMARY = re.compile(r'Found (\d+) errors? in')


def cache_dir() -> str:
    """
    Return where mypy keeps what it learnt: MYPY_CACHE_DIR, else the user's r2d2_sim cache.

    Shared by every checkout (mypy checks each file's hash against it), so a
    fresh clone's first run does not analyse numpy and the ROS wheels again:
    42 s cold, under 1 s warm, on our 2 cores.
    """
    if os.environ.get('MYPY_CACHE_DIR'):
        return os.environ['MYPY_CACHE_DIR']
    home = os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return os.path.join(home, 'r2d2_sim', 'mypy')


def mypy(*paths: str, cwd: str = REPO) -> subprocess.CompletedProcess:
    """Run mypy with the repository's configuration over ``paths``."""
    return subprocess.run(
        [sys.executable, '-m', 'mypy', '--config-file', str(Path(REPO) / 'setup.cfg'),
         '--cache-dir', cache_dir(), *paths], cwd=cwd, capture_output=True, text=True,
        timeout=600)


def error_count(result: subprocess.CompletedProcess) -> int:
    """Return how many errors a mypy run reported (0 for a clean one)."""
    found = SUMMARY.search(result.stdout)
    if found is None:
        assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
        return 0
    return int(found.group(1))


def test_the_package_has_no_type_error():
    """One mypy run over r2d2_sim finds nothing (the lines it finds otherwise)."""
    result = mypy('r2d2_sim')
    errors = [line for line in result.stdout.splitlines() if ': error:' in line]
    assert errors == [], '\n'.join(errors[:50])
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]


def test_the_check_finds_a_wrong_type(tmp_path):
    """A function given a string where it takes an int is an error, in one line."""
    package = tmp_path / 'typed_probe'
    package.mkdir()
    (package / '__init__.py').write_text('')
    (package / 'wrong.py').write_text(textwrap.dedent('''\
        def double(x: int) -> int:
            return 2 * x


        VALUE = double('two')
        '''))
    result = mypy(str(package), cwd=str(tmp_path))
    assert error_count(result) == 1
    assert 'wrong.py:5: error: Argument 1 to "double" has incompatible type "str"' in \
        result.stdout
