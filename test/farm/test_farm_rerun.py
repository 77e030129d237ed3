"""
``python -m r2d2_sim.farm rerun``: which test it runs, from where, and which run it compares.

- A report names the code to run only inside the project the rerun is
  started in: a received report whose case lies elsewhere is refused in one
  line before anything runs, and a case found in the project runs the
  project's file, never the report's directory's ``conftest.py`` or modules.
- The rerun's run that is compared with the report's is the same test
  (wherever pytest's rootdir was), the same run of a seeded test, the same
  final run of a property.

No physics runs here (the cases' tests never call the farm); the reruns of
real runs are in ``test/system/test_farm_system.py``.
"""

import json
import os
from pathlib import Path
import subprocess
import sys

import pytest

from r2d2_sim.farm.__main__ import main
from r2d2_sim.farm.rerun import load_case, locate, ReportError, same_run
from r2d2_sim.farm.report import write_report
from r2d2_sim.farm.run import Outcome
from r2d2_sim.farm.scenario import Scenario

REPO = Path(__file__).resolve().parents[2]
# A conftest.py and a pytest.py that leave a mark when anything imports them.
MARKING = 'from pathlib import Path\nPath({mark!r}).write_text("ran")\n'


def outcome(seed=0, passed=False):
    """Return an outcome as a report keeps it (a run that never reached its goal)."""
    return Outcome(scenario=Scenario(seed=seed), passed=passed,
                   reason='' if passed else 'goal not reached in 1 s', seconds=1.0,
                   time_to_goal_s=None, clearance_m=2.0, closest=None, closest_s=None,
                   contacts=(), tipped_s=None, trajectory=(), steps=240).to_dict()


def record(nodeid, rootdir, run=0, prop=False, seed=0):
    """Return a farm record of a run of ``nodeid`` by a pytest whose rootdir was ``rootdir``."""
    return {'nodeid': nodeid, 'rootdir': str(rootdir), 'run': run, 'worker': '',
            'property': prop, 'outcome': outcome(seed)}


def rerun(report, cwd, *more):
    """Run ``python -m r2d2_sim.farm rerun REPORT --case 0`` in ``cwd``."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (str(REPO), os.environ.get('PYTHONPATH')) if p))
    return subprocess.run([sys.executable, '-m', 'r2d2_sim.farm', 'rerun', str(report),
                           '--case', '0', *more], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=120)


@pytest.fixture
def received(tmp_path):
    """Provide a project, and a report received from elsewhere whose directory plants code."""
    project, elsewhere = tmp_path / 'project', tmp_path / 'elsewhere'
    project.mkdir()
    elsewhere.mkdir()
    mark = tmp_path / 'planted-code-ran'
    for planted in ('conftest.py', 'pytest.py', 'test_case.py'):
        (elsewhere / planted).write_text(MARKING.format(mark=str(mark)))
    report = write_report([record('test_case.py::test_it', elsewhere)], tmp_path / 'received',
                          invocation_dir=str(elsewhere), rootdir=str(elsewhere),
                          picture=False)['report.json']
    return project, report, mark


def test_a_case_outside_the_project_is_refused_in_one_line_and_nothing_runs(received):
    """The report's test is no file of the project: exit 2, one line, no planted code ran."""
    project, report, mark = received
    result = rerun(report, project)
    assert result.returncode == 2, result.stdout + result.stderr
    assert result.stderr.count('\n') == 1, result.stderr
    assert 'test_case.py' in result.stderr and 'not a file of this project' in result.stderr
    assert str(project) in result.stderr and '--project' in result.stderr
    assert not mark.exists()


def test_a_case_found_in_the_project_runs_the_projects_file_only(received, tmp_path):
    """The same path in the project: that file runs, in the project; it says so first."""
    project, report, mark = received
    (project / 'test_case.py').write_text('def test_it():\n    pass\n')
    # Above the project, beside an ini file pytest finds: not the project's, not loaded.
    (tmp_path / 'pytest.ini').write_text('[pytest]\n')
    (tmp_path / 'conftest.py').write_text(MARKING.format(mark=str(mark)))
    result = rerun(report, project)
    assert not mark.exists(), result.stdout
    said = result.stdout.split('\n-')[0]  # what it says before pytest speaks
    assert f'the test: {project / "test_case.py"}::test_it' in said
    assert 'conftest.py: none' in said
    assert f'in {project}' in said
    assert result.returncode == 1  # the test ran, but it ran no farm case
    assert 'the rerun did not run case 0 again' in result.stderr


def test_the_project_may_be_named(received, tmp_path):
    """--project DIR: the rerun runs there, whatever the current directory."""
    project, report, mark = received
    (project / 'test_case.py').write_text('def test_it():\n    pass\n')
    (project / 'conftest.py').write_text('')
    result = rerun(report, tmp_path, '--project', str(project))
    assert not mark.exists()
    assert f'conftest.py: {project / "conftest.py"}' in result.stdout


def test_a_project_that_is_no_directory_is_one_line(received, tmp_path, capsys):
    """--project naming nothing: exit 2, said as such, nothing run."""
    project, report, mark = received
    assert main(['rerun', str(report), '--case', '0', '--project', str(tmp_path / 'no')]) == 2
    assert capsys.readouterr().err == f'r2d2_sim.farm: error: --project {tmp_path / "no"}: ' \
        'not a directory\n'
    assert not mark.exists()


def test_the_test_found_is_the_projects_most_specific_file_or_none(tmp_path):
    """The report's path when in the project; else the longest tail; never a way out."""
    project = tmp_path / 'checkout'
    for path in ('suite/test_x.py', 'test_x.py', 'test_y.py'):
        (project / path).parent.mkdir(parents=True, exist_ok=True)
        (project / path).write_text('')
    (tmp_path / 'test_out.py').write_text('')
    (project / 'test_link.py').symlink_to(tmp_path / 'test_out.py')
    found = {(rootdir, nodeid): locate({'case': 0, 'rootdir': str(rootdir), 'nodeid': nodeid},
                                       project)
             for rootdir, nodeid in ((tmp_path, 'checkout/test_y.py::t'),
                                     ('/builds/ci', 'checkout/suite/test_x.py::t[1]'),
                                     ('/builds/ci/checkout/suite', 'test_x.py::t'))}
    assert list(found.values()) == [(project / 'test_y.py', 't'),
                                    (project / 'suite' / 'test_x.py', 't[1]'),
                                    (project / 'test_x.py', 't')]
    for rootdir, nodeid in ((tmp_path, 'test_out.py::t'), (project, '../test_out.py::t'),
                            (project, f'{tmp_path}/test_out.py::t'),
                            (project, 'test_link.py::t'), (project, 'suite::t')):
        with pytest.raises(ReportError, match='is not a file of this project'):
            locate({'case': 0, 'rootdir': str(rootdir), 'nodeid': nodeid}, project)


def test_the_run_compared_is_the_same_test_whatever_pytests_rootdir(tmp_path):
    """Node ids relative to two rootdirs name one file; another file or test is not it."""
    (tmp_path / 'suite').mkdir()
    test_file = (tmp_path / 'suite' / 'test_x.py').resolve()
    test_file.write_text('')
    case = {'nodeid': 'suite/test_x.py::test_far[2]', 'run': 1, 'property': False,
            'ordinal': 0}
    runs = [record('suite/test_x.py::test_far[1]', tmp_path, run=1, seed=1),
            record('test_x.py::test_far[2]', tmp_path / 'suite', run=0, seed=2),
            record('test_x.py::test_far[2]', tmp_path / 'suite', run=1, seed=3),
            record('test_x.py::test_far[2]', tmp_path / 'suite', run=2, seed=4)]
    assert same_run(runs, case, (test_file, 'test_far[2]')) is runs[2]
    assert same_run(runs, dict(case, run=0), (test_file, 'test_far[2]')) is runs[1]
    assert same_run(runs, dict(case, run=3), (test_file, 'test_far[2]')) is None
    assert same_run(runs, case, (test_file, 'test_far[3]')) is None


def test_a_propertys_case_is_its_final_example_run_of_the_same_rank(tmp_path):
    """Two runs in the shrunk example: cases of ranks 0 and 1; the rerun's finals in order."""
    test_file = (tmp_path / 'test_p.py').resolve()
    test_file.write_text('')
    farm = [record('test_p.py::test_prop', tmp_path, run=run, prop=True, seed=run)
            for run in (41, 40)]
    farm.append(record('test_p.py::test_seeded', tmp_path, run=0))
    report = write_report(farm, tmp_path / 'farm', picture=False)['report.json']
    first, second = load_case(report, 0), load_case(report, 1)
    assert (first['run'], first['ordinal'], second['run'], second['ordinal']) == (40, 0, 41, 1)
    again = [record('test_p.py::test_prop', tmp_path, run=run, prop=run > 2, seed=run)
             for run in (0, 1, 2, 4, 3)]  # explored, then the final example's two runs
    where = (test_file, 'test_prop')
    assert same_run(again, first, where)['run'] == 3
    assert same_run(again, second, where)['run'] == 4
    assert same_run(again[:3], first, where) is None


def test_a_case_is_relative_to_its_own_runs_rootdir(tmp_path):
    """A worker's rootdir, not the main process's; the report's for a record without one."""
    farm = [record('suite/test_x.py::test_a', tmp_path / 'worker'),
            dict(record('test_x.py::test_b', tmp_path), rootdir=None)]
    report = write_report(farm, tmp_path / 'farm', rootdir=str(tmp_path / 'main'),
                          picture=False)['report.json']
    assert load_case(report, 0)['rootdir'] == str(tmp_path / 'worker')
    assert load_case(report, 1)['rootdir'] == str(tmp_path / 'main')
    data = json.loads(report.read_text())
    for case in data['cases']:
        del case['rootdir']  # a report written before cases kept theirs
    report.write_text(json.dumps(data))
    assert load_case(report, 0)['rootdir'] == str(tmp_path / 'main')


# A farm without physics: every run is the same outcome, as the report keeps it.
FAKE_RUNS = '''
import r2d2_sim.farm.run as run


def fake_run(scenario, controller, **keywords):
    return run.Outcome(scenario=scenario, passed=True, reason='', seconds=1.0,
                       time_to_goal_s=0.5, clearance_m=2.0, closest=None, closest_s=None,
                       contacts=(), tipped_s=None, trajectory=(), steps=240)


run.run_scenario = fake_run
'''
FAKE_FARM = '''
import pytest

from r2d2_sim.farm import Scenario


@pytest.mark.parametrize('seed', [1, 2])
def test_fake(r2d2_farm, seed):
    assert r2d2_farm.run(Scenario(seed=seed), None, seconds=1.0).passed
'''


def test_each_record_keeps_the_rootdir_its_node_id_is_relative_to(tmp_path):
    """--farm-dir ../shard1 under xdist: the workers' node ids and rootdir name the file."""
    suite = tmp_path / 'checkout' / 'suite'
    suite.mkdir(parents=True)
    (suite / 'conftest.py').write_text(FAKE_RUNS)
    (suite / 'test_fake.py').write_text(FAKE_FARM)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (str(REPO), os.environ.get('PYTHONPATH')) if p))
    farm = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                           '-p', 'r2d2_sim.farm.pytest_plugin', '-n', '1', '--farm-dir',
                           '../shard1', 'test_fake.py'], cwd=suite, env=env,
                          capture_output=True, text=True, timeout=300)
    assert farm.returncode == 0, farm.stdout[-2000:]
    cases = json.loads((suite.parent / 'shard1' / 'report.json').read_text())['cases']
    assert len(cases) == 2
    for case in cases:
        path = case['nodeid'].partition('::')[0]
        assert Path(case['rootdir'], path).resolve() == (suite / 'test_fake.py').resolve()


def test_a_report_without_its_outcome_is_one_line(tmp_path):
    """A case whose outcome is no outcome: exit 2 before anything runs."""
    data = {'cases': [{'nodeid': 't.py::x', 'run': 0, 'property': False, 'outcome': {}}]}
    (tmp_path / 'report.json').write_text(json.dumps(data))
    result = rerun(tmp_path / 'report.json', tmp_path)
    assert result.returncode == 2 and result.stderr.count('\n') == 1, result.stderr


def test_a_cut_short_last_line_is_left_out_and_another_bad_line_is_one_line(tmp_path, capsys):
    """A run killed while writing leaves half a line: resumable; a line bad before is not."""
    from r2d2_sim.farm.rerun import read_records
    outcomes = tmp_path / 'outcomes'
    outcomes.mkdir()
    good = json.dumps(record('t.py::test_a', tmp_path))
    (outcomes / 'a.jsonl').write_text(good + '\n' + good[:40] + '\n')
    assert read_records(tmp_path) == [json.loads(good)]
    assert 'a.jsonl: its last line is cut short; left out' in capsys.readouterr().err
    (outcomes / 'a.jsonl').write_text(good[:40] + '\n' + good + '\n')
    with pytest.raises(ReportError, match=r'a\.jsonl: line 1 is not a farm outcome$'):
        read_records(tmp_path)


def test_a_shard_that_held_no_seed_merges_into_the_report(tmp_path, capsys):
    """A runner's directory with its farm.json and no outcome adds nothing, and is no error."""
    full, empty = tmp_path / 'shard1', tmp_path / 'shard2'
    (full / 'outcomes').mkdir(parents=True)
    (full / 'outcomes' / 'a.jsonl').write_text(json.dumps(record('t.py::test_a', full)) + '\n')
    (empty / 'outcomes').mkdir(parents=True)
    (empty / 'farm.json').write_text(json.dumps({'farm': {'name': 'x'}}))
    assert main(['report', str(full), str(empty), '--out', str(tmp_path / 'merged')]) == 0
    cases = json.loads((tmp_path / 'merged' / 'report.json').read_text())['cases']
    assert [case['nodeid'] for case in cases] == ['t.py::test_a']
    assert main(['report', str(empty), '--out', str(tmp_path / 'none')]) == 2
    assert capsys.readouterr().err.strip().endswith(f'no farm outcomes in {empty}')
