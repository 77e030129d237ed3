"""The joint info the node serves (r2d2_sim.ros.joint_info), read from the world of physics/."""


def test_joint_info_has_17_attributes_per_joint(world, robot):
    """Each joint record carries the 17 getJointInfo attributes plus its link."""
    from r2d2_sim.ros.joint_info import joint_info
    info = joint_info(robot)
    assert len(info) == 15
    for entry in info:
        assert len([k for k in entry if k not in ('link', 'type_code')]) == 17
        raw = world.client.getJointInfo(robot.id, entry['index'])
        assert entry['name'] == raw[1].decode() and entry['link_name'] == raw[12].decode()
        assert entry['type_code'] == raw[2] and entry['max_force'] == raw[10]
        assert entry['link']['mass'] > 0.0
