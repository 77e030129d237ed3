"""
r2d2_sim: a ROS 2 node that runs a PyBullet simulation of R2D2.

The folders are the layers, each importing only from those listed before it:

- :mod:`r2d2_sim.model`: pure math, numpy at most (kinematics, transforms, sensor
  models, timing, the drive controller);
- :mod:`r2d2_sim.physics`: PyBullet only (named records, bodies that own their
  ids, the world, ray casts, robot descriptions);
- :mod:`r2d2_sim.sim`: the ROS-free core (parameters, robots, entities,
  ``Simulation.step()`` returning plain data);
- :mod:`r2d2_sim.recording`: the live view and MCAP recording (no ROS, no physics);
- :mod:`r2d2_sim.ros`: the node, translation only (outputs, ``cmd_vel``, the
  control services, the simulation standard);
- :mod:`r2d2_sim.testing`: the public testing API (harnesses, domain leases, clients);
- :mod:`r2d2_sim.apps`: the executables (``sim_node``, ``demo``, ``drive``, ``replay``);
- :mod:`r2d2_sim.farm`: the scenario farm (seeded and Hypothesis-drawn variations,
  verdicts with their evidence, reports);
- :mod:`r2d2_sim.gym`: learning environments on the farm's scenario spaces (Gymnasium's
  ``R2D2Nav-v0``, PettingZoo), in process or over ROS, which nothing else imports.
- :mod:`r2d2_sim.conformance`: on top, imported by nothing: a kit that checks any
  simulator against ROS 2's simulation standard (``sim_conformance``).

At the top: :mod:`~r2d2_sim.errors` (one-line errors every layer raises),
:mod:`~r2d2_sim.client` (what any ROS client of the simulator needs) and the
pytest plugin. ``docs/design.md`` follows one ``cmd_vel`` and one spawn through them.
Public names that moved keep their old paths for one minor version, with a
``DeprecationWarning``: :mod:`~r2d2_sim.deprecations` holds the table, whose finder
is installed here (it imports nothing until an old name is used).
"""

from r2d2_sim.deprecations import install

install()
