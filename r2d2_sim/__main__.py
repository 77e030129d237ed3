"""``python -m r2d2_sim [--ros-args ...]`` runs the simulator node, as ``sim_node`` does."""

from r2d2_sim.launcher import sim_node

if __name__ == '__main__':
    sim_node()
