"""
The documentation against the code, the example tests and itself.

- ``docs/parameters.md`` is what the parameter table renders to, so the
  reference cannot drift from the table (as ``sim_node --help`` cannot).
- The test files shown in ``docs/testing.md`` are ``test/examples/``, byte for
  byte and in order, and its other python snippets run; the README's own
  example is one of those files.
- Every relative link of ``README.md`` and ``docs/`` reaches a file (and a
  heading, for an anchor), every page of ``docs/`` is reachable from the
  README, and the README stays short.
- ``docs/`` builds with Sphinx and MyST, as rosdoc2 builds it for docs.ros.org,
  with warnings as errors and the testing API documented from its docstrings.
"""

from pathlib import Path
import re
import subprocess
import sys
import time

import pytest

from common import EXAMPLE_FILES
from r2d2_sim.sim.settings.reference import render_parameter_reference
from r2d2_sim.sim.settings.table import PARAMETERS

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / 'docs'
README = REPO / 'README.md'
EXAMPLES = REPO / 'test' / 'examples'
# In the order docs/testing.md shows them.
PLUGIN = 'r2d2_sim.pytest_plugin'
README_MAX_LINES = 300


def _python_blocks(text):
    return re.findall(r'^```python\n(.*?)^```$', text, re.S | re.M)


def _examples():
    return [(EXAMPLES / name).read_text(encoding='utf-8') for name in EXAMPLE_FILES]


# -- the parameter reference ------------------------------------------------------


def test_parameter_reference_is_the_table_rendered():
    """docs/parameters.md is render_parameter_reference() of today's table."""
    page = (DOCS / 'parameters.md').read_text(encoding='utf-8')
    assert page == render_parameter_reference(), (
        'docs/parameters.md is stale: '
        'python -m r2d2_sim.sim.settings.reference docs/parameters.md')


@pytest.mark.parametrize('change', [
    {'default': 120.0}, {'description': 'Steps per simulated second.'}, {'per_robot': True}])
def test_parameter_reference_check_fails_for_a_changed_table(change):
    """The check above can fail: one parameter changed renders to another page."""
    changed = [spec._replace(**change) if spec.name == 'physics_rate' else spec
               for spec in PARAMETERS]
    page = (DOCS / 'parameters.md').read_text(encoding='utf-8')
    assert render_parameter_reference(changed) != page


# -- the examples ---------------------------------------------------------------------


def test_testing_page_test_files_are_the_example_files():
    """Each test-file block of docs/testing.md is one example file, byte for byte, in order."""
    assert sorted(p.name for p in EXAMPLES.glob('test_*.py')) == sorted(EXAMPLE_FILES)
    text = (DOCS / 'testing.md').read_text(encoding='utf-8')
    blocks = [b for b in _python_blocks(text) if PLUGIN in b]
    assert blocks == _examples(), 'docs/testing.md and test/examples/ differ'


def test_readme_example_is_an_example_file():
    """The README's test file is one of test/examples/, byte for byte."""
    blocks = [b for b in _python_blocks(README.read_text(encoding='utf-8')) if PLUGIN in b]
    assert blocks, 'README.md shows no test file'
    examples = _examples()
    for block in blocks:
        assert block in examples, block


def test_testing_page_other_snippets_run(capsys):
    """The python blocks of docs/testing.md that are not test files run as written."""
    text = (DOCS / 'testing.md').read_text(encoding='utf-8')
    snippets = [b for b in _python_blocks(text) if PLUGIN not in b]
    assert snippets
    for snippet in snippets:
        exec(compile(snippet, 'docs/testing.md', 'exec'), {})
    printed = capsys.readouterr().out.split()
    assert float(printed[-1]) > 0.5, printed


# -- links ----------------------------------------------------------------------------

_FENCE = re.compile(r'^```.*?^```$', re.S | re.M)
_COMMENT = re.compile(r'<!--.*?-->', re.S)
_CODE_SPAN = re.compile(r'`[^`\n]*`')
_LINK = re.compile(r'\[[^\]]*\]\(([^)\s]+)\)')
_HEADING = re.compile(r'^#{1,6} +(.+?) *$', re.M)


def _prose(text):
    """Return ``text`` without code blocks, comments and code spans (links stay)."""
    return _CODE_SPAN.sub('code', _COMMENT.sub('', _FENCE.sub('', text)))


def _slug(heading):
    """Return GitHub's anchor for a heading (MyST makes the same ones)."""
    return re.sub(r'[^\w\- ]', '', heading.strip().lower()).replace(' ', '-')


def _anchors(page):
    return {_slug(h) for h in _HEADING.findall(_FENCE.sub('', page.read_text(encoding='utf-8')))}


def _links(page):
    """Return the relative links of a Markdown page: (target path or None, anchor or None)."""
    links = []
    for target in _LINK.findall(_prose(page.read_text(encoding='utf-8'))):
        if re.match(r'[a-z][a-z0-9+.-]*:', target):  # https:, mailto:
            continue
        path, _, anchor = target.partition('#')
        links.append((page.parent / path if path else page, anchor or None))
    return links


def _pages():
    return [README] + sorted(DOCS.rglob('*.md'))


@pytest.mark.parametrize('page', _pages(), ids=lambda p: str(p.relative_to(REPO)))
def test_relative_links_resolve(page):
    """Every relative link reaches a file in the repository, and its anchor a heading there."""
    broken = []
    for path, anchor in _links(page):
        resolved = path.resolve()
        if not resolved.exists() or REPO not in resolved.parents:
            broken.append(f'{path.relative_to(page.parent) if path != page else ""}: no such file')
        elif anchor is not None and (resolved.suffix != '.md' or anchor not in _anchors(resolved)):
            broken.append(f'{resolved.relative_to(REPO)}#{anchor}: no such heading')
    assert not broken, broken


def test_every_docs_page_is_reachable_from_the_readme():
    """Following Markdown links from README.md reaches every page of docs/."""
    reached, todo = {README}, [README]
    while todo:
        for path, _ in _links(todo.pop()):
            path = path.resolve()
            if path.suffix == '.md' and path.is_file() and path not in reached:
                reached.add(path)
                todo.append(path)
    unreached = [str(p.relative_to(REPO)) for p in DOCS.rglob('*.md') if p not in reached]
    assert not unreached, unreached


def test_readme_is_short():
    """The README stays a front page: details go to docs/."""
    lines = README.read_text(encoding='utf-8').splitlines()
    assert len(lines) <= README_MAX_LINES, len(lines)


# -- the Sphinx build -------------------------------------------------------------------


def test_docs_build_with_sphinx_and_myst_without_warnings(tmp_path):
    """docs/ builds as rosdoc2 builds it (Sphinx + MyST), warnings as errors, API included."""
    html = tmp_path / 'html'
    started = time.monotonic()
    result = subprocess.run(
        [sys.executable, '-m', 'sphinx', '-W', '--keep-going', '-q', '-b', 'html',
         '-d', str(tmp_path / 'doctrees'), str(DOCS), str(html)],
        cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout[-4000:] + result.stderr[-4000:]
    print(f'Sphinx build of docs/: {time.monotonic() - started:.1f} s')
    api = (html / 'api' / 'testing.html').read_text(encoding='utf-8')
    for name in ('r2d2_sim.testing.SimHarness', 'r2d2_sim.testing.SimProcess',
                 'r2d2_sim.pytest_plugin.r2d2_sim'):
        assert f'id="{name}"' in api, name
    assert not (DOCS / '_build').exists()
