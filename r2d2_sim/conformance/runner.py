"""
Running clauses against one simulator: :class:`Kit`, and choosing clauses: :func:`select`.

Each clause runs from the same start state (STOPPED, see
:meth:`~r2d2_sim.conformance.undo.TargetUndo.prepare`; those that only ask,
FEAT and RESULT, wherever the simulator is), is skipped when a
feature it needs is not declared (or an interface no feature stands for is
not served), and is undone afterwards (what it spawned deleted, the world
it loaded replaced). At the end the kit leaves the simulator in the state it
found it in, reset. The whole run has a time limit (``total_timeout_s``):
past it the clause under way fails, the rest are not run, and the kit takes
a little more time (:data:`RESTORE_TIMEOUTS` timeouts) to leave the simulator
as found. A reason is one line, however much the simulator sent.
"""

import fnmatch
import time
from typing import Callable, List, Optional, Sequence, Tuple

from r2d2_sim.conformance.clause import (
    Clause, ClauseFailed, ClauseSkipped, FAIL, feature_text, one_line, Outcome, PASS, SKIP)
from r2d2_sim.conformance.clauses import CLAUSES, GROUPS
from r2d2_sim.conformance.target import KitError, KitOptions, Target

__all__ = ['Kit', 'select', 'TOTAL_TIMEOUTS', 'RESTORE_TIMEOUTS']

# Without total_timeout_s, a run may take this many timeouts (a whole run of
# r2d2_sim takes about one: 131 clauses in 7 s against a 10 s timeout).
TOTAL_TIMEOUTS = 30
# After the run, leaving the simulator as found may take this many timeouts more.
RESTORE_TIMEOUTS = 3


def select(only: Sequence[str] = (), skip: Sequence[str] = (),
           clauses: Sequence[Clause] = CLAUSES) -> List[Clause]:
    """
    Return the clauses ``only`` names (all when empty) but those ``skip`` names, in order.

    Each name is a clause id (``STATE-03``), a group (``STATE``) or a
    shell pattern (``SPAWN-1*``); a name that matches nothing is a KitError.
    """
    def matching(name: str) -> set:
        pattern = name.strip().upper()
        if pattern in GROUPS:
            pattern += '-*'
        found = {c.id for c in clauses if fnmatch.fnmatchcase(c.id, pattern)}
        if not found:
            raise KitError(f'{name!r} names no clause or group (groups: {", ".join(GROUPS)})')
        return found
    chosen = set().union(*(matching(n) for n in only)) if only else {c.id for c in clauses}
    dropped = set().union(*(matching(n) for n in skip)) if skip else set()
    return [c for c in clauses if c.id in chosen and c.id not in dropped]


class Kit:
    """
    The conformance kit on one simulator: connect, run clauses, leave it as found.

    ``Kit(KitOptions(prefix='/gzserver'))``; :meth:`run` (or
    :meth:`run_clause`) connects on first use; :meth:`close` restores the
    simulator and closes the kit's node. A context manager.
    Raises KitError for the kit's own setup (simulation_interfaces missing)
    and when it cannot tell which simulator to check (none at the prefix but
    some elsewhere, or several there): then it touches none.
    ``check``, called before each clause and between the spins of every
    wait, may raise (the command line's Ctrl-C: KeyboardInterrupt) to stop
    the kit there, where no rclpy code is under way.
    """

    def __init__(self, options: Optional[KitOptions] = None,
                 check: Optional[Callable[[], None]] = None) -> None:
        self.options = options or KitOptions()
        self.target = Target(self.options)
        if check is not None:
            self.target.check = check
        self.connected = False
        self.closed = False
        self.restore_problems: List[str] = []
        self.outcomes: List[Outcome] = []  # every clause run so far, in order
        self.total_s = self.options.total_timeout_s or TOTAL_TIMEOUTS * self.options.timeout_s
        self.deadline: Optional[float] = None  # time.monotonic() when the run's time is up

    def connect(self) -> None:
        """Find the simulator's interfaces and features (once); KitError if it cannot choose."""
        if not self.connected:
            self.connected = True
            self.deadline = time.monotonic() + self.total_s
            self.target.client.deadline = self.deadline
            self.target.connect()
        if self.target.refusal:
            raise KitError(self.target.refusal)

    def out_of_time(self) -> bool:
        """Return True once the run's time limit has passed."""
        return self.deadline is not None and time.monotonic() >= self.deadline

    def run_clause(self, clause: Clause) -> Outcome:
        """Run one clause from the start state; return its Outcome (kept in ``outcomes``)."""
        self.target.check()
        self.connect()
        started = time.monotonic()
        status, reason = self._run(clause)
        outcome = Outcome(clause, status, one_line(reason), time.monotonic() - started)
        self.outcomes.append(outcome)
        return outcome

    def setup_problems(self) -> List[str]:
        """Return what the user gave that the simulator refused (the world, the asset)."""
        t = self.target
        return [p for p in (t.world.problem, t.entities.problem) if p]

    def unchecked(self) -> str:
        """
        Return why the run so far checked nothing, in one line ('' when a clause ran).

        The simulator's features unknown (none found at the prefix), or every
        clause skipped (none chosen, none whose features are declared, the
        time limit): either way the run says nothing of the simulator, and
        the front ends count it an error, never a pass.
        """
        t = self.target
        if t.features_error:
            return one_line(f'nothing was checked: {t.features_error}')
        if any(o.status in (PASS, FAIL) for o in self.outcomes):
            return ''
        if not self.outcomes:
            return 'nothing was checked: no clause was run'
        late = any(o.reason.startswith('not run: ') for o in self.outcomes)
        return (f'nothing was checked: all clauses skipped ({len(self.outcomes)} chosen'
                + (f'; the run\'s time limit, {self.total_s:g} s, was reached)' if late else ')'))

    def _run(self, clause: Clause) -> Tuple[str, str]:
        t = self.target
        limit = f'the run\'s time limit ({self.total_s:g} s) was reached'
        if t.features is None:  # before the time limit: an absent simulator fails FEAT-01
            if clause.id == 'FEAT-01':
                return FAIL, t.features_error
            return SKIP, 'the features are unknown (see FEAT-01)'
        if self.out_of_time():
            return SKIP, f'not run: {limit}'
        missing = [f for f in clause.features if not t.declared(f)]
        if missing:
            return SKIP, f'needs {feature_text(missing)} (not declared)'
        if clause.unless and all(t.declared(f) for f in clause.unless):
            return SKIP, f'moot: {feature_text(clause.unless)} declared'
        unserved = [s for s in clause.services if s not in t.interfaces]
        if unserved:
            return SKIP, f'{", ".join(unserved)} not served'
        if clause.start and t.world.missing:  # no world: nothing starts from STOPPED
            return SKIP, t.world.missing
        rival = t.rivals()  # another simulator came up where requests would reach it too
        if rival:
            t.refusal = rival
            raise KitError(rival)
        try:
            t.undo.prepare(stop=clause.start)
        except (ClauseFailed, ClauseSkipped) as exc:
            late = f' ({limit})' if self.out_of_time() else ''
            return FAIL, f'could not reach the start state (STOPPED): {exc}{late}'
        try:
            note = clause.check(t)
            status, reason = PASS, note if isinstance(note, str) else ''
        except ClauseFailed as exc:
            status, reason = FAIL, str(exc)
        except ClauseSkipped as exc:
            status, reason = SKIP, str(exc)
        except Exception as exc:  # a defect of the kit itself: shown, never a traceback
            first = str(exc).splitlines()[0][:200] if str(exc) else ''
            status, reason = FAIL, f'kit error ({type(exc).__name__}: {first})'
        if self.out_of_time():  # what it left is undone by close(), given time of its own
            return status, reason if status == PASS else '; '.join(filter(None, [reason, limit]))
        problems = t.undo.cleanup()
        if problems:
            reason = '; '.join(filter(None, [reason, 'afterwards: ' + '; '.join(problems)]))
        return status, reason

    def run(self, clauses: Sequence[Clause] = CLAUSES,
            each: Optional[Callable[[Outcome], object]] = None) -> List[Outcome]:
        """Run ``clauses`` in order; call ``each(outcome)`` after each; return the outcomes."""
        outcomes = []
        for clause in clauses:
            outcome = self.run_clause(clause)
            outcomes.append(outcome)
            if each is not None:
                each(outcome)
        return outcomes

    def close(self) -> List[str]:
        """
        Leave the simulator as found (TargetUndo.restore), close the node; return problems.

        Once: closing again returns the same problems.
        """
        if self.closed:
            return self.restore_problems
        self.closed = True
        t = self.target
        try:
            if self.connected and t.features is not None and not t.refusal:
                t.client.deadline = (time.monotonic()
                                     + RESTORE_TIMEOUTS * self.options.timeout_s)
                # A request a Ctrl-C left under way is answered (or timed out) first.
                t.wait(lambda: not t.calls_under_way())
                self.restore_problems = [one_line(p) for p in t.undo.restore()]
        finally:
            self.target.close()
        return self.restore_problems

    def __enter__(self) -> 'Kit':
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
