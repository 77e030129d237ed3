"""
The simulation core, free of ROS: one step for the world, and its parts by concept.

At the top, :class:`~.simulation.Simulation`: the step (``step()`` returns what
every robot measured as plain data), the reset, and every change of the world
(spawn, delete, place, describe, load and unload a world). It composes the
parts, each owning its data and answering what changes nothing:

- :mod:`.entities`: the world's bodies as the standard's entities (names, states,
  info, bounds; a spawn's files read, a body loaded); :mod:`.spawnables`: what a
  spawn may load, read safely;
- :mod:`.worlds`: what a world is, where worlds come from, reading, listing and
  the one loaded (:class:`~.worlds.files.WorldFiles`);
- :mod:`.robots`: one driven robot (drive train, controller, sensors);
- :mod:`.settings`: the parameter table and everything derived from it;
- :mod:`.startup`: what start-up loads, in its order, and building it again on a reset;
- :mod:`.sdf`: Gazebo's SDF read into bodies (no PyBullet until they are loaded);
- :mod:`.oracles`: what a run did as the physics saw it (contacts, clearance, tipping);
- the standard's vocabulary shared by entities and worlds: :mod:`.names`,
  :mod:`.tags`, :mod:`.bounds`.
"""
