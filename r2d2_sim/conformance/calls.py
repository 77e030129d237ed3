"""
What the parts of the :class:`~r2d2_sim.conformance.target.Target` use of it: :class:`TargetCalls`.

The Target composes its parts (``t.sim``, ``t.entities``, ``t.clock``,
``t.world``, ``t.undo``) and hands each itself; a part calls back only
through this seam: the connection's node and client, the interfaces found,
the declared features and the typed calls. So a part depends on what it
uses, not on the module that builds it, and the two never import each
other. The Target satisfies it as it is (the type checker checks that
where the parts are made).
"""

from typing import Any, Callable, Dict, List, Optional, Protocol, Sequence, TYPE_CHECKING

from r2d2_sim.conformance.options import KitOptions

if TYPE_CHECKING:
    from rclpy.node import Node

    from r2d2_sim.testing.remote import RemoteProbe
    from r2d2_sim.testing.standard import StandardClient

__all__ = ['TargetCalls']


class TargetCalls(Protocol):
    """The connection to the simulator under test, as the Target's parts call it."""

    options: KitOptions
    timeout_s: float
    probe: 'RemoteProbe'
    node: 'Node'
    client: 'StandardClient'
    msg: Any                          # simulation_interfaces.msg
    srv: Any                          # simulation_interfaces.srv
    interfaces: Dict[str, str]        # interface -> service (or action) name
    spawn_formats: List[str]

    def declared(self, *features: str) -> bool:
        """Return True when each feature given is declared; ``A|B`` means either of the two."""

    def wait(self, condition: Callable[[], bool], timeout_s: Optional[float] = None) -> bool:
        """Spin the kit's node until ``condition()`` holds (True) or the timeout passes."""

    def call(self, kind: str, request: Any, check: bool = True) -> Any:
        """Call the service of interface ``kind``; return its reply (see the Target's)."""

    def describe(self, kind: Optional[str], reply: Any) -> str:
        """Return a reply's result for a reason: ``NAME_NOT_UNIQUE (101): 'taken'``."""

    def expect(self, kind: str, request: Any, codes: Sequence[int], doing: str) -> Any:
        """Call and return the reply if its result is one of ``codes``; else ClauseFailed."""

    def ok(self, kind: str, request: Any, doing: str) -> Any:
        """Call and return the reply if its result is OK; else ClauseFailed."""
