"""``python -m r2d2_sim.conformance [options]`` runs the kit, as ``sim_conformance`` does."""

import sys

from r2d2_sim.conformance.cli import main

if __name__ == '__main__':
    sys.exit(main())
