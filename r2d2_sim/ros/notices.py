"""
Warnings said once per process: a farm or a test suite starts many simulators in one.

No ROS here beyond the logger handed in. A fact about the machine (an
optional interface package missing) is the same for every simulator a
process starts; saying it at each start filled a 200-variation farm's log
with 200 copies.
"""

import threading
from typing import Any, Set

__all__ = ['warn_once']

_said: Set[str] = set()
_lock = threading.Lock()


def warn_once(logger: Any, text: str) -> bool:
    """Log ``text`` as a warning unless this process said it already; True if logged now."""
    with _lock:
        if text in _said:
            return False
        _said.add(text)
    logger.warning(text)
    return True
