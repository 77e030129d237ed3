"""
sim_node's paced loop, with stand-ins for the node and the pacer: the schedule it keeps.

A simulator at half real time still steps and publishes correctly; only the
deadlines it waits for tell. These check them exactly: one physics step per
1/(240 * real_time_factor) s, a GUI frame's batch per batch/(240 * factor) s,
and no waiting at all as fast as possible.
"""

import threading
from types import SimpleNamespace

import pytest

from r2d2_sim.apps import sim_node
from r2d2_sim.model import timing


class Node:
    """The SimNode's face to run_paced: config, its GUI batch, and advances it counts."""

    def __init__(self, stop, periods, real_time_factor=1.0, gui=False, batch=8):
        self.config = SimpleNamespace(physics_rate_hz=240.0,
                                      real_time_factor=real_time_factor, gui=gui)
        self.simulation = SimpleNamespace(steps_per_gui_frame=batch)
        self.advances = []
        self._stop, self._periods = stop, periods

    def advance_if_running(self, steps):
        self.advances.append(steps)
        if len(self.advances) == self._periods:
            self._stop.set()
        return True


@pytest.fixture
def pacers(monkeypatch):
    """Record every pacer run_paced makes: its period and its waits."""
    made = []

    class RecordingPacer(timing.DeadlinePacer):
        def __init__(self, period_s, **kwargs):
            super().__init__(period_s, sleep=lambda s: None, **kwargs)
            self.waits = 0
            made.append(self)

        def wait(self):
            self.waits += 1
    monkeypatch.setattr(timing, 'DeadlinePacer', RecordingPacer)
    return made


@pytest.mark.parametrize('factor', [1.0, 0.5, 2.0, 10.0])
def test_one_step_per_deadline_at_the_real_time_factor(pacers, factor):
    """Real time: a step, then a wait for the next deadline 1/(240 factor) s on."""
    stop = threading.Event()
    node = Node(stop, periods=5, real_time_factor=factor)
    sim_node.run_paced(node, stop)
    assert len(pacers) == 1 and pacers[0].period_s == pytest.approx(1.0 / (240.0 * factor))
    assert node.advances == [1] * 5 and pacers[0].waits == 5


def test_a_window_steps_a_frame_batch_per_deadline(pacers):
    """With the GUI, 8 steps a frame: the deadline is 8/240 s apart, still real time."""
    stop = threading.Event()
    node = Node(stop, periods=3, gui=True, batch=8)
    sim_node.run_paced(node, stop)
    assert pacers[0].period_s == pytest.approx(8.0 / 240.0)
    assert node.advances == [8] * 3


def test_as_fast_as_possible_waits_for_nothing(pacers):
    """real_time_factor 0: whole control periods back to back, no pacer at all."""
    stop = threading.Event()
    node = Node(stop, periods=4, real_time_factor=0.0)
    sim_node.run_paced(node, stop)
    assert pacers == [] and node.advances == [None] * 4
