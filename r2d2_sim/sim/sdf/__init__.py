"""
Gazebo's SDF worlds and models, read and made into the URDF bodies PyBullet loads; no ROS.

In the order a load goes: :mod:`.elements` (XML read safely, bounded, every
value placed in its file and element), :mod:`.resources` (``model://``,
Fuel's cache, packages, paths; where files may come from), :mod:`.reader`
with :mod:`.models` and :mod:`.parts` (the file and its includes into a
:mod:`.description`: models flattened, poses resolved through
:mod:`r2d2_sim.model.sdf_poses`, what is not simulated counted),
:mod:`.bodies` (each model as the URDF trees PyBullet can load),
:mod:`.meshes` and :mod:`.mesh_cache` (DAE, STL, OBJ converted once into
OBJ files kept by content), :mod:`.urdf` (the text), and :mod:`.loading`
(the steps in order). :mod:`.spawning` reads a model a spawn request brings;
:mod:`r2d2_sim.sim.worlds.sdf_format` makes SDF one of the world formats.
"""
