"""
sim_node's paced loop, with stand-ins for the node and the pacer: the schedule it keeps.

A simulator at half real time still steps and publishes correctly; only the
deadlines it waits for tell. These check them exactly: one physics step per
1/(240 * real_time_factor) s, a GUI frame's batch per batch/(240 * factor) s,
and no waiting at all as fast as possible; and a loop that never sleeps (as
fast as possible, or behind its deadlines) lets the ROS threads have the
interpreter lock every YIELD_EVERY_S.
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
        def __init__(self, period_s, sleep=None, **kwargs):
            super().__init__(period_s, sleep=lambda s: None, **kwargs)
            self.sleep_given = sleep  # run_paced's: the stop event's wait
            self.waits = 0
            made.append(self)

        def wait(self):
            self.waits += 1
            return True  # it slept: on time
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
    # It sleeps on the stop event: a signal ends the wait at once, however slow the rate.
    assert pacers[0].sleep_given == stop.wait


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


class SteppedClock:
    """A wall clock that moves ``step_s`` each time it is read."""

    def __init__(self, step_s):
        self.now, self.step_s = 0.0, step_s

    def __call__(self):
        self.now += self.step_s
        return self.now


class LatePacer:
    """A pacer always behind its deadlines: it never sleeps."""

    def wait(self):
        return False

    def reanchor(self):
        pass


def test_as_fast_as_possible_yields_the_interpreter_every_interval():
    """The clock moves a third of YIELD_EVERY_S a reading: a yield every three or four loops."""
    stop = threading.Event()
    node = Node(stop, periods=30, real_time_factor=0.0)
    yields = []
    clock = SteppedClock(sim_node.YIELD_EVERY_S / 3.0)
    sim_node.run_paced(node, stop, yield_=lambda: yields.append(clock.now), clock=clock)
    gaps = [b - a for a, b in zip(yields, yields[1:])]
    assert len(node.advances) == 30 and 6 <= len(yields) <= 10
    assert all(gap >= sim_node.YIELD_EVERY_S for gap in gaps)


def test_a_loop_behind_its_deadlines_yields_and_one_on_time_does_not(pacers):
    """Late: the pacer never sleeps, so the loop yields; on time its sleeps are the yields."""
    stop = threading.Event()
    node = Node(stop, periods=20)
    yields = []
    sim_node.run_paced(node, stop, pacer=LatePacer(), yield_=lambda: yields.append(1),
                       clock=SteppedClock(sim_node.YIELD_EVERY_S))
    assert node.advances == [1] * 20 and len(yields) >= 10
    stop.clear()
    on_time = Node(stop, periods=20)
    sim_node.run_paced(on_time, stop, yield_=lambda: yields.append(2),
                       clock=SteppedClock(sim_node.YIELD_EVERY_S))
    assert pacers[0].waits == 20 and 2 not in yields


def test_a_paused_loop_waits_and_reanchors_without_yielding():
    """Paused (advance says False): a 5 ms wait and a fresh schedule; yields only when it ran."""
    stop = threading.Event()
    node = Node(stop, periods=3)
    answers = iter([False, False, True, True, True])
    reanchored = []

    class Pacer(LatePacer):
        def reanchor(self):
            reanchored.append(1)

    def advance(steps):
        running = next(answers)
        if running:
            node.advance_if_running(steps)
        return running
    yields = []
    sim_node.run_paced(node, stop, pacer=Pacer(), advance=advance,
                       yield_=lambda: yields.append(1),
                       clock=SteppedClock(sim_node.YIELD_EVERY_S))
    assert reanchored == [1, 1] and len(yields) == 3 and node.advances == [1] * 3
