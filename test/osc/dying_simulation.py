"""A simulation that kills its own process at reset: a crash in C, for the executors' tests."""

import os
import signal

from r2d2_sim.osc import R2D2Simulation


class DyingSimulation(R2D2Simulation):
    """R2D2Simulation whose reset kills the process it runs in (SIGKILL), as a segfault would."""

    def reset(self, **parameters):
        os.kill(os.getpid(), signal.SIGKILL)
