"""
docs/conformance.md against the kit: the clause list, the matrix, the example client.

- The clause list is what the clause table renders to (as docs/parameters.md
  is the parameter table's), so the page cannot cite a sentence the kit no
  longer checks; the check fails for a changed clause.
- r2d2_sim's matrix on the page names every clause, in order, and no failure.
- The README's matrix by group (passed/clauses) is the page's matrix summed up.
- The warehouse client shown is ``test/children/warehouse_client.py``, byte for byte.
No ROS: the clause table is read without rclpy.
"""

from pathlib import Path
import re

from r2d2_sim.conformance.clauses import CLAUSES
from r2d2_sim.conformance.report import clause_block, render_clause_reference, update_page

REPO = Path(__file__).resolve().parents[2]
PAGE = REPO / 'docs' / 'conformance.md'
README = REPO / 'README.md'
CLIENT = REPO / 'test' / 'children' / 'warehouse_client.py'


def _page() -> str:
    return PAGE.read_text(encoding='utf-8')


def test_clause_list_is_the_clause_table_rendered():
    """The generated block of docs/conformance.md is render_clause_reference() of today's table."""
    page = _page()
    assert clause_block(page) == render_clause_reference(), (
        'docs/conformance.md is stale: python -m r2d2_sim.conformance.report docs/conformance.md')
    assert update_page(page) == page


def test_clause_list_check_fails_for_a_changed_clause():
    """The check above can fail: a clause with another title or quote renders another list."""
    for change in ({'title': 'something else'}, {'quote': 'another sentence entirely'}):
        changed = [c._replace(**change) if c.id == 'STATE-08' else c for c in CLAUSES]
        assert render_clause_reference(changed) != clause_block(_page())


def test_matrix_on_the_page_names_every_clause_without_a_failure():
    """r2d2_sim's matrix, pasted from a run, lists each clause once, in order, PASS or SKIP."""
    rows = re.findall(r'^\| ([A-Z]+-\d\d) \| (PASS|FAIL|SKIP) \|', _page(), re.M)
    assert [clause_id for clause_id, _ in rows] == [c.id for c in CLAUSES]
    assert {status for _, status in rows} <= {'PASS', 'SKIP'}
    passed = sum(status == 'PASS' for _, status in rows)
    assert f'{len(CLAUSES)} clauses: {passed} passed, 0 failed' in _page()


def test_readme_counts_are_the_page_matrix():
    """The README's clauses, passed, failed and skipped are what the page's rows give."""
    rows = re.findall(r'^\| ([A-Z]+)-\d\d \| (PASS|FAIL|SKIP) \|', _page(), re.M)
    counts = [sum(status == wanted for _, status in rows) for wanted in ('PASS', 'FAIL', 'SKIP')]
    shown = re.search(r'(\d+) clauses, (\d+) passed, (\d+) failed, (\d+)\s+skipped',
                      README.read_text(encoding='utf-8'))
    assert shown is not None, "the README no longer gives r2d2_sim's conformance counts"
    assert [int(n) for n in shown.groups()] == [len(rows), *counts]


def test_the_example_client_is_the_tested_file():
    """The warehouse client in the page is test/children/warehouse_client.py as it is."""
    blocks = re.findall(r'^```python\n(.*?)^```$', _page(), re.S | re.M)
    assert CLIENT.read_text(encoding='utf-8') in blocks
