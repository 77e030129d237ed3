"""
The demo's lockstep loop with stand-ins: every state is answered before the next step.

A bit-for-bit comparison of two runs passes as long as each state happens to
arrive quickly; this checks the rule itself, with a state that takes a few
spins to arrive: the loop must wait for it (up to its stall deadline), answer
it, and only then step again.
"""

import threading
from types import SimpleNamespace

from geometry_msgs.msg import Twist

from r2d2_sim.apps import demo

STEP_NS = 10**9 // 60


class SlowDelivery:
    """An executor whose each spin brings the pending state one spin closer (3 spins)."""

    def __init__(self, driver):
        self.driver = driver
        self.pending = None  # (time_ns, spins left)

    def spin_once(self, timeout_sec=None):
        if self.pending is None:
            return
        time_ns, left = self.pending
        if left > 1:
            self.pending = (time_ns, left - 1)
            threading.Event().wait(min(timeout_sec or 0.0, 0.005))  # a spin takes a while
            return
        self.pending = None
        self.driver.answer(time_ns)


class Driver:
    """The manoeuvre driver's face to the loop: answers each state with one command."""

    def __init__(self, states):
        self.phases = (SimpleNamespace(duration_s=0.0),)  # no settle phase: every state counts
        self.handled_ns = -1
        self.done = False
        self.left = states
        self.sent = []

    def linked(self):
        return True

    def begin(self, start_s=0.0):
        pass

    def answer(self, time_ns):
        self.handled_ns = time_ns
        self.sent.append(Twist())
        self.sent[-1].linear.x = time_ns / 1e9
        self.left -= 1
        self.done = self.left == 0


class Simulator:
    """sim_node through SimProcess: ~/step, then the state comes through the executor."""

    def __init__(self, executor, driver):
        self.executor, self.driver = executor, driver
        self.time_ns = 0
        self.log = []
        self.process = SimpleNamespace(exited=lambda: False,
                                       failure_message=lambda text: text)

    def step(self):
        # A loop that steps on unanswered never finishes the driver: stop it here.
        assert len(self.log) < 40, f'stepping on without answering: {self.log[-6:]}'
        self.log.append(('step', self.driver.handled_ns, self.time_ns))
        self.time_ns += STEP_NS
        self.executor.pending = (self.time_ns, 3)
        return {'sim_time_ns': self.time_ns}

    def send_cmd_vel(self, twist):
        self.log.append(('command', twist.linear.x))


def test_each_state_is_answered_before_the_next_step():
    """Five periods whose states arrive on the third spin: step, answer, command, step..."""
    driver = Driver(states=5)
    executor = SlowDelivery(driver)
    simulator = Simulator(executor, driver)
    guard = SimpleNamespace(found=lambda: False, check=lambda: None)
    demo._run_lockstep(driver, executor, simulator, guard, threading.Event(), driver.sent)
    steps = [entry for entry in simulator.log if entry[0] == 'step']
    assert len(steps) == 5
    for i, (_, handled_ns, time_ns) in enumerate(steps):
        assert handled_ns == (time_ns if i else -1), simulator.log  # the last state answered
    commands = [entry[1] for entry in simulator.log if entry[0] == 'command']
    assert commands == [n * STEP_NS / 1e9 for n in range(1, 6)]
    assert [entry[0] for entry in simulator.log] == ['step', 'command'] * 5
