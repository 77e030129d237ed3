"""
The ROS side: the node and what it translates, and nothing the core could do.

:class:`~.node.SimNode` owns the core and advances it when asked; each robot's
interfaces (:mod:`.robot_interfaces`: outputs, ``cmd_vel``, description, joint
info) are kept by :mod:`.fleet`; messages are serialized once and patched in
place (:mod:`.serialization`, :mod:`.outputs`, :mod:`.tf_outputs`); the
node's own services are in :mod:`.control_services`, ROS 2's simulation
standard in :mod:`.standard`.
"""
