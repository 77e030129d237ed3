"""
The scenario farm as users run it: pytest in a subprocess, xdist workers, shards, reruns.

- docs/farm.md's example farm (test/examples/farm/), a few variations, in two
  pytest-split shards at once: each shard's report covers its own cases, and
  ``python -m r2d2_sim.farm report`` makes one of both;
- a farm with failures run twice under ``-n 2``, the second time in the
  reverse order: the same verdicts and byte-identical failure recordings; a
  failure rerun from the report by ``python -m r2d2_sim.farm rerun`` gives the
  same outcome and the same file, which ``replay`` plays;
- a Hypothesis property over a stopper that stops too late: it fails, its
  shrunk scenario (smaller than the first failing one) is in the failure's
  notes and the report with its recording, and replays from its JSON;
- a farm whose directory and reruns' recordings lie beside the checkout (CI
  artifacts: ``--farm-dir ../shard1``), each case rerun from the test's folder.
"""

import hashlib
import json
import os
from pathlib import Path
import re
import subprocess
import sys
import textwrap

from helpers import REPO

from common import EXAMPLES
from r2d2_sim.farm.scenario import Scenario
from r2d2_sim.testing import lease_domain, ros_child_env

FARM_EXAMPLE = EXAMPLES / 'farm' / 'test_stopper_farm.py'
PLUGIN = ['-p', 'r2d2_sim.farm.pytest_plugin', '-p', 'no:cacheprovider']

# A stopper that stops too late (0.3 m: R2D2's legs stand out further), in a small
# space of 0.3 m boxes ahead of a robot at the origin driving to (2.5, 0).
LATE_STOPPER = '''
from r2d2_sim.farm import ScenarioSpace
from stopper_example import GoalStopper, PARAMETERS

SPACE = ScenarioSpace(obstacles=(0, 3), area=(0.9, -0.6, 1.5, 0.6), box_size=(0.3, 0.3),
                      box_yaw=(0.0, 0.0), start_area=(0.0, 0.0, 0.0, 0.0), start_yaw=(0.0, 0.0),
                      goal_area=(2.5, 0.0, 2.5, 0.0), keep_out=0.5)


def late_stopper(harness, scenario):
    harness.add_node(GoalStopper(scenario.goal_point, stop_m=0.3, context=harness.context))
'''

LATE_FARM = '''
import os

import pytest

from r2d2_sim.farm import safe
from late_stopper import late_stopper, PARAMETERS, SPACE

SEEDS = list(range(8))
if os.environ.get('REVERSED'):
    SEEDS.reverse()


@pytest.mark.parametrize('seed', SEEDS)
def test_late(r2d2_farm, seed):
    outcome = r2d2_farm.run(SPACE.draw(seed), late_stopper, seconds=3.0, verdict=safe,
                            parameters=PARAMETERS)
    assert outcome.passed, outcome
'''

LATE_PROPERTY = '''
from hypothesis import given

from r2d2_sim.farm import farm_settings, safe, scenarios
from late_stopper import late_stopper, PARAMETERS, SPACE


@farm_settings(max_examples=10)
@given(scenario=scenarios(SPACE))
def test_it_never_touches_a_box(r2d2_farm, scenario):
    outcome = r2d2_farm.run(scenario, late_stopper, seconds=3.0, verdict=safe,
                            parameters=PARAMETERS)
    assert outcome.passed, outcome
'''


def write_project(folder: Path) -> None:
    """Write the example (as a module, not a test) and the late stopper's tests."""
    (folder / 'stopper_example.py').write_text(FARM_EXAMPLE.read_text(encoding='utf-8'))
    (folder / 'late_stopper.py').write_text(LATE_STOPPER)
    (folder / 'test_late_farm.py').write_text(LATE_FARM)
    (folder / 'test_late_property.py').write_text(LATE_PROPERTY)


def environment(**more) -> dict:
    env = ros_child_env()
    env.pop('ROS_DOMAIN_ID', None)  # every harness leases a free domain
    env['PYTHONPATH'] = os.pathsep.join(p for p in (REPO, env.get('PYTHONPATH')) if p)
    env.update(more)
    return env


def pytest_run(folder: Path, *args, timeout=600, **env) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'pytest', '-q', *PLUGIN, *args], cwd=folder,
                          env=environment(**env), capture_output=True, text=True,
                          timeout=timeout)


def report(farm_dir: Path) -> dict:
    return json.loads((farm_dir / 'report.json').read_text(encoding='utf-8'))


def sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def test_the_example_farm_in_two_shards_reports_each_shards_cases(tmp_path):
    """pytest-split shards at once, each with its farm directory: reports that add up."""
    (tmp_path / FARM_EXAMPLE.name).write_text(FARM_EXAMPLE.read_text(encoding='utf-8'))
    shards = [subprocess.Popen(
        [sys.executable, '-m', 'pytest', '-q', *PLUGIN, '--splits', '2', '--group', str(group),
         '--farm-dir', str(tmp_path / f'farm{group}'), FARM_EXAMPLE.name], cwd=tmp_path,
        env=environment(VARIATIONS='3', EXAMPLES='1'), stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True) for group in (1, 2)]
    nodeids = []
    for group, shard in enumerate(shards, start=1):
        out, _ = shard.communicate(timeout=600)
        assert shard.returncode == 0, out[-3000:]
        farm = tmp_path / f'farm{group}'
        assert str(farm / 'report.md') in out
        data = report(farm)
        assert data['summary']['runs'] == data['summary']['passed'] == len(data['cases'])
        nodeids.append({case['nodeid'] for case in data['cases']})
        assert (farm / 'trajectories.png').read_bytes()[:4] == b'\x89PNG'
        assert '# Farm report' in (farm / 'report.md').read_text(encoding='utf-8')
    seeded = {f'{FARM_EXAMPLE.name}::test_the_stopper_never_touches_anything[{seed}]'
              for seed in range(3)}
    assert not nodeids[0] & nodeids[1] and nodeids[0] | nodeids[1] == seeded
    merged = subprocess.run(
        [sys.executable, '-m', 'r2d2_sim.farm', 'report', str(tmp_path / 'farm1'),
         str(tmp_path / 'farm2'), '--out', str(tmp_path / 'all')], env=environment(),
        capture_output=True, text=True, timeout=120)
    assert merged.returncode == 0, merged.stderr
    assert [c['nodeid'] for c in report(tmp_path / 'all')['cases']] == sorted(seeded)


def test_a_farm_rerun_in_another_order_gives_the_same_verdicts_and_recordings(tmp_path):
    """-n 2 twice, reversed the second time; then a failure rerun from the report, replayed."""
    write_project(tmp_path)
    first = pytest_run(tmp_path, '-n', '2', '--farm-dir', str(tmp_path / 'a'),
                       'test_late_farm.py')
    second = pytest_run(tmp_path, '-n', '2', '--farm-dir', str(tmp_path / 'b'),
                        'test_late_farm.py', REVERSED='1')
    runs = [report(tmp_path / 'a'), report(tmp_path / 'b')]
    for result, data in zip((first, second), runs):
        failed = data['summary']['failed']
        assert 0 < failed < 8, result.stdout[-3000:]
        assert f'{failed} failed' in result.stdout
    verdicts = [[(c['nodeid'], c['passed'], c['reason']) for c in data['cases']] for data in runs]
    assert verdicts[0] == verdicts[1]
    hashes = [[sha256(c['recording']) for c in data['cases'] if not c['passed']]
              for data in runs]
    assert hashes[0] == hashes[1]
    assert all(c['recording'] is None for data in runs for c in data['cases'] if c['passed'])
    # Each worker ran its cases in another order the second time.
    sequences = [_executed(tmp_path / farm) for farm in ('a', 'b')]
    assert sequences[0] != sequences[1]

    case = next(c for c in runs[0]['cases'] if not c['passed'])
    rerun = subprocess.run(
        [sys.executable, '-m', 'r2d2_sim.farm', 'rerun', str(tmp_path / 'a' / 'report.json'),
         '--case', str(case['case']), '--record', str(tmp_path / 'rerun')], cwd=tmp_path,
        env=environment(), capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stdout[-2000:] + rerun.stderr[-2000:]
    assert 'the same outcome as in the report (failed: touched box_' in rerun.stdout
    printed = re.findall(r'(/\S+?(?:report\.json|report\.md|trajectories\.png))', rerun.stdout)
    assert printed and all(Path(p).is_file() for p in printed), printed  # not a scratch dir's
    recorded = list((tmp_path / 'rerun').glob('*.mcap'))
    assert len(recorded) == 1 and sha256(recorded[0]) == sha256(case['recording'])

    with lease_domain() as lease:
        played = subprocess.run([sys.executable, '-m', 'r2d2_sim.apps.replay',
                                 str(recorded[0]), '--rate', '20'],
                                env=ros_child_env(lease.domain_id), capture_output=True,
                                text=True, timeout=120)
    assert played.returncode == 0, played.stderr
    assert 'done, ' in played.stdout


def _executed(farm_dir: Path) -> list:
    """Return each worker's node ids in the order it ran them."""
    sequences = []
    for path in sorted((farm_dir / 'outcomes').glob('*.jsonl')):
        lines = path.read_text(encoding='utf-8').splitlines()
        sequences.append([json.loads(line)['nodeid'] for line in lines])
    return sorted(sequences)


def test_a_failing_property_is_shrunk_reported_recorded_and_replayed(tmp_path):
    """The late stopper fails; the shrunk case is smaller, noted, recorded, and reruns alike."""
    write_project(tmp_path)
    farm = tmp_path / 'farm'
    result = pytest_run(tmp_path, '--farm-dir', str(farm), 'test_late_property.py')
    assert result.returncode == 1, result.stdout[-3000:]
    out = result.stdout
    assert 'r2d2_farm: the shrunk scenario (seed ' in out, out[-3000:]
    assert 'r2d2_farm: the first failing scenario had ' in out
    (case,) = report(farm)['cases']
    assert case['property'] and not case['passed'] and case['reason'].startswith('touched box_')
    shrunk = Scenario.from_dict(case['outcome']['scenario'])
    first = Scenario.from_dict(case['first_failure'])
    assert shrunk.to_json() in out
    assert _size(shrunk) < _size(first), (shrunk, first)
    assert Path(case['recording']).is_file() and case['recording'] in out
    assert 'Hypothesis' in (farm / 'report.md').read_text(encoding='utf-8')

    rerun = subprocess.run(
        [sys.executable, '-m', 'r2d2_sim.farm', 'rerun', str(farm / 'report.json'), '--case',
         '0'], cwd=tmp_path, env=environment(), capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stdout[-2000:] + rerun.stderr[-2000:]
    assert 'the same outcome as in the report' in rerun.stdout
    (recorded,) = (farm / 'rerun-0').glob('*.mcap')
    assert sha256(recorded) == sha256(case['recording'])


# Two runs in each test: the first reaches its goal (it stands in it), the second cannot.
TWO_RUNS = '''
import pytest

from r2d2_sim.farm import Scenario
from r2d2_sim.model.regions import circle_region

QUIET = {'scan_rate': 0.0, 'imu_rate': 0.0, 'publish_tf': False, 'publish_rate': 20.0}


def stand(harness, scenario):
    pass


@pytest.mark.parametrize('seed', [1, 2])
def test_two_runs(r2d2_farm, seed):
    here = r2d2_farm.run(Scenario(goal=circle_region(0.0, 0.0, 0.5), seed=seed), stand,
                         seconds=0.5, parameters=QUIET)
    far = r2d2_farm.run(Scenario(goal=circle_region(9.0, 0.0, 0.2), seed=seed), stand,
                        seconds=0.3, parameters=QUIET)
    assert here.passed and far.passed, far
'''


def test_a_farm_beside_the_checkout_reruns_each_case_from_the_tests_folder(tmp_path):
    """--farm-dir ../shard1 (made by the farm) and --record ../../artifacts: each case again."""
    suite = tmp_path / 'ci' / 'checkout' / 'suite'
    suite.mkdir(parents=True)
    (suite / 'test_two_runs.py').write_text(TWO_RUNS)
    # Two separate arguments, as users write them: pytest takes '../shard1' for a path
    # when it chooses its rootdir, and xdist's workers find it made by then.
    farm = pytest_run(suite, '-n', '2', '--farm-dir', '../shard1', 'test_two_runs.py')
    shard = tmp_path / 'ci' / 'checkout' / 'shard1'
    cases = report(shard)['cases']
    assert [(c['run'], c['passed']) for c in cases] == [(0, True), (1, False)] * 2, \
        farm.stdout[-3000:]
    for case in cases:
        record = tmp_path / 'ci' / 'artifacts' / f'rerun-{case["case"]}'
        rerun = subprocess.run(
            [sys.executable, '-m', 'r2d2_sim.farm', 'rerun', '../shard1/report.json',
             '--case', str(case['case']), '--record', f'../../artifacts/{record.name}'],
            cwd=suite, env=environment(), capture_output=True, text=True, timeout=300)
        assert rerun.returncode == 0, rerun.stdout[-2000:] + rerun.stderr[-2000:]
        verdict = 'passed' if case['passed'] else 'failed: goal not reached in 0.3 s'
        assert f'the same outcome as in the report ({verdict})' in rerun.stdout
        assert f'the test: {suite / "test_two_runs.py"}::' in rerun.stdout
        assert len(list(record.glob('*.mcap'))) == 2  # both runs of the test, recorded


def _size(scenario: Scenario) -> tuple:
    """Fewer boxes first, then smaller numbers: how Hypothesis orders its shrinking."""
    numbers = [abs(v) for b in scenario.obstacles for v in (b.x, b.y, b.yaw)]
    return len(scenario.obstacles), sum(numbers) + scenario.seed


def test_the_plugin_imports_nothing_heavy_and_a_bad_rerun_is_one_line(tmp_path):
    """Loaded in every pytest run of an install: no rclpy, PyBullet, Hypothesis, matplotlib."""
    script = textwrap.dedent('''
        import sys
        import r2d2_sim.farm.pytest_plugin
        print([m for m in ('rclpy', 'pybullet', 'hypothesis', 'matplotlib') if m in sys.modules])
    ''')
    loaded = subprocess.run([sys.executable, '-c', script], env=environment(), cwd=REPO,
                            capture_output=True, text=True, timeout=60)
    assert loaded.stdout.strip() == '[]', loaded.stderr
    (tmp_path / 'report.json').write_text('{"cases": []}')
    for args, words in ((['rerun', str(tmp_path / 'report.json'), '--case', '0'],
                         'has cases 0..-1, not 0'),
                        (['rerun', str(tmp_path / 'missing.json'), '--case', '0'],
                         'not a farm report')):
        bad = subprocess.run([sys.executable, '-m', 'r2d2_sim.farm', *args], env=environment(),
                             capture_output=True, text=True, timeout=60)
        assert bad.returncode == 2
        assert bad.stderr.count('\n') == 1 and words in bad.stderr, bad.stderr
