pytest_plugins = ['r2d2_sim.pytest_plugin']


def test_drives_forward(r2d2_sim):
    r2d2_sim.send_cmd_vel(linear=0.3)  # returns once the simulator has it
    r2d2_sim.advance(seconds=2.0)      # simulated time: about 0.2 s of wall time
    assert r2d2_sim.ground_truth().pose.pose.position.x > 0.5
