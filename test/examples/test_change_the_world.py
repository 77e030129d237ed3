import pytest
from sensor_msgs.msg import LaserScan

pytest_plugins = ['r2d2_sim.pytest_plugin']


def test_a_box_dropped_in_the_path_shows_in_the_scan(r2d2_sim):
    scans = []
    r2d2_sim.create_node('listener').create_subscription(LaserScan, 'scan', scans.append, 10)
    r2d2_sim.send_cmd_vel(linear=0.3)
    r2d2_sim.advance(seconds=1.0)
    assert scans[-1].ranges[180] == float('inf')  # beam 180 looks ahead: nothing there
    x = r2d2_sim.ground_truth().pose.pose.position.x
    box = r2d2_sim.spawn('cube.urdf', position=(x + 2.0, 0.0, 1.0))  # a 1 m cube, dropped
    r2d2_sim.advance(seconds=1.0)  # it lands on the floor; the robot drives on 0.3 m
    assert r2d2_sim.entity_state(box).position[2] == pytest.approx(0.5, abs=0.01)
    assert scans[-1].ranges[180] == pytest.approx(2.0 - 0.5 - 0.3, abs=0.01)
    r2d2_sim.reset_world()  # time back to 0, everything home, spawned entities gone
    assert r2d2_sim.entities() == ['ground_plane', 'r2d2']
