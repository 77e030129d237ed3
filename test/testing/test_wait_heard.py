"""
SimProcess waits until the simulator's writers match its readers, not only the reverse.

A DDS writer learns of a new reader on its own, a moment after the reader
learned of the writer; what it publishes in between never reaches the reader
(a first step's ``/tf`` was lost so, once in a CI run). ``_wait_heard`` polls
``~/get_readers`` until each topic counts at least the harness's own
readers. The simulator's side is stood in for here, so each answer is
chosen: the real reply is test/ros/test_control.py's.
"""

from types import SimpleNamespace

import pytest

from r2d2_sim.testing import HarnessError, SimProcess


def waiting_process(answers, topics=('/tf', '/tf', '/odom', '/c/odom'), timeout_s=5.0):
    """Return a SimProcess whose readers() replies ``answers`` in turn (the last for good)."""
    process = SimProcess.__new__(SimProcess)
    asked = []

    def readers():
        asked.append(1)
        return answers[min(len(asked), len(answers)) - 1]
    node = SimpleNamespace(subscriptions=[SimpleNamespace(topic_name=t) for t in topics])
    process.probe = SimpleNamespace(node=node, spin_until=lambda condition, timeout_s: False)
    process.readers = readers
    process.timeout_s = timeout_s
    return process, asked


def test_it_asks_until_every_writer_counts_our_readers():
    """Two readers on /tf: one matched is not enough; topics it does not publish do not count."""
    process, asked = waiting_process([{'/tf': 0, '/odom': 1}, {'/tf': 1, '/odom': 1},
                                      {'/tf': 2, '/odom': 0}, {'/tf': 2, '/odom': 1}])
    process._wait_heard()
    assert len(asked) == 4


def test_it_says_which_topics_were_never_matched():
    """A writer that never matches: HarnessError naming the topic, after the deadline."""
    process, asked = waiting_process([{'/tf': 2, '/odom': 0}], timeout_s=0.05)
    with pytest.raises(HarnessError, match=r'readers of /odom within 0.05 s'):
        process._wait_heard()
    assert len(asked) > 1
