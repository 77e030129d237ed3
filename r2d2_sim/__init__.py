"""
r2d2_sim: a ROS 2 node that runs a PyBullet simulation of R2D2.

Layered so each part can be tested alone, with no import running back up:
pure math (``kinematics``, ``transforms``, ``sensors``, ``drive_controller``,
``parameters``, ``timing``), PyBullet (``body``, ``world``), the ROS-free
simulation core (``robot``, ``simulation``: ``Simulation.step()`` returns what
every robot measured), and ROS (``outputs``, ``command_input``,
``robot_interfaces``: one robot's ROS side, ``node``, ``sim_node``). Tools and
the testing API (``testing``, ``pytest_plugin``) sit on top. README.md's
Design section maps every module and follows one ``cmd_vel`` through them.
"""
