"""Absolute-deadline pacing, checked against a fake clock."""

import pytest

from r2d2_sim.model.timing import DeadlinePacer, StepSchedule


class FakeTime:
    """A clock that only moves when the code under test sleeps or work is simulated."""

    def __init__(self):
        self.now = 100.0
        self.sleeps = []

    def clock(self):
        return self.now

    def sleep(self, seconds):
        self.sleeps.append(seconds)
        self.now += seconds


def test_deadlines_do_not_accumulate_work_time():
    """With 1 ms of work per 4 ms tick, each sleep is 3 ms and tick n ends at n * 4 ms."""
    t = FakeTime()
    pacer = DeadlinePacer(0.004, clock=t.clock, sleep=t.sleep)
    start = t.now
    for _ in range(1000):
        t.now += 0.001  # the step's own cost
        pacer.wait()
    assert t.sleeps[0] == pytest.approx(0.003)
    assert t.now - start == pytest.approx(1000 * 0.004)  # no drift, unlike sleep(period)


def test_late_tick_is_caught_up_without_sleeping():
    """A tick that overran by less than max_lag is made up by the next ticks."""
    t = FakeTime()
    pacer = DeadlinePacer(0.004, clock=t.clock, sleep=t.sleep)
    start = t.now
    t.now += 0.010  # one slow step: 2.5 periods
    pacer.wait()
    pacer.wait()
    pacer.wait()
    assert len(t.sleeps) == 1  # the first two waits were already late
    assert t.now - start == pytest.approx(3 * 0.004)


def test_long_stall_reanchors_instead_of_bursting():
    """After a stall beyond max_lag the schedule restarts from now."""
    t = FakeTime()
    pacer = DeadlinePacer(0.004, max_lag_s=0.1, clock=t.clock, sleep=t.sleep)
    t.now += 5.0
    pacer.wait()
    assert pacer.overruns == 1
    before = t.now
    pacer.wait()
    assert t.now - before == pytest.approx(0.004)


def test_reanchor_after_pause():
    """reanchor() schedules the next tick one period from now."""
    t = FakeTime()
    pacer = DeadlinePacer(0.004, clock=t.clock, sleep=t.sleep)
    t.now += 0.05
    pacer.reanchor()
    pacer.wait()
    assert t.sleeps == [pytest.approx(0.004)]


def test_wait_says_whether_it_slept():
    """On time it sleeps and says True; past the deadline it does not sleep and says False."""
    t = FakeTime()
    pacer = DeadlinePacer(0.004, clock=t.clock, sleep=t.sleep)
    assert pacer.wait() is True and len(t.sleeps) == 1
    t.now += 0.010  # work past the next deadline
    assert pacer.wait() is False and len(t.sleeps) == 1


def test_period_must_be_positive():
    """A zero period is refused."""
    with pytest.raises(ValueError):
        DeadlinePacer(0.0)


def test_step_schedule_divisor_rate():
    """60 Hz at 240 Hz: due every 4th step, at 4, 8, 12."""
    schedule = StepSchedule(240.0, 60.0)
    due = [step for step in range(1, 13) if schedule.due(step)]
    assert due == [4, 8, 12]


def test_step_schedule_non_divisor_rate_has_no_drift():
    """50 Hz at 240 Hz: the n-th event at ceil(4.8 n); exactly 50 in 240 steps."""
    schedule = StepSchedule(240.0, 50.0)
    due = [step for step in range(1, 241) if schedule.due(step)]
    assert due[:5] == [5, 10, 15, 20, 24]  # ceil(4.8), ceil(9.6), ceil(14.4), ...
    assert len(due) == 50 and due[-1] == 240


def test_step_schedule_fires_once_when_a_step_is_seen_late():
    """Checking only at step 9 after missing 4 and 8 fires once, then resumes at 12."""
    schedule = StepSchedule(240.0, 60.0)
    assert schedule.due(9)
    assert schedule.next_step == 8  # the second event is still owed
    assert schedule.due(10) and schedule.next_step == 12


@pytest.mark.parametrize('rate_hz', [0.0, 1e-7, -5.0])
def test_a_schedule_refuses_a_rate_that_is_no_rate(rate_hz):
    """A rate that rounds to 0 Hz would divide by zero: a ValueError instead."""
    with pytest.raises(ValueError, match='positive'):
        StepSchedule(240.0, rate_hz)
