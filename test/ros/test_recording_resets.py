"""
A recording across time resets: log times go on while the messages' stamps start again.

Players order by log time (``ros2 bag play``, Foxglove, ``replay``): with the
simulated time set back to 0 by a reset, the second episode's messages were
logged at the first's times and came out mixed with them.
"""

from r2d2_sim.testing import read_recording, SimHarness


def test_log_times_never_go_back_across_a_time_reset(tmp_path):
    """Two episodes with a time reset between: log times rise, each episode's stamps from 0."""
    path = tmp_path / 'two_episodes.mcap'
    with SimHarness(record=str(path), scan_rate=0.0, imu_rate=0.0) as harness:
        harness.advance(seconds=0.5)
        first_end = harness.sim.sim_time_ns
        harness.reset_world(time=True, state=True, spawned=False)
        harness.advance(seconds=0.25)
    clocks = read_recording(str(path), topics=['/clock'])['/clock']
    logged = [r.log_time_ns for r in clocks]
    stamps = [r.message.clock.sec * 10**9 + r.message.clock.nanosec for r in clocks]
    assert logged == sorted(logged)  # in order for any player
    restart = next(i for i in range(1, len(stamps)) if stamps[i] < stamps[i - 1])
    assert stamps[restart - 1] == first_end and stamps[restart] < 10**8  # the reset
    assert logged[:restart] == stamps[:restart]  # the first episode at its simulated times
    assert [t - first_end for t in logged[restart:]] == stamps[restart:]
