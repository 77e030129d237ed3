"""
The types are checked, not only written: mypy over the package, with setup.cfg's settings.

``model``, ``physics``, ``sim``, ``ros``, ``recording``, ``testing``, ``apps`` and ``gym``
(setup.cfg's ``[mypy] files``) are held at zero errors: the typed seams between
translation and the core mean something only while a checker holds the code to them,
and the testing API ships ``py.typed``, so its signatures are what users' checkers see.
The rest of the package (the farm, the kit, the scenarios) is counted and may not grow past
:data:`REST_AT_MOST` (a ratchet: lower it as it falls). A file written for the purpose
proves that the check finds what it looks for. Imports no ROS: part of the fast tier.
"""

from pathlib import Path
import re
import subprocess
import sys
import textwrap

from common import REPO

LAYERS = ['r2d2_sim/model', 'r2d2_sim/physics', 'r2d2_sim/sim', 'r2d2_sim/ros',
          'r2d2_sim/recording', 'r2d2_sim/testing', 'r2d2_sim/apps', 'r2d2_sim/gym']
# The errors mypy finds in the rest of the package; it may fall, never rise.
REST_AT_MOST = 16
SUMMARY = re.compile(r'Found (\d+) errors? in')


def mypy(*paths: str, cwd: str = REPO) -> subprocess.CompletedProcess:
    """Run mypy with the repository's configuration over ``paths``."""
    return subprocess.run(
        [sys.executable, '-m', 'mypy', '--config-file', str(Path(REPO) / 'setup.cfg'),
         *paths], cwd=cwd, capture_output=True, text=True, timeout=600)


def error_count(result: subprocess.CompletedProcess) -> int:
    """Return how many errors a mypy run reported (0 for a clean one)."""
    found = SUMMARY.search(result.stdout)
    if found is None:
        assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
        return 0
    return int(found.group(1))


def test_the_core_layers_have_no_type_error_and_the_rest_no_more_than_before():
    """
    One mypy run over the package: nothing in the layers of LAYERS; the rest counted.

    The lines found in those layers are the failure's message; the count of the rest
    (print) stays at or below REST_AT_MOST.
    """
    result = mypy('r2d2_sim')
    errors = [line for line in result.stdout.splitlines() if ': error:' in line]
    core = [line for line in errors if any(line.startswith(layer + '/') for layer in LAYERS)]
    assert core == [], '\n'.join(core[:50])
    print(f'mypy: {len(errors)} errors in the rest of the package')
    assert len(errors) == error_count(result)
    assert len(errors) <= REST_AT_MOST, '\n'.join(errors[:50])


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
