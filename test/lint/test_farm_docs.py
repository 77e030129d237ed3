"""
docs/farm.md against the farm's example and the report it shows.

- The test files docs/farm.md shows are ``test/examples/farm/``, byte for
  byte and in order; the README's farm snippet is a piece of one of them.
- The report docs/farm.md shows is the one ``bench/farm.py`` kept
  (``bench/farm_report/report.md``): its lines are that report's lines, and its
  date is the report's.
"""

from pathlib import Path
import re

from common import EXAMPLES

REPO = Path(__file__).resolve().parents[2]
FARM_PAGE = REPO / 'docs' / 'farm.md'
FARM_EXAMPLES = EXAMPLES / 'farm'
BENCH_REPORT = REPO / 'bench' / 'farm_report' / 'report.md'


def _blocks(text, language):
    return re.findall(rf'^```{language}\n(.*?)^```$', text, re.S | re.M)


def test_the_farm_page_shows_the_example_files():
    """Each python block of docs/farm.md with a test in it is an example file, in order."""
    page = FARM_PAGE.read_text(encoding='utf-8')
    shown = [b for b in _blocks(page, 'python') if 'def test_' in b]
    files = [p.read_text(encoding='utf-8') for p in sorted(FARM_EXAMPLES.glob('test_*.py'))]
    assert shown == files


def test_the_readme_farm_snippet_is_a_piece_of_the_example():
    """The README's farm code is cut from the example file as it is."""
    readme = (REPO / 'README.md').read_text(encoding='utf-8')
    snippets = [b for b in _blocks(readme, 'python') if 'r2d2_farm' in b]
    assert snippets
    files = [p.read_text(encoding='utf-8') for p in FARM_EXAMPLES.glob('test_*.py')]
    for snippet in snippets:
        assert any(snippet in text for text in files), snippet


def test_the_report_shown_is_the_benchmarks_report():
    """Every line of the report docs/farm.md shows is in bench/farm_report/report.md."""
    page = FARM_PAGE.read_text(encoding='utf-8')
    (shown,) = [b for b in _blocks(page, 'markdown') if '# Farm report' in b]
    kept = BENCH_REPORT.read_text(encoding='utf-8').splitlines()
    missing = [line for line in shown.splitlines() if line.strip() and line not in kept]
    assert not missing, missing
    date = kept[2][:10]  # the report's first sentence starts with its date and time
    assert re.match(r'\d{4}-\d{2}-\d{2}$', date) and f'bench/farm.py`, {date}' in page
