"""
The package's version, stated three times, is one: package.xml, setup.py and CHANGELOG.rst.

``CHANGELOG.rst`` is kept as ROS packages keep it (the format of
``catkin_generate_changelog``, which bloom reads for a release): a title, then one
section a release, newest first, ``X.Y.Z (YYYY-MM-DD)`` underlined with dashes, its
items bullets. Its newest section is the version package.xml and setup.py state. It
is read as catkin_pkg reads it too (catkin_pkg comes with colcon). Imports no ROS.
"""

import ast
from pathlib import Path
import re
import xml.etree.ElementTree as ElementTree

from catkin_pkg.changelog import Changelog, populate_changelog_from_rst
import pytest

from common import REPO

# catkin_pkg 1.1 calls docutils' deprecated Node.traverse().
pytestmark = pytest.mark.filterwarnings('ignore:nodes.Node.traverse:DeprecationWarning')
ROOT = Path(REPO)
PACKAGE = 'r2d2_sim'
SECTION = re.compile(r'^(\d+)\.(\d+)\.(\d+) \((\d{4}-\d{2}-\d{2})\)\n(-*)$', re.M)


def package_xml_version(text):
    """Return package.xml's <version>."""
    return ElementTree.fromstring(text).findtext('version', '').strip()


def setup_py_version(text):
    """Return the ``version=`` that setup.py gives setup(), read without running it."""
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Call) and getattr(node.func, 'id', '') == 'setup':
            for keyword in node.keywords:
                if keyword.arg == 'version' and isinstance(keyword.value, ast.Constant):
                    return keyword.value.value
    return ''


def changelog_problems(text):
    """Return what keeps ``text`` from being a catkin changelog of r2d2_sim, newest first."""
    problems = []
    title = f'Changelog for package {PACKAGE}'
    if text.splitlines()[:3] != ['^' * len(title), title, '^' * len(title)]:
        problems.append(f'the title is not "{title}" between two lines of ^')
    sections = SECTION.findall(text)
    if not sections:
        problems.append('no section "X.Y.Z (YYYY-MM-DD)"')
    for major, minor, patch, date, underline in sections:
        if len(underline) != len(f'{major}.{minor}.{patch} ({date})'):
            problems.append(f'{major}.{minor}.{patch}: the underline is not as long as the title')
    releases = [((int(a), int(b), int(c)), date) for a, b, c, date, _ in sections]
    if releases != sorted(releases, reverse=True) or len(set(releases)) != len(releases):
        problems.append('the sections are not newest first, each version once')
    changelog = Changelog(PACKAGE)
    populate_changelog_from_rst(changelog, text)
    read = {version: content for version, _, content in changelog.foreach_version()}
    if sorted(read) != sorted('.'.join(section[:3]) for section in sections):
        problems.append(f'catkin_pkg reads other releases: {sorted(read)}')
    problems.extend(f'{version}: no items' for version, content in read.items() if not content)
    return problems


def newest_version(text):
    """Return the version of the changelog's first section ('' without one)."""
    found = SECTION.search(text)
    return '.'.join(found.groups()[:3]) if found else ''


def version_problems(package_xml, setup_py, changelog):
    """Return a line for each statement of the version that differs from package.xml's."""
    version = package_xml_version(package_xml)
    problems = [] if re.fullmatch(r'\d+\.\d+\.\d+', version) else [
        f'package.xml: {version!r} is not X.Y.Z']
    for where, stated in (('setup.py', setup_py_version(setup_py)),
                          ('CHANGELOG.rst', newest_version(changelog))):
        if stated != version:
            problems.append(f'{where} says {stated!r}, package.xml {version!r}')
    return problems


def _sections_reversed(text):
    """Return the changelog with its sections in the opposite order."""
    starts = [found.start() for found in SECTION.finditer(text)]
    parts = [text[a:b].rstrip('\n') for a, b in zip(starts, starts[1:] + [len(text)])]
    return text[:starts[0]] + '\n\n'.join(reversed(parts)) + '\n'


def _newest_emptied(text):
    """Return the changelog with its newest section's items left out."""
    first, second = list(SECTION.finditer(text))[:2]
    return text[:first.end()] + '\n\n' + text[second.start():]


def _read(name):
    return (ROOT / name).read_text(encoding='utf-8')


def test_package_xml_setup_py_and_the_changelog_state_one_version():
    """The newest section of CHANGELOG.rst is the version of package.xml and setup.py."""
    assert version_problems(_read('package.xml'), _read('setup.py'),
                            _read('CHANGELOG.rst')) == []


def test_the_changelog_is_kept_as_ros_packages_keep_it():
    """Title, sections newest first with their dates, bullets: catkin_generate_changelog's form."""
    assert changelog_problems(_read('CHANGELOG.rst')) == []


def test_a_version_stated_differently_is_found():
    """setup.py or the changelog behind package.xml, or a version that is not X.Y.Z."""
    package_xml, setup_py, changelog = (_read('package.xml'), _read('setup.py'),
                                        _read('CHANGELOG.rst'))
    version = package_xml_version(package_xml)
    older = '0.0.1'
    assert version_problems(package_xml, setup_py.replace(f"'{version}'", f"'{older}'"),
                            changelog) == [f'setup.py says {older!r}, package.xml {version!r}']
    assert version_problems(package_xml, setup_py, changelog.replace(
        f'{version} (', f'{older} (', 1)) == [
            f'CHANGELOG.rst says {older!r}, package.xml {version!r}']
    assert version_problems(package_xml.replace(f'>{version}<', '>next<'), setup_py,
                            changelog) == [
        "package.xml: 'next' is not X.Y.Z", f"setup.py says {version!r}, package.xml 'next'",
        f"CHANGELOG.rst says {version!r}, package.xml 'next'"]


@pytest.mark.parametrize('change, problem', [
    (lambda text: text.replace('Changelog for package', 'Changes of', 1),
     'the title is not "Changelog for package r2d2_sim" between two lines of ^'),
    (lambda text: text.replace('\n------------------\n', '\n-------\n', 1),
     'the underline is not as long as the title'),
    (lambda text: _sections_reversed(text),
     'the sections are not newest first, each version once'),
    (lambda text: _newest_emptied(text), 'no items'),
])
def test_a_changelog_out_of_form_is_found(change, problem):
    """A changed title, a short underline, the sections in the wrong order, a release emptied."""
    changed = change(_read('CHANGELOG.rst'))
    assert any(problem in line for line in changelog_problems(changed)), (
        changelog_problems(changed), changed[:600])
