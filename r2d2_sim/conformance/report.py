"""
What a run shows: the matrix, the summary line, JUnit XML; and the clause list of the docs.

No ROS here (the standard library only): the clause list in
``docs/conformance.md`` is rendered from the clause table, and a test fails
when the page is stale. To write it again after changing a clause::

    python -m r2d2_sim.conformance.report docs/conformance.md
"""

from collections import Counter
import re
import sys
from typing import Dict, List, Optional, Sequence
import xml.etree.ElementTree as ElementTree

from r2d2_sim.conformance.clause import Clause, FAIL, feature_text, Outcome, PASS, SKIP
from r2d2_sim.conformance.clauses import CLAUSES, GROUPS

__all__ = ['matrix', 'summary', 'exit_status', 'write_junit', 'markdown_matrix',
           'render_clause_reference', 'update_page', 'CLAUSES_BEGIN', 'CLAUSES_END', 'main']

CLAUSES_BEGIN = ('<!-- The clause list below is generated from the clause table by\n'
                 '     python -m r2d2_sim.conformance.report docs/conformance.md\n'
                 '     Edit the clauses, not this list: a test fails when the two differ. -->')
CLAUSES_END = '<!-- End of the generated clause list. -->'
ID_WIDTH = 14


def matrix(outcomes: Sequence[Outcome]) -> str:
    """Return a line per clause (id, PASS/FAIL/SKIP, title), its reason (or note) below."""
    lines = []
    for outcome in outcomes:
        clause = outcome.clause
        lines.append(f'{clause.id:<{ID_WIDTH}} {outcome.status}  {clause.title}')
        if outcome.reason:
            lines.append(f'{"":<{ID_WIDTH}}       {outcome.reason}')
    return '\n'.join(lines)


def counts(outcomes: Sequence[Outcome]) -> Dict[str, int]:
    """Return how many clauses passed, failed and were skipped."""
    seen = Counter(o.status for o in outcomes)
    return {PASS: seen[PASS], FAIL: seen[FAIL], SKIP: seen[SKIP]}


def summary(outcomes: Sequence[Outcome], where: str = '') -> str:
    """Return the summary line: ``131 clauses: 90 passed, 0 failed, 41 skipped (where)``."""
    n = counts(outcomes)
    text = (f'{len(outcomes)} clauses: {n[PASS]} passed, {n[FAIL]} failed, '
            f'{n[SKIP]} skipped')
    return f'{text} ({where})' if where else text


def exit_status(outcomes: Sequence[Outcome]) -> int:
    """Return 0 when no clause failed, else 1."""
    return 1 if any(o.status == FAIL for o in outcomes) else 0


def write_junit(outcomes: Sequence[Outcome], path: str,
                properties: Optional[Dict[str, str]] = None) -> None:
    """Write the outcomes as JUnit XML (one testcase per clause, its group as the class)."""
    n = counts(outcomes)
    suite = ElementTree.Element('testsuite', {
        'name': 'simulation_interfaces conformance', 'tests': str(len(outcomes)),
        'failures': str(n[FAIL]), 'errors': '0', 'skipped': str(n[SKIP]),
        'time': f'{sum(o.seconds for o in outcomes):.3f}'})
    if properties:
        props = ElementTree.SubElement(suite, 'properties')
        for name, value in properties.items():
            ElementTree.SubElement(props, 'property', {'name': name, 'value': str(value)})
    for outcome in outcomes:
        clause = outcome.clause
        case = ElementTree.SubElement(suite, 'testcase', {
            'classname': f'simulation_interfaces.{clause.group}',
            'name': f'{clause.id} {clause.title}', 'time': f'{outcome.seconds:.3f}'})
        if outcome.status == FAIL:
            failure = ElementTree.SubElement(case, 'failure', {'message': outcome.reason})
            failure.text = f'{clause.source}: {clause.quote}\n{outcome.reason}'
        elif outcome.status == SKIP:
            ElementTree.SubElement(case, 'skipped', {'message': outcome.reason})
        elif outcome.reason:  # a pass with a note
            ElementTree.SubElement(case, 'system-out').text = outcome.reason
    root = ElementTree.Element('testsuites')
    root.append(suite)
    tree = ElementTree.ElementTree(root)
    ElementTree.indent(tree)
    tree.write(path, encoding='utf-8', xml_declaration=True)


def _cell(text: str) -> str:
    return text.replace('|', '\\|').replace('\n', ' ')


def markdown_matrix(outcomes: Sequence[Outcome]) -> str:
    """Return the outcomes as a Markdown table: clause, result, title, reason."""
    rows = ['| clause | result | what | why |', '|---|---|---|---|']
    rows += [f'| {o.clause.id} | {o.status} | {_cell(o.clause.title)} | {_cell(o.reason)} |'
             for o in outcomes]
    return '\n'.join(rows) + '\n'


def render_clause_reference(clauses: Sequence[Clause] = CLAUSES) -> str:
    """Return the clause list of ``docs/conformance.md``: a table per group, markers included."""
    per_group = Counter(c.group for c in clauses)
    parts = [CLAUSES_BEGIN, '',
             f'{len(clauses)} clauses: ' + ', '.join(f'{g} {per_group[g]}' for g in GROUPS
                                                     if per_group[g]) + '.', '']
    for group in GROUPS:
        members = [c for c in clauses if c.group == group]
        if not members:
            continue
        parts += [f'### {group}', '', '| id | checks | needs | the standard says |',
                  '|---|---|---|---|']
        for c in members:
            needs = [feature_text(c.features)] if c.features else []
            if c.advisory:
                needs.append('advisory: a note, never a failure')
            if c.unless:
                needs.append(f'moot when {" and ".join(c.unless)} are declared')
            if c.services:
                needs.append(f'{", ".join(c.services)} served')
            parts.append(f'| {c.id} | {_cell(c.title)} | {_cell("; ".join(needs) or "-")} | '
                         f'`{c.source}`: "{_cell(c.quote)}" |')
        parts.append('')
    parts.append(CLAUSES_END)
    return '\n'.join(parts) + '\n'


_BLOCK = re.compile(re.escape(CLAUSES_BEGIN) + r'.*?' + re.escape(CLAUSES_END) + r'\n', re.S)


def clause_block(page: str) -> Optional[str]:
    """Return the generated clause list in a page (markers included), or None."""
    found = _BLOCK.search(page)
    return found.group(0) if found else None


def update_page(page: str, clauses: Sequence[Clause] = CLAUSES) -> str:
    """Return ``page`` with its clause list rendered again from ``clauses``."""
    if clause_block(page) is None:
        raise ValueError('the page has no generated clause list (its markers are missing)')
    return _BLOCK.sub(lambda _: render_clause_reference(clauses), page)


def main(argv: Optional[List[str]] = None) -> int:
    """Render the clause list again in the Markdown page given (docs/conformance.md)."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print('usage: python -m r2d2_sim.conformance.report PAGE.md', file=sys.stderr)
        return 2
    with open(argv[0], encoding='utf-8') as handle:
        page = handle.read()
    try:
        text = update_page(page)
    except ValueError as exc:
        print(f'r2d2_sim.conformance.report: error: {argv[0]}: {exc}', file=sys.stderr)
        return 2
    with open(argv[0], 'w', encoding='utf-8') as handle:
        handle.write(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
