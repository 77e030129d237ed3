"""
``help(r2d2_sim.testing)`` opens with the handful of names a new user needs, each one real.

A new user found ``help(r2d2_sim.testing)`` thousands of lines long, the names
that matter lost in it: the module docstring starts with "Names you need",
within its first lines, and every name that section gives exists (an importable
class or function, a fixture of the plugin, a verb of the harnesses), as do the
pages it points to.
"""

import inspect
import os
import pydoc
import re

from _pytest.fixtures import getfixturemarker

from common import REPO
from r2d2_sim import pytest_plugin, testing

SECTION = re.compile(r'Names you need.*?\n\n(.*?)\n\n', re.S)
FIXTURES = ('r2d2_sim', 'r2d2_sim_parameters', 'r2d2_sim_factory', 'r2d2_sim_process')


def names_you_need():
    """Return the docstring's "Names you need" list."""
    return SECTION.search(testing.__doc__).group(1)


def test_help_opens_with_the_names_you_need():
    text = pydoc.render_doc(testing, renderer=pydoc.plaintext)
    assert 'Names you need' in '\n'.join(text.splitlines()[:10])
    assert len(names_you_need().splitlines()) <= 30


def test_every_name_it_gives_exists():
    section = names_you_need()
    for name in re.findall(r':(?:class|func):`(\w+)`', section):
        assert name in testing.__all__, name
    for name in FIXTURES:
        assert name in section and getfixturemarker(getattr(pytest_plugin, name)), name
    verbs = {name for cls in (testing.SimHarness, testing.SimProcess)
             for name, _ in inspect.getmembers(cls)} | set(vars(testing.RefusedError('A', 'b')))
    for verb in re.findall(r'``(\w+)(?:\(|``)', section):
        assert verb in verbs or verb in FIXTURES + ('pytest_plugins', 'sim_node'), verb
    for page in re.findall(r'``(docs/[\w/.-]+\.md)``', testing.__doc__):
        assert os.path.isfile(os.path.join(REPO, page)), page
