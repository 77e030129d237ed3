"""
The simulation core, free of ROS: parameters, robots, entities, one step for the world.

The parameter table (:mod:`.parameters`), its readers and its reference
(:mod:`.parameter_docs`), several robots' settings (:mod:`.robot_parameters`),
a robot's drive train and sensors (:mod:`.drive_train`, :mod:`.sensor_mounts`,
:mod:`.robot`), the standard's entities and what a spawn may load
(:mod:`.entities`, :mod:`.spawnables`), the world as launched and built again
(:mod:`.launch`), what a run did as the physics saw it (:mod:`.oracles`), and
:class:`~.simulation.Simulation`, whose ``step()`` returns what every robot
measured as plain data.
"""
