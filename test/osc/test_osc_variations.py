"""
A parameter file's documents as variations: one task each, on the farm's executors.

One verdict per document, in document order, the same on a rerun in another order;
one JUnit file and the farm's report. The crossing example with four speeds of its
second robot: a few simulated seconds each.
"""

import json
import subprocess
import sys
import xml.etree.ElementTree as ElementTree

import pytest

from common import OSC_EXAMPLES, osc_env, REPO, scenario_execution
from r2d2_sim.osc.variations import (
    executor_map, read_documents, run_document, run_variations, tasks_of)

SPEEDS = [0.25, 0.6, 0.5, 0.27]


def write_speeds(tmp_path):
    """Write the crossing's parameter file: one document per speed of r2."""
    path = tmp_path / 'speeds.yaml'
    path.write_text('---\n'.join(f'crossing:\n  r2_speed: {speed}\n' for speed in SPEEDS))
    return path


def test_each_document_is_one_task():
    """A file of two documents is two tasks, numbered, each with its document."""
    tasks = tasks_of(str(OSC_EXAMPLES / 'crossing.osc'),
                     str(OSC_EXAMPLES / 'crossing_speeds.yaml'))
    assert [(t.number, t.document) for t in tasks] == [
        (0, {'crossing': {'r2_speed': 0.25}}), (1, {'crossing': {'r2_speed': 0.6}})]
    assert read_documents(str(OSC_EXAMPLES / 'crossing_speeds.yaml')) == \
        [t.document for t in tasks]


def test_a_pool_gives_one_verdict_per_document_the_same_on_a_rerun(tmp_path):
    """Two processes, then the documents one by one in reverse: the same verdicts, measures."""
    speeds = write_speeds(tmp_path)
    verdicts = run_variations(str(OSC_EXAMPLES / 'crossing.osc'), str(speeds),
                              str(tmp_path / 'out'), jobs=2)
    assert [v.name for v in verdicts] == [f'crossing-{i}' for i in range(len(SPEEDS))]
    assert [v.passed for v in verdicts] == [True, False, False, True]
    assert verdicts[1].reason.startswith('r2d2 came within 0.3 m of r2 (0.')
    again = [run_document(task) for task in reversed(tasks_of(
        str(OSC_EXAMPLES / 'crossing.osc'), str(speeds)))]
    assert all(a.same_as(b) for a, b in zip(verdicts, reversed(again)))
    cases = ElementTree.parse(tmp_path / 'out' / 'test.xml').getroot().findall('testcase')
    assert [(c.get('name'), c.find('failure') is None) for c in cases] == \
        [(v.name, v.passed) for v in verdicts]
    report = (tmp_path / 'out' / 'farm' / 'report.md').read_text()
    assert '| passed | 2 of 4 (50.0 %) |' in report


def test_a_document_whose_process_dies_is_its_failure_and_the_others_still_run():
    """A worker killed mid-document: that document crashed (not rerun), the rest unharmed."""
    tasks = tasks_of(str(OSC_EXAMPLES / 'crossing.osc'),
                     str(OSC_EXAMPLES / 'crossing_speeds.yaml'))
    tasks[0] = tasks[0]._replace(simulation='dying_simulation:DyingSimulation')
    verdicts = sorted(executor_map('local', workers=2)(run_document, tasks),
                      key=lambda v: v.number)
    assert [(v.name, v.passed) for v in verdicts] == [('crossing-0', False),
                                                      ('crossing-1', False)]
    assert verdicts[0].reason.startswith('crashed: its worker process ')
    assert verdicts[0].reason.endswith('died, killed by SIGKILL')
    assert verdicts[1].reason.startswith('r2d2 came within 0.3 m of r2'), verdicts[1].reason
    assert verdicts[1].same_as(run_document(tasks[1]))


def test_the_command_line_says_each_verdict(tmp_path):
    """The command line: a line per variation, the count, exit status 1 for a failure."""
    result = subprocess.run(
        [sys.executable, '-m', 'r2d2_sim.osc', str(OSC_EXAMPLES / 'crossing.osc'),
         '--parameters', str(OSC_EXAMPLES / 'crossing_speeds.yaml'), '-o', 'out', '--jobs', '2'],
        cwd=tmp_path, env=osc_env(tmp_path / 'shim'), capture_output=True, text=True,
        timeout=300)
    lines = result.stdout.splitlines()
    assert lines[0] == 'crossing-0: passed', result.stdout + result.stderr
    assert lines[1].startswith('crossing-1: FAILED: r2d2 came within 0.3 m of r2')
    assert lines[2] == '1 passed, 1 failed; out/test.xml' and result.returncode == 1
    # The report's rerun is the documents again, not the farm's rerun of a pytest test,
    # which says so in one line if asked.
    report = tmp_path / 'out' / 'farm' / 'report.json'
    failed = json.loads(report.read_text())['cases'][1]
    assert failed['rerun'].startswith('python -m r2d2_sim.osc ') and \
        failed['rerun'].endswith('crossing_speeds.yaml --jobs 1 (document 1)')
    asked = subprocess.run([sys.executable, '-m', 'r2d2_sim.farm', 'rerun', str(report),
                            '--case', '1'], cwd=tmp_path, env=osc_env(tmp_path / 'shim'),
                           capture_output=True, text=True, timeout=120)
    assert asked.returncode == 2 and asked.stderr.splitlines() == [
        'r2d2_sim.farm: error: case 1 is the OpenSCENARIO variation crossing-1, not a pytest '
        f'test: run it again with {failed["rerun"]}']


def test_a_cluster_that_does_not_answer_is_one_line(tmp_path):
    """--address of a Dask scheduler nobody runs: exit status 2, one line naming it."""
    result = subprocess.run(
        [sys.executable, '-m', 'r2d2_sim.osc', str(OSC_EXAMPLES / 'crossing.osc'),
         '--parameters', str(OSC_EXAMPLES / 'crossing_speeds.yaml'),
         '--address', 'tcp://127.0.0.1:9'], cwd=tmp_path, env=osc_env(tmp_path / 'shim'),
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stdout + result.stderr
    assert result.stderr.splitlines() == [
        'r2d2_sim.osc: error: cannot reach the Dask scheduler at tcp://127.0.0.1:9 '
        '(127.0.0.1:9: Connection refused); is it running, and is the address right?']


def test_a_scenario_that_does_not_parse_is_one_line_before_anything_runs(tmp_path):
    """Not each document failing alike: exit status 2 and the parser's error, once."""
    (tmp_path / 'garbage.osc').write_text('garbage { here\n')
    result = subprocess.run(
        [sys.executable, '-m', 'r2d2_sim.osc', 'garbage.osc', '--parameters',
         str(OSC_EXAMPLES / 'crossing_speeds.yaml')], cwd=tmp_path,
        env=osc_env(tmp_path / 'shim'), capture_output=True, text=True, timeout=120)
    lines = result.stderr.splitlines()
    assert result.returncode == 2 and len(lines) == 1, result.stderr
    assert lines[0].startswith("r2d2_sim.osc: error: garbage.osc: parsing failed: line 1:0 "
                               "mismatched input 'garbage'")
    assert not (tmp_path / 'osc_results').exists()


def test_an_output_directory_that_is_a_file_is_one_line(tmp_path):
    """-o naming a file: exit status 2, one line, before anything runs."""
    (tmp_path / 'fleet.yaml').write_text('mine\n')
    result = subprocess.run(
        [sys.executable, '-m', 'r2d2_sim.osc', str(OSC_EXAMPLES / 'crossing.osc'), '-o',
         'fleet.yaml'], cwd=tmp_path, env=osc_env(tmp_path / 'shim'), capture_output=True,
        text=True, timeout=120)
    assert result.returncode == 2 and result.stderr.splitlines() == [
        'r2d2_sim.osc: error: -o fleet.yaml is a file, not a directory'], result.stderr
    assert (tmp_path / 'fleet.yaml').read_text() == 'mine\n'


def test_a_parameter_file_that_cannot_be_read_is_one_line(tmp_path):
    """A document that is not {scenario: {parameter: value}}: exit status 2, one line."""
    bad = tmp_path / 'bad.yaml'
    bad.write_text('crossing:\n  r2_speed: 0.3\n---\n- 1\n- 2\n')
    result = subprocess.run(
        [sys.executable, '-m', 'r2d2_sim.osc', str(OSC_EXAMPLES / 'crossing.osc'),
         '--parameters', str(bad)], cwd=tmp_path, env=osc_env(tmp_path / 'shim'),
        capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.splitlines() == [
        f'r2d2_sim.osc: error: parameter file {bad}: document 1 is not '
        '{scenario name: {parameter: value}}']


def test_simulator_parameters_need_no_install(tmp_path):
    """Called first in a fresh process of a source checkout (no shim): osc.r2d2 is found."""
    code = ('from r2d2_sim.osc.variations import simulator_parameters\n'
            f'print(simulator_parameters({str(OSC_EXAMPLES / "crossing.osc")!r})["publish_rate"])')
    result = subprocess.run([sys.executable, '-c', code], cwd=tmp_path, capture_output=True,
                            text=True, timeout=120,
                            env=dict(osc_env(tmp_path / 'shim'), PYTHONPATH=REPO))
    assert result.stdout == '20.0\n', result.stdout + result.stderr


TWO_SCENARIOS = ('import osc.helpers\nimport osc.r2d2\n\n'
                 'scenario a:\n    do serial:\n        wait elapsed(0.2s)\n'
                 'scenario b:\n    timeout(1s)\n    do serial:\n'
                 '        wait_until_in_region(x: 5m, y: 0m, radius: 0.1m)\n')


@pytest.mark.parametrize('documents', [None, ['b: {}\n'], ['a: {}\n', 'b: {}\n']])
def test_each_scenario_is_a_case_named_as_scenario_execution_names_it(tmp_path, documents):
    """Two scenarios (a passes, b times out), with no, one or two documents: its own cases."""
    scenario = tmp_path / 'two.osc'
    scenario.write_text(TWO_SCENARIOS)
    args = ['--simulation', 'r2d2_sim.osc:R2D2Simulation', scenario]
    parameters = None
    if documents is not None:
        parameters = tmp_path / 'documents.yaml'
        parameters.write_text('---\n'.join(documents))
        args = ['--scenario-parameter-file', parameters, *args]
    _, output, theirs = scenario_execution(args, osc_env(tmp_path / 'shim'), tmp_path)
    verdicts = run_variations(str(scenario), parameters and str(parameters),
                              str(tmp_path / 'ours'), jobs=1, report=False)
    assert {v.name: v.passed for v in verdicts} == {
        name: failure is None for name, failure in theirs.items()}, output[-3000:]
    suffixes = ['-0', '-1'] if documents and len(documents) > 1 else ['']
    assert [v.name for v in verdicts] == [f'{s}{n}' for n in suffixes for s in 'ab']
    assert [v.reason for v in verdicts if not v.passed] == ['timed out after 1 s'] * len(suffixes)
    cases = ElementTree.parse(tmp_path / 'ours' / 'test.xml').getroot().findall('testcase')
    assert [c.get('name') for c in cases] == [v.name for v in verdicts]


def test_a_scenario_left_empty_in_a_document_keeps_its_defaults(tmp_path):
    """`a:` with no value (None), as scenario_execution runs it: no overrides, not refused."""
    from r2d2_sim.osc.variations import DocumentsJob
    scenario = tmp_path / 'two.osc'
    scenario.write_text(TWO_SCENARIOS)
    parameters = tmp_path / 'documents.yaml'
    parameters.write_text('a:\n---\na:\nb:\n  {}\n')
    assert read_documents(str(parameters)) == [{'a': None}, {'a': None, 'b': {}}]
    verdicts = run_variations(str(scenario), str(parameters), str(tmp_path / 'ours'), jobs=1,
                              report=False)
    assert [(v.name, v.passed) for v in verdicts] == [
        ('a-0', True), ('b-0', False), ('a-1', True), ('b-1', False)]
    tasks = tasks_of(str(scenario), str(parameters))
    assert [item.seed for item in DocumentsJob(tuple(tasks)).items()] == [0, 0, 0, 0]
