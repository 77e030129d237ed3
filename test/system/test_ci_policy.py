"""
The suite's own rule for CI: a skipped test fails the run there (R2D2_SIM_CI, set by .ci/run).

A feature whose test skips in CI (no browser, no display, no interface
package) would otherwise pass unnoticed. Checked on a copy of this suite's
conftest with one passing and one skipping test, in a pytest of its own.
"""

import os
from pathlib import Path
import shutil
import subprocess
import sys

import pytest

TEST_DIR = Path(__file__).resolve().parent.parent
SKIPPING = '''
import pytest


def test_runs():
    pass


@pytest.mark.skip(reason='no browser here')
def test_needs_a_browser():
    pass
'''


@pytest.mark.parametrize('ci, status', [('1', 1), ('', 0)], ids=['in CI', 'elsewhere'])
def test_a_skip_fails_a_ci_run_and_only_there(tmp_path, ci, status):
    """Under R2D2_SIM_CI a skip makes the exit status 1, naming the rule; elsewhere 0."""
    for name in ('conftest.py', 'common.py'):
        shutil.copy(TEST_DIR / name, tmp_path / name)
    (tmp_path / 'test_skipping.py').write_text(SKIPPING)
    env = dict(os.environ, R2D2_SIM_CI=ci)
    result = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-rs', '-p', 'no:cacheprovider',
                             str(tmp_path)], cwd=tmp_path, env=env,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == status, result.stdout[-2000:] + result.stderr[-2000:]
    assert 'no browser here' in result.stdout  # -rs: the reason is shown either way
    assert ('1 test(s) skipped, which CI must not' in result.stdout) == bool(ci)
