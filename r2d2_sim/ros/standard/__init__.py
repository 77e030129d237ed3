"""
ROS 2's simulation standard (``simulation_interfaces``) on the simulator node.

:mod:`.server` serves the simulation's state, steps and resets and assembles
the rest; :mod:`.entities` lists, reads, places, spawns and deletes entities.
"""
