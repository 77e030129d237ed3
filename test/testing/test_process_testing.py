"""The ROS arguments the child-process layer reads (its processes: system/test_process.py)."""

from r2d2_sim.testing.process import parse_ros_args, RosArgs, sim_node_command


def test_remaps_for_the_node_are_read_and_others_left_out():
    args = ['-p', 'x:=1', '-r', '__ns:=/a', '--remap', '/clock:=/a/clock',
            '-r', 'other_node:/tf:=/x', '-r', 'r2d2_sim:scan:=front_scan', '-r', '__node:=sim']
    assert parse_ros_args(args, 'r2d2_sim') == RosArgs(
        'sim', '/a', ('/clock:=/a/clock', 'scan:=front_scan'))
    assert parse_ros_args([], 'r2d2_sim') == RosArgs(None, None, ())


def test_a_parameter_given_as_none_is_left_at_the_nodes_default():
    """SimProcess(record=None) means no recording, not a file named null."""
    command = sim_node_command({'record': None, 'scan_rate': 10.0, 'world': 'room'},
                               command=['sim_node'])
    assert command == ['sim_node', '--ros-args', '-p', 'scan_rate:=10.0', '-p', 'world:="room"']
    assert sim_node_command({'record': None}, command=['sim_node']) == ['sim_node']
