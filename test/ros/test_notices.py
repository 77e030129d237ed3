"""
A fact about the machine is said once per process, however many simulators it starts.

A farm worker or a test suite starts simulator after simulator in one
process: an optional interface package missing was one warning per
simulator (200 in a farm of 200 variations).
"""

from r2d2_sim.ros.notices import warn_once


class Logger:
    def __init__(self):
        self.lines = []

    def warning(self, text):
        self.lines.append(text)


def test_a_warning_is_said_once_per_process_whatever_the_logger():
    first, second = Logger(), Logger()
    text = 'test_notices: something optional is missing (said once)'
    assert warn_once(first, text)
    assert not warn_once(second, text)  # another simulator's logger, the same process
    assert warn_once(second, text + ', and something else')
    assert first.lines == [text] and second.lines == [text + ', and something else']
