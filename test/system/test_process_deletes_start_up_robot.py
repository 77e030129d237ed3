"""
A start-up robot deleted from a simulator in its own process, and built again by a full reset.

Through ``SimProcess`` (the standard's services over ROS): the robot's topics
go with it, and after ``reset_world`` the harness reads the robot built again.
"""


def test_a_process_harness_follows_the_robot_out_of_the_world_and_back(r2d2_sim_process):
    """delete_entity('r2d2'): no robot; reset_world(): r2d2 again, its state read as before."""
    sim = r2d2_sim_process(start_paused=True)
    sim.step_physics(24)
    before = sim.ground_truth().pose.pose.position
    sim.delete_entity('r2d2')
    assert sim.entities() == ['ground_plane'] and sim.robot_names == []
    sim.reset_world()
    assert sim.entities() == ['ground_plane', 'r2d2'] and sim.robot_names == ['r2d2']
    sim.step_physics(24)
    after = sim.ground_truth().pose.pose.position
    assert (after.x, after.y, after.z) == (before.x, before.y, before.z)  # as launched
