"""
The conformance kit as a user runs it: ``python -m r2d2_sim.conformance`` and the pytest plugin.

Against ``sim_node`` in a process of its own (r2d2_sim passes every clause
whose features it declares; the others skip, and say which feature they
need), and against the toy simulator of ``test/toy_simulator.py`` from
another process (a clause it gets wrong fails the run: exit status 1, a
JUnit failure), a hostile one (huge or slow replies: the kit's lines and its
time stay bounded) and two of them on one domain (the kit refuses in one line).
"""

from pathlib import Path
import re
import subprocess
import sys
import xml.etree.ElementTree as ElementTree

from common import REPO
from helpers import next_domain_id
from r2d2_sim.client import ros_child_env
from r2d2_sim.conformance import BY_ID, CLAUSES
from r2d2_sim.conformance.discovery import FEATURES
from toy_simulator import ToySimulator

KIT = [sys.executable, '-m', 'r2d2_sim.conformance']
RUN_S = 300
# What the kit may spawn and load in r2d2_sim (the world is used once it serves LoadWorld).
ASSET, WORLD = 'cube.urdf', 'package://r2d2_sim/urdf/room.world.yaml'


def junit_cases(path: Path):
    """Return (the testsuite element, {clause id: (status, message)})."""
    suite = ElementTree.parse(path).getroot().find('testsuite')
    cases = {}
    for case in suite.findall('testcase'):
        clause_id = case.get('name').split()[0].split('[')[-1].rstrip(']')
        failure, skipped = case.find('failure'), case.find('skipped')
        if failure is not None:
            cases[clause_id] = ('FAIL', failure.get('message'))
        elif skipped is not None:
            cases[clause_id] = ('SKIP', skipped.get('message'))
        else:
            cases[clause_id] = ('PASS', '')
    return suite, cases


def declared_features(sim) -> set:
    """Return the names of the features ``sim`` declares, asked through the standard."""
    from simulation_interfaces.msg import SimulatorFeatures
    names = {getattr(SimulatorFeatures, n): n for n in FEATURES}
    return {names[value] for value in sim.standard.features()}


def undeclared(clause_id: str, declared: set) -> bool:
    """Return True when a clause needs a feature ``declared`` lacks (or is moot by them)."""
    clause = BY_ID[clause_id]
    missing = any(not set(f.split('|')) & declared for f in clause.features)
    return missing or bool(clause.unless and set(clause.unless) <= declared)


def test_sim_node_passes_every_clause_it_declares(r2d2_sim_process, tmp_path):
    """The kit from another process: exit 0, no failure, skips only for undeclared features."""
    sim = r2d2_sim_process(cmd_vel_timeout=0.0, world=WORLD)
    out = tmp_path / 'conformance.xml'
    result = subprocess.run(KIT + ['--domain', str(sim.domain_id), '--asset', ASSET,
                                   '--world', WORLD, '--junit', str(out)],
                            env=ros_child_env(sim.domain_id), cwd=REPO, capture_output=True,
                            text=True, timeout=RUN_S)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    assert result.stdout.strip().splitlines()[-1].startswith(f'{len(CLAUSES)} clauses: ')
    suite, cases = junit_cases(out)
    declared = set(next(p.get('value') for p in suite.iter('property')
                        if p.get('name') == 'features').split())
    assert declared == declared_features(sim) and len(cases) == len(CLAUSES)
    for clause_id, (status, message) in cases.items():
        if undeclared(clause_id, declared):
            assert status == 'SKIP', (clause_id, status, message)
        else:  # every clause whose features are declared ran and passed: no runtime skip
            assert status == 'PASS', (clause_id, status, message)
    assert sim.standard.state() == 1  # left PLAYING, as it was found
    assert sim.standard.entities() == ['ground_plane', 'r2d2', 'room']


# Of the eight clauses that time steps by /clock (STATE-14, STEP-06, STEP-07, ACTION-06,
# RESET-04, RESET-05, RESET-10, RESET-13), one of each verb: a step, the action, a reset.
# All eight take 17 s here, each check of a quiet clock waiting 0.25 s; the toy simulator's
# clock-every-fifth-step variant runs all eight (test_conformance_toy.py).
CLOCK_CLAUSES = ('STEP-06', 'ACTION-06', 'RESET-04')


def test_sim_node_publishing_the_clock_every_few_steps_passes_the_clock_clauses(
        r2d2_sim_process):
    """publish_rate 50 at 240 Hz: /clock every 4-5 steps; each clause timing steps passes."""
    sim = r2d2_sim_process(cmd_vel_timeout=0.0, world=WORLD, publish_rate=50.0)
    result = subprocess.run(KIT + ['--domain', str(sim.domain_id), '--asset', ASSET,
                                   '--only', ','.join(CLOCK_CLAUSES)],
                            env=ros_child_env(sim.domain_id), cwd=REPO, capture_output=True,
                            text=True, timeout=RUN_S)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    passed = re.findall(r'^([A-Z]+-\d\d) +PASS ', result.stdout, re.M)
    assert sorted(passed) == sorted(CLOCK_CLAUSES), result.stdout


TEST_FILE = '''\
from r2d2_sim.conformance.pytest_plugin import test_simulation_standard  # noqa: F401
'''


def test_the_pytest_plugin_runs_one_test_per_clause(r2d2_sim_process, tmp_path):
    """A simulator's CI: -p the plugin, one imported test: 131 tests, none failed."""
    sim = r2d2_sim_process(cmd_vel_timeout=0.0, world=WORLD)
    (tmp_path / 'test_standard.py').write_text(TEST_FILE)
    out = tmp_path / 'pytest.xml'
    result = subprocess.run(
        [sys.executable, '-m', 'pytest', '-p', 'r2d2_sim.conformance.pytest_plugin',
         '-p', 'no:cacheprovider', '-p', 'no:xdist', '-q', '-rs', '--rootdir', str(tmp_path),
         '--conformance-domain', str(sim.domain_id), '--conformance-asset', ASSET,
         '--conformance-world', WORLD, f'--junitxml={out}', str(tmp_path / 'test_standard.py')],
        env=ros_child_env(sim.domain_id), cwd=tmp_path, capture_output=True, text=True,
        timeout=RUN_S)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-2000:]
    suite, cases = junit_cases(out)
    assert suite.get('tests') == str(len(CLAUSES)) and suite.get('failures') == '0'
    assert sorted(cases) == sorted(c.id for c in CLAUSES)
    skipped = {i for i, (status, _) in cases.items() if status == 'SKIP'}
    declared = declared_features(sim)
    assert skipped == {c.id for c in CLAUSES if undeclared(c.id, declared)}
    assert all('not declared' in cases[i][1] or 'moot' in cases[i][1] for i in skipped)


def test_a_clause_the_simulator_gets_wrong_fails_the_run(tmp_path):
    """The toy answering OK to STOPPED when stopped: exit status 1 and a JUnit failure."""
    domain = next_domain_id()
    out = tmp_path / 'conformance.xml'
    with ToySimulator(domain, defect='STATE-08'):
        result = subprocess.run(KIT + ['--prefix', '/toy', '--asset', 'toy://box', '--only',
                                       'STATE', '--junit', str(out)],
                                env=ros_child_env(domain), cwd=REPO, capture_output=True,
                                text=True, timeout=RUN_S)
    assert result.returncode == 1, result.stdout[-3000:] + result.stderr[-2000:]
    assert re.search(r'^STATE-08 +FAIL ', result.stdout, re.M), result.stdout
    _, cases = junit_cases(out)
    assert cases['STATE-08'][0] == 'FAIL' and 'ALREADY_IN_TARGET_STATE' in cases['STATE-08'][1]
    assert {i for i, (s, _) in cases.items() if s == 'FAIL'} == {'STATE-08'}
    assert sorted(cases) == [c.id for c in CLAUSES if c.group == 'STATE']


def test_huge_replies_print_no_huge_line(tmp_path):
    """Megabytes in a spawn format, a name, a frame, error messages: every line stays short."""
    domain = next_domain_id()
    out = tmp_path / 'conformance.xml'
    with ToySimulator(domain, defect='HUGE'):
        result = subprocess.run(KIT + ['--prefix', '/toy', '--asset', 'toy://box', '--only',
                                       'FEAT-01,RESULT-05,ENTITY-01,ENTITY-03', '--junit',
                                       str(out)],
                                env=ros_child_env(domain), cwd=REPO, capture_output=True,
                                text=True, timeout=RUN_S)
    assert result.returncode == 1, result.stdout[-3000:] + result.stderr[-2000:]
    lines = (result.stdout + result.stderr).splitlines()
    assert max(len(line) for line in lines) <= 1000, [len(line) for line in lines]
    assert re.search(r'^ENTITY-01 +FAIL ', result.stdout, re.M), result.stdout[:3000]
    _, cases = junit_cases(out)
    assert max(len(message or '') for _, message in cases.values()) <= 1000


def test_a_slow_simulator_is_checked_within_the_total_time(tmp_path):
    """--total-timeout bounds the run: the clauses past it are not run, and say so."""
    domain = next_domain_id()
    with ToySimulator(domain, defect='SLOW'):
        result = subprocess.run(KIT + ['--prefix', '/toy', '--asset', 'toy://box', '--only',
                                       'STATE', '--timeout', '10', '--total-timeout', '6'],
                                env=ros_child_env(domain), cwd=REPO, capture_output=True,
                                text=True, timeout=RUN_S)
    assert result.returncode == 1, result.stdout[-3000:] + result.stderr[-2000:]
    assert 'time limit' in result.stdout.splitlines()[-2], result.stdout[-3000:]


def test_no_simulator_found_is_a_failure_even_when_feat_01_is_not_run():
    """Only STATE asked for, nothing answers: exit status 1 and one line, never a pass."""
    domain = next_domain_id()
    result = subprocess.run(KIT + ['--prefix', '/nobody', '--asset', 'toy://box', '--only',
                                   'STATE', '--timeout', '1'],
                            env=ros_child_env(domain), cwd=REPO, capture_output=True,
                            text=True, timeout=RUN_S)
    assert result.returncode == 1, result.stdout[-3000:] + result.stderr[-2000:]
    assert result.stderr.splitlines() == [
        "sim_conformance: error: nothing was checked: no service of type GetSimulatorFeatures "
        "under '/nobody' within 1 s (found: none of the standard's services)"]


def test_a_simulator_under_a_namespace_is_refused_in_one_line():
    """The default prefix takes no simulator below the root: one line asks for --prefix."""
    domain = next_domain_id()
    with ToySimulator(domain, prefix='/victim') as victim:
        result = subprocess.run(KIT + ['--only', 'STATE'], env=ros_child_env(domain), cwd=REPO,
                                capture_output=True, text=True, timeout=RUN_S)
        assert victim.changes == 0
    assert result.returncode == 2, result.stdout[-3000:] + result.stderr[-2000:]
    assert result.stderr.count('\n') == 1 and '--prefix /victim' in result.stderr, result.stderr
