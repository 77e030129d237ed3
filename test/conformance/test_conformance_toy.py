"""
The conformance kit against a second implementation: a toy simulator, right, then wrong.

None of Gazebo, Isaac Sim or O3DE can be installed on this machine (no
registry here carries them), so the second implementation is
``test/toy_simulator.py``: every service and the action under ``/toy``,
named its own way, found by type. Right, it passes every clause; with the
defect of one clause (:data:`toy_simulator.DEFECTS`), that clause fails:
each clause can fail.
"""

import pytest

from helpers import next_domain_id
from r2d2_sim.conformance import BY_ID, CLAUSES, FAIL, Kit, KitOptions, PASS, SKIP
from toy_simulator import DEFECTS, ToySimulator

# Replies come in milliseconds; FEAT-01's defect makes the kit wait this long for nothing.
TIMEOUT_S = 3.0


def kit_options(domain_id: int) -> KitOptions:
    """Return the kit's options for the toy: its prefix, its asset."""
    return KitOptions(prefix='/toy', domain_id=domain_id, asset='toy://box', timeout_s=TIMEOUT_S)


def run(clause_ids, defect=None, without=()):
    """Run clauses against a fresh toy (with ``defect``); return their outcomes by id."""
    domain = next_domain_id()
    with ToySimulator(domain, defect, without) as toy:
        with Kit(kit_options(domain)) as kit:
            outcomes = {o.clause.id: o for o in kit.run([BY_ID[i] for i in clause_ids])}
        assert toy.thread.is_alive(), 'the toy stopped spinning'
    return outcomes


def test_every_clause_has_a_defect_in_the_toy():
    """The toy can get each clause wrong, and names no clause the kit does not have."""
    assert sorted(DEFECTS) == sorted(c.id for c in CLAUSES)


def test_a_right_toy_passes_every_clause():
    """With no defect, every clause passes, but FILTER-09, moot where box bounds are declared."""
    outcomes = run([c.id for c in CLAUSES])
    failed = {i: o.reason for i, o in outcomes.items() if o.status != PASS and i != 'FILTER-09'}
    assert not failed, failed
    assert outcomes['FILTER-09'].status == SKIP, outcomes['FILTER-09']


def test_filter_09_passes_where_box_bounds_are_not_declared():
    """A toy that leaves ENTITY_BOUNDS_BOX out and refuses a box filter with 0 passes FILTER-09."""
    outcome = run(['FILTER-09'], without=('ENTITY_BOUNDS_BOX',))['FILTER-09']
    assert outcome.status == PASS, outcome


@pytest.mark.parametrize('clause_id', [c.id for c in CLAUSES])
def test_each_clause_fails_on_its_defect(clause_id):
    """The toy wrong in the one way a clause checks: that clause FAILs, with a reason."""
    outcome = run([clause_id], defect=clause_id)[clause_id]
    assert outcome.status == FAIL, (DEFECTS[clause_id], outcome)
    assert outcome.reason and '\n' not in outcome.reason
