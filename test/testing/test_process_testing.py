"""The ROS arguments the child-process layer reads (its processes: system/test_process.py)."""

from r2d2_sim.testing.process import parse_ros_args, RosArgs


def test_remaps_for_the_node_are_read_and_others_left_out():
    args = ['-p', 'x:=1', '-r', '__ns:=/a', '--remap', '/clock:=/a/clock',
            '-r', 'other_node:/tf:=/x', '-r', 'r2d2_sim:scan:=front_scan', '-r', '__node:=sim']
    assert parse_ros_args(args, 'r2d2_sim') == RosArgs(
        'sim', '/a', ('/clock:=/a/clock', 'scan:=front_scan'))
    assert parse_ros_args([], 'r2d2_sim') == RosArgs(None, None, ())
