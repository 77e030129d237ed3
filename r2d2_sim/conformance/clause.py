"""
One clause of the standard: an id, a title, the features it needs, the sentence it checks.

No ROS here: the clause table is read by the docs and by ``--list`` without
rclpy. A clause's check is a function of a
:class:`~r2d2_sim.conformance.target.Target`; it returns for a pass (a str:
a note that goes with the pass, such as a reading the standard allows that
the clause could not check further), raises :class:`ClauseFailed` with a
one-line reason for a failure and :class:`ClauseSkipped` when something it
needs beyond its features is missing (no ``/clock``, nothing to spawn). An
``advisory`` clause never fails: what it finds is a note under its pass.
"""

from typing import Callable, List, NamedTuple, Sequence, Tuple

__all__ = ['Clause', 'ClauseFailed', 'ClauseSkipped', 'Outcome', 'PASS', 'FAIL', 'SKIP',
           'clause', 'feature_text', 'one_line', 'LINE_LIMIT']

PASS, FAIL, SKIP = 'PASS', 'FAIL', 'SKIP'
# The most characters of a simulator's text the kit prints in one reason or header line.
LINE_LIMIT = 400


class ClauseFailed(Exception):
    """The simulator does not do what the clause's sentence says; ``str()`` is the reason."""


class ClauseSkipped(Exception):
    """The clause cannot run here (no ``/clock``, nothing to spawn...); ``str()`` says why."""


class Clause(NamedTuple):
    """
    One checkable sentence of ``simulation_interfaces`` (Jazzy 1.5.1).

    ``features``: the SimulatorFeatures names it needs declared, each a name
    or alternatives joined by ``|``; ``unless``: names whose declaration
    makes it moot (all of them declared: skipped); ``services``: interfaces
    it calls that no feature stands for (GetEntities), skipped when not
    served; ``source`` and ``quote``: the definition file and the sentence
    of it the clause checks; ``start``: False for a clause that only asks
    (FEAT, RESULT), which runs wherever the simulator is instead of from STOPPED;
    ``advisory``: True for a clause whose finding the standard does not make
    a fault (it notes it, and passes).
    """

    id: str
    title: str
    features: Tuple[str, ...]
    source: str
    quote: str
    check: Callable
    unless: Tuple[str, ...] = ()
    services: Tuple[str, ...] = ()
    start: bool = True
    advisory: bool = False

    @property
    def group(self) -> str:
        """Return the group of the clause, the part of its id before the dash (``STATE``)."""
        return self.id.rsplit('-', 1)[0]


class Outcome(NamedTuple):
    """What one clause gave: PASS, FAIL or SKIP, a one-line reason, and how long it took."""

    clause: Clause
    status: str
    reason: str = ''
    seconds: float = 0.0


def feature_text(features: Sequence[str]) -> str:
    """Return features as people read them: ``A, B or C`` for ``('A', 'B|C')``."""
    return ', '.join(f.replace('|', ' or ') for f in features)


def one_line(text: str, limit: int = LINE_LIMIT) -> str:
    """
    Return ``text`` as one printable line: ``limit`` characters at most, and a count of the rest.

    A reason quotes what the simulator sent (names, frames, messages), which
    may hold line breaks or megabytes: the kit never prints either.
    """
    head = ''.join(c if c.isprintable() else ' ' for c in text[:limit])
    rest = len(text) - limit
    return head + (f'... ({rest} more characters)' if rest > 0 else '')


def clause(registry: List[Clause], id: str, title: str, features: Sequence[str], source: str,
           quote: str, *, unless: Sequence[str] = (), services: Sequence[str] = (),
           start: bool = True, advisory: bool = False) -> Callable[[Callable], Callable]:
    """Return a decorator that adds its function to ``registry`` as a clause."""
    def add(check: Callable) -> Callable:
        registry.append(Clause(id, title, tuple(features), source, quote, check,
                               tuple(unless), tuple(services), start, advisory))
        return check
    return add
