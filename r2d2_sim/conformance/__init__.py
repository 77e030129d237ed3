"""
A conformance kit for ROS 2's simulation standard (``simulation_interfaces``), for any simulator.

It finds a simulator's services and action by type under a prefix (``/``,
``/gzserver``, ``/isaacsim``), reads the features it declares, and checks
the standard's definitions clause by clause: each clause cites the sentence
it checks, and is skipped, not failed, when a feature it needs is not
declared. It needs nothing the simulator does not serve, starts every
clause from STOPPED and undoes what it did. Run it as ``sim_conformance``
(:mod:`.cli`), ``python -m r2d2_sim.conformance``, from Python (:class:`Kit`)
or under pytest (:mod:`.pytest_plugin`, opt-in).

The layer above all the others: it uses the testing API's
:class:`~r2d2_sim.testing.RemoteProbe` and the package's one client of the
standard, :class:`~r2d2_sim.testing.StandardClient` (never the server), and
nothing imports it. By role:
:mod:`.clause` (what a clause is), :mod:`.clauses` (the clauses, one module
per part of the standard), :mod:`.discovery` (interfaces by type, which
feature stands for which), :mod:`.target` (the simulator as the clauses see
it, composed of parts: :mod:`.simulation_verbs`, :mod:`.entity_verbs`,
:mod:`.clock_verbs`, :mod:`.world_verbs`, :mod:`.undo`), :mod:`.runner`
(:class:`Kit`, :func:`select`), :mod:`.report` (matrix, JUnit XML, the docs'
clause list). ``docs/conformance.md`` is its manual.
"""

from r2d2_sim.conformance.clause import (
    Clause, ClauseFailed, ClauseSkipped, FAIL, Outcome, PASS, SKIP)
from r2d2_sim.conformance.clauses import BY_ID, CLAUSES, GROUPS
from r2d2_sim.conformance.runner import Kit, select
from r2d2_sim.conformance.target import KitError, KitOptions, Target

__all__ = ['Kit', 'KitOptions', 'KitError', 'Target', 'select', 'CLAUSES', 'BY_ID', 'GROUPS',
           'Clause', 'Outcome', 'ClauseFailed', 'ClauseSkipped', 'PASS', 'FAIL', 'SKIP']
