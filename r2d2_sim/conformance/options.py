"""
Where the simulator under test is and what the kit may use there: :class:`KitOptions`.

Its own module so that the :class:`~r2d2_sim.conformance.target.Target` and
the seam its parts call through (:mod:`~r2d2_sim.conformance.calls`) both
name it without importing one another.
"""

from typing import NamedTuple, Optional, Tuple

__all__ = ['KitOptions']


class KitOptions(NamedTuple):
    """
    Where the simulator is and what the kit may use there.

    ``prefix``: the namespace its services are under (``/``, ``/gzserver``);
    ``domain_id``: its ROS domain (None: ``ROS_DOMAIN_ID``, else 0);
    ``asset``: a URI its SpawnEntity takes (``cube.urdf``, a ``.usd``);
    ``world``: a URI its LoadWorld takes; ``timeout_s``: the longest wait
    for any one reply or discovery; ``free_space``: a point with free room
    around it (20 m along x) where the kit puts what it spawns;
    ``world_frame``: the world frame's name besides '' and ``world``;
    ``clock_topic``: where simulated time is published; ``total_timeout_s``:
    the longest the whole run may take, connecting included (None: 30
    timeouts; see :class:`~r2d2_sim.conformance.runner.Kit`).
    """

    prefix: str = '/'
    domain_id: Optional[int] = None
    asset: str = ''
    world: str = ''
    timeout_s: float = 10.0
    free_space: Tuple[float, float, float] = (20.0, 20.0, 5.0)
    world_frame: str = 'world'
    clock_topic: str = '/clock'
    total_timeout_s: Optional[float] = None
