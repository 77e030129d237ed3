"""
A farm's report from outcome records made by hand: its case numbers and its distributions.

The figures the README and docs/farm.md quote (median, p90) are worked out
here by hand: ten times to goal of 1..10 s have the median 5.5 s (halfway
between the 5th and 6th) and the p90 9.1 s (a tenth of the way from the 9th
to the 10th: numpy's default, linear, definition).
"""

import json

import pytest

from r2d2_sim.farm.report import case_key, percentile, write_report
from r2d2_sim.farm.run import Outcome
from r2d2_sim.farm.scenario import Scenario


def record(nodeid, run=0, time_to_goal_s=None, clearance_m=1.0, seed=0):
    """Make what the farm writes of a passed run: one JSON line, as data."""
    outcome = Outcome(scenario=Scenario(seed=seed), passed=True, reason='', seconds=20.0,
                      time_to_goal_s=time_to_goal_s, clearance_m=clearance_m, closest=None,
                      closest_s=None, contacts=(), tipped_s=None, trajectory=(), steps=240)
    return {'nodeid': nodeid, 'run': run, 'worker': '', 'property': False,
            'outcome': outcome.to_dict()}


def test_cases_are_numbered_with_numbers_compared_as_numbers(tmp_path):
    """test[2] before test[10]; a test's runs in their order; whatever order workers wrote."""
    nodeids = [('t.py::test[10]', 0), ('t.py::test[2]', 1), ('t.py::test[1]', 0),
               ('t.py::test[2]', 0), ('t.py::test[9]', 0), ('s.py::test[100]', 0)]
    records = [record(nodeid, run, seed=number) for number, (nodeid, run) in enumerate(nodeids)]
    written = write_report(records, tmp_path, picture=False)
    cases = json.loads(written['report.json'].read_text())['cases']
    assert [(c['nodeid'], c['run']) for c in cases] == [
        ('s.py::test[100]', 0), ('t.py::test[1]', 0), ('t.py::test[2]', 0),
        ('t.py::test[2]', 1), ('t.py::test[9]', 0), ('t.py::test[10]', 0)]
    assert [c['case'] for c in cases] == list(range(6))
    assert sorted(records, key=case_key) == [records[5], records[2], records[3], records[1],
                                             records[4], records[0]]


def test_the_distributions_are_the_ones_worked_out_by_hand(tmp_path):
    """1..10 s to the goal: median 5.5, p90 9.1; clearances 0.1..1.0 and 2.0 m: 0.6, 1.0."""
    times = [7.0, 2.0, 10.0, 1.0, 5.0, 3.0, 9.0, 4.0, 8.0, 6.0]
    records = [record(f't.py::test[{i}]', time_to_goal_s=t, clearance_m=t / 10.0)
               for i, t in enumerate(times)]
    records.append(record('t.py::test_never', clearance_m=2.0))  # no time to goal
    written = write_report(records, tmp_path, picture=False)
    summary = json.loads(written['report.json'].read_text())['summary']
    assert summary['goal_reached'] == 10
    assert summary['time_to_goal_s'] == pytest.approx(
        {'runs': 10, 'min': 1.0, 'median': 5.5, 'p90': 9.1, 'max': 10.0})
    assert summary['clearance_m'] == pytest.approx(
        {'runs': 11, 'min': 0.1, 'median': 0.6, 'p90': 1.0, 'max': 2.0})
    markdown = written['report.md'].read_text()
    assert '| time to goal (s) | 1.000 | 5.500 | 9.100 | 10.000 | 10 |' in markdown
    assert '| clearance (m) | 0.100 | 0.600 | 1.000 | 2.000 | 11 |' in markdown


@pytest.mark.parametrize('values, q, expected', [
    ([0.4, 0.1, 0.5, 0.3, 0.2], 50.0, 0.3), ([0.4, 0.1, 0.5, 0.3, 0.2], 90.0, 0.46),
    ([3.0, 1.0], 50.0, 2.0), ([3.0, 1.0], 90.0, 2.8), ([2.0], 90.0, 2.0),
    ([1.0, 2.0, 3.0, 4.0], 0.0, 1.0), ([1.0, 2.0, 3.0, 4.0], 100.0, 4.0)])
def test_percentiles_by_hand(values, q, expected):
    """Linear between the two nearest of the sorted values, at (n - 1) * q / 100."""
    assert percentile(values, q) == pytest.approx(expected)


def test_no_values_have_no_percentile():
    """An empty list (no run reached its goal) is NaN, never an error."""
    assert percentile([], 50.0) != percentile([], 50.0)
