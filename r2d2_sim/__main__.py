"""``python -m r2d2_sim [--ros-args ...]`` runs the simulator node, as ``sim_node`` does."""

import sys

from r2d2_sim.apps.sim_node import main

if __name__ == '__main__':
    sys.exit(main())
