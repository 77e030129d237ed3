"""
The farm's pytest plugin in a pytest of its own: names, crashes, and what a case's verdict is.

- Every failing test gets a recording of its own, whatever its folder and
  parameters (two ``test_farm.py::test[0]`` in two folders, ids with '/').
- A run that raises is a crashed case of the report (never "N of N passed"),
  and reruns from it.
- A case passes only when its verdict and its test did: a test failing on
  its own assertion fails its runs, and a property's final example is
  recorded and noted whatever its verdict.

No physics runs here: the project's conftest.py replaces ``run_scenario`` with
a fake that judges by the seed (odd fails, 3 raises) and, like the simulator, refuses a
recording file that exists. Real runs are in ``test/system/test_farm_system.py``.
"""

import json
import os
from pathlib import Path
import subprocess
import sys

from r2d2_sim.farm.pytest_plugin import _slug

REPO = Path(__file__).resolve().parents[2]
# A farm without physics: odd seeds fail; a recording is made as the simulator makes
# it (refused if its file exists), empty.
FAKE_RUNS = '''
import r2d2_sim.farm.run as run


def fake_run(scenario, controller, *, seconds, record=None, record_failure=None, **keywords):
    if scenario.seed == 3:
        raise RuntimeError("a bug in the user's node")  # as a CallbackError would
    passed = scenario.seed % 2 == 0
    recording = record if passed or record else record_failure
    if recording is not None:
        with open(recording, 'x'):  # the simulator refuses an MCAP file that exists
            pass
    return run.Outcome(scenario=scenario, passed=passed, reason='' if passed else 'odd seed',
                       seconds=seconds, time_to_goal_s=0.5, clearance_m=2.0, closest=None,
                       closest_s=None, contacts=(), tipped_s=None, trajectory=(), steps=240,
                       recording=recording)


run.run_scenario = fake_run
'''
SEEDED = '''
import pytest

from r2d2_sim.farm import Scenario


@pytest.mark.parametrize('seed', [1])
@pytest.mark.parametrize('where', ['maps/late'])
def test_it(r2d2_farm, where, seed):
    assert r2d2_farm.run(Scenario(seed=seed), None, seconds=1.0).passed
'''


CRASHING = '''
import pytest

from r2d2_sim.farm import Scenario


@pytest.mark.parametrize('seed', [2, 3, 4])
def test_it(r2d2_farm, seed):
    assert r2d2_farm.run(Scenario(seed=seed), None, seconds=1.0).passed
'''


OWN_ASSERTIONS = '''
import pytest
from hypothesis import given

from r2d2_sim.farm import farm_settings, Scenario, scenarios, ScenarioSpace


@pytest.mark.parametrize('seed', [2])
def test_seeded(r2d2_farm, seed):
    outcome = r2d2_farm.run(Scenario(seed=seed), None, seconds=1.0)
    assert outcome.passed
    assert outcome.clearance_m > 5.0, 'clearance'  # a measure the verdict does not judge


def test_two_runs(r2d2_farm):
    first = r2d2_farm.run(Scenario(seed=2), None, seconds=1.0)
    second = r2d2_farm.run(Scenario(seed=1), None, seconds=1.0)  # its verdict fails
    assert first.passed and second.passed


@farm_settings(max_examples=5)
@given(scenario=scenarios(ScenarioSpace(obstacles=(0, 2))))
def test_property(r2d2_farm, scenario):
    outcome = r2d2_farm.run(scenario, None, seconds=1.0)
    assert outcome.clearance_m > 5.0, 'clearance'
'''


def environment() -> dict:
    """Return this process's environment with the checkout first on PYTHONPATH."""
    return dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (str(REPO), os.environ.get('PYTHONPATH')) if p))


def farm(project: Path, *args: str) -> subprocess.CompletedProcess:
    """Run pytest with the farm plugin in ``project``; its farm directory is project/farm."""
    (project / 'conftest.py').write_text(FAKE_RUNS)
    return subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                           '-p', 'r2d2_sim.farm.pytest_plugin', '--farm-dir', 'farm', *args],
                          cwd=project, env=environment(), capture_output=True, text=True,
                          timeout=300)


def cases(project: Path) -> list:
    """Return the cases of the project's farm report."""
    return json.loads((project / 'farm' / 'report.json').read_text())['cases']


def test_a_name_is_readable_and_unique_to_its_node_id():
    """Folders, file, test and parameters, cut to fit; a '/' in a parameter cuts nothing."""
    first, second = (_slug(f'{name}.py::test[maps/late-0]') for name in ('nav/a', 'dock/a'))
    assert first.startswith('nav-a-test-maps-late-0-') and second.startswith('dock-a-test-')
    assert first != second
    assert _slug('x/t.py::test[0]') != _slug('x-t.py::test[0]')  # the same readable part
    long = 'test_farm.py::test[' + 'x' * 300
    assert len(_slug(long)) < 100 and _slug(long) != _slug(long + 'y')


def test_two_failing_tests_of_one_name_in_two_folders_keep_a_recording_each(tmp_path):
    """nav/test_farm.py::test_it[...] and dock/...: both reported, each with its own file."""
    for folder in ('nav', 'dock'):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / '__init__.py').write_text('')
        (tmp_path / folder / 'test_farm.py').write_text(SEEDED)
    result = farm(tmp_path, '-n', '2', 'nav', 'dock')
    assert '2 failed' in result.stdout, result.stdout[-3000:]
    found = cases(tmp_path)
    assert [c['nodeid'].split('/')[0] for c in found] == ['dock', 'nav']
    assert not any(c['passed'] or c['crashed'] for c in found)
    recordings = {c['recording'] for c in found}
    assert len(recordings) == 2 and all(Path(r).is_file() for r in recordings)


def test_a_run_that_raises_is_a_crashed_case_and_reruns_from_the_report(tmp_path):
    """Seeds 2, 3, 4, the run of 3 raising: 2 of 3 passed, 1 crashed with its seed and why."""
    (tmp_path / 'test_crash.py').write_text(CRASHING)
    result = farm(tmp_path, 'test_crash.py')
    assert '1 failed, 2 passed' in result.stdout, result.stdout[-3000:]
    assert "RuntimeError: a bug in the user's node" in result.stdout  # the test's failure
    report = json.loads((tmp_path / 'farm' / 'report.json').read_text())
    summary = report['summary']
    assert (summary['runs'], summary['passed'], summary['failed'], summary['crashed']) == \
        (3, 2, 0, 1)
    (crashed,) = [c for c in report['cases'] if c['crashed']]
    assert crashed['seed'] == 3 and not crashed['passed']
    assert crashed['reason'] == "raised RuntimeError: a bug in the user's node"
    assert 'fake_run' in crashed['traceback']
    markdown = (tmp_path / 'farm' / 'report.md').read_text()
    assert '| passed | 2 of 3 (66.7 %) |' in markdown and '## Crashed (1)' in markdown

    again = subprocess.run([sys.executable, '-m', 'r2d2_sim.farm', 'rerun', 'farm/report.json',
                            '--case', str(crashed['case'])], cwd=tmp_path, env=environment(),
                           capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stdout[-2000:] + again.stderr[-2000:]
    assert ("the report has it crashed (raised RuntimeError: a bug in the user's node); this "
            "time it raised RuntimeError: a bug in the user's node") in again.stdout


def test_a_test_failing_on_its_own_assertion_fails_its_cases_and_keeps_the_final_example(
        tmp_path):
    """Verdicts passed, tests failed: failed cases; the property's shrunk run recorded, noted."""
    (tmp_path / 'test_own.py').write_text(OWN_ASSERTIONS)
    result = farm(tmp_path, 'test_own.py')
    assert '3 failed' in result.stdout, result.stdout[-3000:]
    assert 'r2d2_farm: the verdict passed: the test failed on its own; recording: ' in \
        result.stdout
    found = {}
    for case in cases(tmp_path):
        found.setdefault(case['nodeid'].split('::')[1].split('[')[0], case)
    seeded, prop = found['test_seeded'], found['test_property']
    for case in seeded, prop:
        assert case['outcome']['passed'] and not case['passed'] and not case['crashed']
        assert case['reason'].startswith('the verdict passed, the test failed: AssertionError: '
                                         'clearance'), case['reason']
    assert seeded['recording'] is None  # a passing verdict: not run again to record it
    assert prop['property'] and Path(prop['recording']).is_file()
    (scenario,) = (tmp_path / 'farm' / 'scenarios').glob('*.json')
    assert scenario.read_text().strip() == json.dumps(prop['outcome']['scenario'],
                                                      sort_keys=True)
    # A failed verdict explains its test's failure: the test's other run keeps its verdict.
    two = [(c['run'], c['passed']) for c in cases(tmp_path) if 'test_two_runs' in c['nodeid']]
    assert two == [(0, True), (1, False)]
    markdown = (tmp_path / 'farm' / 'report.md').read_text()
    assert '| passed | 1 of 4 (25.0 %) |' in markdown and '## Failures (3)' in markdown
