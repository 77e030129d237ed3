pytest_plugins = ['r2d2_sim.pytest_plugin']


def test_steps_sim_node_in_its_own_process(r2d2_sim_process):
    sim = r2d2_sim_process(start_paused=True, publish_rate=20.0, cmd_vel_timeout=0.0)
    sim.send_cmd_vel(linear=0.3)  # returns once sim_node has counted it
    state = sim.step(40)          # 40 control periods of 1/20 s, through ~/step
    assert state['sim_time'] == 2.0 and state['commands_received'] == 1
    assert sim.ground_truth().pose.pose.position.x > 0.5
