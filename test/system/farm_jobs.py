"""
Farms for the runner's system tests: docs/farm.md's stopper, and a variation that waits to die.

Workers import this file by its path (``farm_jobs.py:FARM``), as a user's
farm is named on the command line. ``R2D2_FARM_VICTIM=SEED:FILE`` makes the
variation of that seed write its process id into FILE once its simulator and
its Fast DDS participant exist, then wait (up to a minute) for the test to
kill its process; every other variation is the stopper's run, unchanged.
``FARM`` runs 20 simulated seconds (the pinned references'), ``SHORT`` 4.
"""

import os
from pathlib import Path
import sys
import time

from r2d2_sim.farm import FarmJob, safe

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'examples' / 'farm'))
import test_stopper_farm as example  # noqa: E402  (docs/farm.md's example)

VICTIM_ENV = 'R2D2_FARM_VICTIM'
WAIT_TO_BE_KILLED_S = 60.0


def stopper_or_victim(harness, scenario):
    """Add the stopper; as the victim, say where this process is and wait to be killed."""
    victim = os.environ.get(VICTIM_ENV, '')
    seed, _, path = victim.partition(':')
    if victim and int(seed) == scenario.seed:
        scratch = Path(path + '.new')
        scratch.write_text(str(os.getpid()), encoding='utf-8')
        scratch.rename(path)
        deadline = time.monotonic() + WAIT_TO_BE_KILLED_S
        while time.monotonic() < deadline:
            time.sleep(0.05)  # the test kills this process meanwhile
        raise RuntimeError(f'not killed within {WAIT_TO_BE_KILLED_S:g} s')
    example.goal_stopper(harness, scenario)


FARM = FarmJob(example.SPACE, stopper_or_victim, seconds=20.0, verdict=safe,
               parameters=example.PARAMETERS, name='stopper')
SHORT = FarmJob(example.SPACE, stopper_or_victim, seconds=4.0, verdict=safe,
                parameters=example.PARAMETERS, name='stopper')


# A stopper that stops too late (0.3 m: R2D2's legs stand out further), among 0.3 m boxes
# ahead of a robot at the origin driving to (2.5, 0): test_farm_system.py's late stopper.
LATE_SPACE = example.ScenarioSpace(
    obstacles=(0, 3), area=(0.9, -0.6, 1.5, 0.6), box_size=(0.3, 0.3), box_yaw=(0.0, 0.0),
    start_area=(0.0, 0.0, 0.0, 0.0), start_yaw=(0.0, 0.0), goal_area=(2.5, 0.0, 2.5, 0.0),
    keep_out=0.5)


def late_stopper(harness, scenario):
    """Add a stopper that stops at 0.3 m."""
    harness.add_node(example.GoalStopper(scenario.goal_point, stop_m=0.3,
                                         context=harness.context))


LATE = FarmJob(LATE_SPACE, late_stopper, seconds=4.0, verdict=safe,
               parameters=example.PARAMETERS, name='late')
