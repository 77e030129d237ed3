"""
``end_with_parent``, sim_node's tie to the process that started it, on input it must refuse.

The watch itself (a simulator ending with its killed test process) is proved
against the real executable in ``test/system/test_harness_death.py``; here,
in this process, what it does with a variable that names no parent.
"""

import os
import threading

import pytest

from r2d2_sim.client import end_with_parent, PARENT_PID_ENV
from r2d2_sim.errors import StartupError


def test_without_the_variable_nothing_is_watched(monkeypatch):
    """A sim_node run by hand (no R2D2_SIM_PARENT_PID) starts no watch."""
    monkeypatch.delenv(PARENT_PID_ENV, raising=False)
    before = threading.active_count()
    end_with_parent()
    assert threading.active_count() == before


@pytest.mark.parametrize('value, fragment', [
    ('a pid', 'must be a process id'),
    ('ours', 'has ended'),           # alive, but not an ancestor: the parent it named is gone
    ('4194304', 'has ended'),        # above Linux's largest pid: no such process
])
def test_a_parent_that_is_no_ancestor_is_refused_in_one_line(monkeypatch, value, fragment):
    """A malformed id, or a process that did not start us (it has ended), stops the start."""
    monkeypatch.setenv(PARENT_PID_ENV, str(os.getpid()) if value == 'ours' else value)
    before = threading.active_count()
    with pytest.raises(StartupError) as refused:
        end_with_parent()
    assert fragment in str(refused.value) and '\n' not in str(refused.value)
    assert PARENT_PID_ENV not in os.environ  # not handed down to our own children
    assert threading.active_count() == before
