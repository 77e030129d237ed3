"""
The simulation core, free of ROS: parameters, robots, entities, one step for the world.

The parameter table (:mod:`.parameters`) and its readers, several robots'
settings (:mod:`.robot_parameters`), a robot's drive train and sensors
(:mod:`.drive_train`, :mod:`.sensor_mounts`, :mod:`.robot`), the standard's
entities (:mod:`.entities`), and :class:`~.simulation.Simulation`, whose
``step()`` returns what every robot measured as plain data.
"""
