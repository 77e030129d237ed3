"""
The conformance kit's own parts: the clause table, discovery by type, choosing clauses, reports.

No simulator here: the table is checked as data (ids, features, the files it
cites), discovery against graphs written by hand, the reports against
outcomes made up for the purpose, and the command line's usage errors.
"""

import importlib
from pathlib import Path
import xml.etree.ElementTree as ElementTree

import pytest

from common import REPO, setup_py_console_scripts
from r2d2_sim.conformance import BY_ID, CLAUSES, FAIL, GROUPS, KitError, Outcome, PASS, select
from r2d2_sim.conformance.cli import main
from r2d2_sim.conformance.discovery import (
    FEATURE_INTERFACES, FEATURES, find_interfaces, SERVICES, simulator_levels, snake_case,
    SUB_FEATURES)
from r2d2_sim.conformance.report import (
    exit_status, markdown_matrix, matrix, SKIP, summary, write_junit)

DEFINITIONS = Path(REPO) / 'tools' / 'interfaces' / 'simulation_interfaces'


# -- the clause table -------------------------------------------------------------------

def test_at_least_sixty_clauses_with_unique_ids_in_group_order():
    """At least 60 clauses, ids unique, numbered 01, 02... in each group, groups in a row."""
    assert len(CLAUSES) >= 60
    assert len(BY_ID) == len(CLAUSES)
    for group in GROUPS:
        ids = [c.id for c in CLAUSES if c.group == group]
        assert ids == [f'{group}-{n:02d}' for n in range(1, len(ids) + 1)], ids
    order = [c.group for c in CLAUSES]
    assert order == sorted(order, key=GROUPS.index)


def test_every_clause_cites_a_definition_file_and_names_real_features():
    """Each clause quotes a sentence of a .msg/.srv/.action the standard has; features exist."""
    files = {p.name for p in DEFINITIONS.rglob('*') if p.suffix in ('.msg', '.srv', '.action')}
    assert len(files) == 38
    for c in CLAUSES:
        assert c.source in files, (c.id, c.source)
        assert len(c.quote) > 20 and c.title and c.check.__doc__, c.id
        for feature in c.features + c.unless:
            assert set(feature.split('|')) <= set(FEATURES), (c.id, feature)
        assert set(c.services) <= set(SERVICES), c.id


def test_the_feature_tables_cover_every_feature_and_interface():
    """Each feature stands for an interface or is part of one; all services but two have one."""
    assert len(FEATURES) == 32 and len(SERVICES) == 22
    covered = set(FEATURE_INTERFACES) | set(SUB_FEATURES)
    rest = set(FEATURES) - covered
    assert rest == {'ENTITY_TAGS', 'ENTITY_BOUNDS_BOX', 'ENTITY_BOUNDS_CONVEX',
                    'ENTITY_CATEGORIES'}  # parts of GetEntities' filters, which has no feature
    owned = {k for kinds in FEATURE_INTERFACES.values() for alt in kinds for k in alt.split('|')}
    assert set(SERVICES) - owned == {'GetSimulatorFeatures', 'GetEntities'}


def test_state_12_quotes_incorrect_transition_with_what_limits_it():
    """The sentence is not cut before its limit: 103 is for pausing a stopped simulation."""
    assert BY_ID['STATE-12'].quote.endswith(
        'INCORRECT_TRANSITION = 103 # Incorrect transition (pausing when in stopped state).')


# -- discovery by type ------------------------------------------------------------------

def _graph(*pairs):
    return [(name, [f'simulation_interfaces/{kind}']) for name, kind in pairs]


def test_discovery_finds_services_and_the_action_by_type_at_the_prefix():
    """Any name will do; only the prefix's own level counts; the action is its send_goal."""
    graph = _graph(('/gz/step', 'srv/StepSimulation'), ('/gz/Spawn', 'srv/SpawnEntity'),
                   ('/gz/steps/_action/send_goal', 'action/SimulateSteps_SendGoal'),
                   ('/gz/steps/_action/get_result', 'action/SimulateSteps_GetResult'),
                   ('/other/spawn_entity', 'srv/SpawnEntity'),
                   ('/gz/deeper/step_simulation', 'srv/StepSimulation'))
    graph.append(('/gz/describe_parameters', ['rcl_interfaces/srv/DescribeParameters']))
    found, several = find_interfaces(graph, '/gz/')
    assert found == {'StepSimulation': '/gz/step', 'SpawnEntity': '/gz/Spawn',
                     'SimulateSteps': '/gz/steps'}
    assert several == {}
    # The root's own level holds none of them: a simulator in a namespace is not taken.
    assert find_interfaces(graph, '/') == ({}, {})
    assert find_interfaces(graph, '/gz/deeper') == (
        {'StepSimulation': '/gz/deeper/step_simulation'}, {})


def test_discovery_names_several_of_one_type_at_one_level():
    """Two names of one type at the prefix's level are two simulators: both named."""
    graph = _graph(('/a/b/spawn', 'srv/SpawnEntity'), ('/spawn_entity', 'srv/SpawnEntity'),
                   ('/SpawnEntity', 'srv/SpawnEntity'), ('/x/delete', 'srv/DeleteEntity'))
    found, several = find_interfaces(graph, '')
    assert found == {'SpawnEntity': '/spawn_entity'}
    assert several == {'SpawnEntity': ['/SpawnEntity', '/spawn_entity']}
    assert snake_case('GetSimulatorFeatures') == 'get_simulator_features'


def test_simulators_are_found_at_every_level():
    """Each namespace that serves GetSimulatorFeatures is a simulator the kit can name."""
    graph = _graph(('/get_simulator_features', 'srv/GetSimulatorFeatures'),
                   ('/victim/GetSimulatorFeatures', 'srv/GetSimulatorFeatures'),
                   ('/a/b/features', 'srv/GetSimulatorFeatures'),
                   ('/x/delete', 'srv/DeleteEntity'))
    assert simulator_levels(graph) == ['/', '/a/b', '/victim']


# -- choosing clauses -----------------------------------------------------------------------

def test_select_takes_ids_groups_and_patterns():
    """--only and --skip take ids, groups and shell patterns; an unknown name is an error."""
    assert [c.id for c in select(['STATE-03'])] == ['STATE-03']
    assert [c.id for c in select(['step'], ['STEP-07'])] == [f'STEP-0{n}' for n in range(1, 7)]
    assert {c.group for c in select(['SPAWN-1*'])} == {'SPAWN'}
    assert len(select()) == len(CLAUSES)
    with pytest.raises(KitError, match='names no clause'):
        select(['NOPE'])


# -- reports --------------------------------------------------------------------------------

OUTCOMES = [Outcome(BY_ID['STATE-03'], PASS, '', 0.01),
            Outcome(BY_ID['STEP-04'], FAIL, 'StepSimulation while PLAYING: got OK (1)', 0.02),
            Outcome(BY_ID['WORLD-01'], SKIP, 'needs AVAILABLE_WORLDS (not declared)', 0.0)]


def test_matrix_summary_and_exit_status():
    """One line a clause, its reason below; the counts; 1 when a clause failed, else 0."""
    lines = matrix(OUTCOMES).splitlines()
    assert lines[0].startswith('STATE-03') and 'PASS' in lines[0]
    assert 'FAIL' in lines[1] and lines[2].strip() == OUTCOMES[1].reason
    assert summary(OUTCOMES, 'here') == '3 clauses: 1 passed, 1 failed, 1 skipped (here)'
    assert exit_status(OUTCOMES) == 1 and exit_status([OUTCOMES[0], OUTCOMES[2]]) == 0
    assert markdown_matrix(OUTCOMES).count('\n') == 2 + len(OUTCOMES)


def test_junit_xml_has_a_testcase_per_clause(tmp_path):
    """CI reads failures (with the cited sentence) and skips (with the reason)."""
    path = tmp_path / 'out.xml'
    write_junit(OUTCOMES, str(path), {'prefix': '/'})
    suite = ElementTree.parse(path).getroot().find('testsuite')
    assert (suite.get('tests'), suite.get('failures'), suite.get('skipped')) == ('3', '1', '1')
    cases = suite.findall('testcase')
    assert [c.get('classname') for c in cases] == [
        'simulation_interfaces.STATE', 'simulation_interfaces.STEP', 'simulation_interfaces.WORLD']
    failure = cases[1].find('failure')
    assert failure.get('message') == OUTCOMES[1].reason and 'StepSimulation.srv' in failure.text
    assert cases[2].find('skipped').get('message') == OUTCOMES[2].reason


# -- the command line -----------------------------------------------------------------------

def test_list_prints_the_clauses(capsys):
    """--list prints the chosen clauses with what they need, and starts no ROS node."""
    assert main(['--list', '--only', 'RESET']) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(select(['RESET'])) and lines[0].startswith('RESET-01')


@pytest.mark.parametrize('argv, says', [
    (['--only', 'NOPE'], "'NOPE' names no clause"),
    (['--prefix', '/bad prefix!'], "--prefix '/bad prefix!'"),
    (['--clock-topic', 'bad topic!'], "--clock-topic 'bad topic!': topic name must not"),
])
def test_usage_errors_are_one_line_and_status_2(argv, says, capsys):
    """A bad clause name, prefix or clock topic: one line on stderr, status 2, no traceback."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and says in err and err.startswith('sim_conformance: error:')


def test_bad_numbers_are_argparse_errors(capsys):
    """--timeout and --free-space refuse what is not a finite number, as argparse does."""
    for argv in (['--timeout', 'nan'], ['--free-space', '1,2'], ['--domain', '999']):
        with pytest.raises(SystemExit) as exited:
            main(argv)
        assert exited.value.code == 2
    assert 'usage: sim_conformance' in capsys.readouterr().err


def test_console_scripts_resolve():
    """Every console script of setup.py names a module:function that imports (sim_conformance)."""
    scripts = setup_py_console_scripts()
    assert any(s.startswith('sim_conformance = ') for s in scripts)
    for script in scripts:
        module, _, function = script.split(' = ')[1].partition(':')
        assert callable(getattr(importlib.import_module(module), function)), script
