"""
The executables: ``sim_node`` (:mod:`.sim_node`), ``demo``, ``drive`` and ``replay``.

:mod:`.cli` holds what they share: argparse types, the split of ROS
arguments, and stopping on SIGINT and SIGTERM where the program chooses.
"""
