"""
The clauses, in the order they run: :data:`CLAUSES`.

One module per part of the standard: :mod:`.features` (FEAT, RESULT),
:mod:`.state` (STATE), :mod:`.stepping` (STEP, ACTION), :mod:`.reset`
(RESET), :mod:`.spawning` (SPAWN, BATCH, DELETE, SPAWNABLES),
:mod:`.entities` (ENTITY, BOUNDS), :mod:`.filters` (FILTER) and
:mod:`.worlds` (NAMED, WORLD). The worlds come last: loading one changes
the most. None of them imports ROS at the top, so the table can be read
(``--list``, the docs) without rclpy.
"""

from typing import Dict, List

from r2d2_sim.conformance.clause import Clause
from r2d2_sim.conformance.clauses import (
    entities, features, filters, reset, spawning, state, stepping, worlds)

__all__ = ['CLAUSES', 'BY_ID', 'GROUPS']

CLAUSES: List[Clause] = (features.CLAUSES + state.CLAUSES + stepping.CLAUSES + reset.CLAUSES
                         + spawning.CLAUSES + entities.CLAUSES + filters.CLAUSES + worlds.CLAUSES)
BY_ID: Dict[str, Clause] = {c.id: c for c in CLAUSES}
GROUPS: List[str] = list(dict.fromkeys(c.group for c in CLAUSES))
