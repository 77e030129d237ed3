"""
The simulator's settings: one parameter table, and everything derived from it.

No ROS. The modules:

- :mod:`.table`: :data:`~.table.PARAMETERS` (name, ROS type, default, unit, bounds,
  description), :class:`~.table.SimConfig` and :func:`~.table.parse_config`;
- :mod:`.readers`: a raw value in, a valid one out, or one :class:`~.readers.ConfigError` line;
- :mod:`.robots`: several robots' settings, each the world's with its own on top;
- :mod:`.given`: parameters as a program hands them over (numpy's numbers, paths), and
  the names the simulator does not read;
- :mod:`.reference`: the table written out for people (``sim_node --help``,
  ``docs/parameters.md``).
"""
