"""
The conformance kit against a second implementation: a toy simulator, right, then wrong.

None of Gazebo, Isaac Sim or O3DE can be installed on this machine (no
registry here carries them), so the second implementation is
``test/toy_simulator.py``: every service and the action under ``/toy``,
named its own way, found by type. Right, it passes every clause; with the
defect of one clause (:data:`toy_simulator.DEFECTS`), that clause fails:
each clause can fail. So can the kit on the further violations an audit of it
injected (:data:`toy_simulator.MORE_DEFECTS`), each failing the clauses that
check it; a reading the standard allows (:data:`toy_simulator.VARIANTS`)
passes them. Two toys on one domain are two simulators: the kit checks the one it
is pointed at and never touches the other.
"""

import pytest

from helpers import next_domain_id
from r2d2_sim.conformance import BY_ID, CLAUSES, FAIL, Kit, KitError, KitOptions, PASS, SKIP
from toy_simulator import DEFECTS, MORE_DEFECTS, S, ToySimulator, VARIANTS

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


@pytest.mark.parametrize('clause_id', [c.id for c in CLAUSES if not c.advisory])
def test_each_clause_fails_on_its_defect(clause_id):
    """The toy wrong in the one way a clause checks: that clause FAILs, with a reason."""
    outcome = run([clause_id], defect=clause_id)[clause_id]
    assert outcome.status == FAIL, (DEFECTS[clause_id], outcome)
    assert outcome.reason and '\n' not in outcome.reason


def test_feat_04_notes_an_undeclared_service_and_passes():
    """
    Serving GetNamedPoses without NAMED_POSES declared: a note under a pass, never a failure.

    Result.msg says support "can sometimes be deduced" from a served
    interface; nothing makes serving one without its feature a fault.
    """
    assert [c.id for c in CLAUSES if c.advisory] == ['FEAT-04']
    clause_id = 'FEAT-04'
    outcome = run([clause_id], defect=clause_id)[clause_id]
    assert outcome.status == PASS and outcome.reason.startswith('note: '), outcome
    assert 'GetNamedPoses (NAMED_POSES)' in outcome.reason and '\n' not in outcome.reason
    right = run([clause_id])[clause_id]
    assert right.status == PASS and not right.reason, right


def test_reset_07_names_the_randomization_the_standard_allows():
    """SCOPE_STATE may randomize where a simulator has that on: a failure of RESET-07 says so."""
    outcome = run(['RESET-07'], defect='RESET-07')['RESET-07']
    assert outcome.status == FAIL and 'randomizes the state' in outcome.reason, outcome


@pytest.mark.parametrize('defect', sorted(MORE_DEFECTS))
def test_each_further_violation_fails_the_clauses_that_check_it(defect):
    """An empty GetNamedPoses, states out of order, time half back: the checking clauses fail."""
    what, clause_ids = MORE_DEFECTS[defect]
    outcomes = run(clause_ids, defect=defect)
    passed = {i: (o.status, o.reason) for i, o in outcomes.items() if o.status != FAIL}
    assert not passed, (what, passed)
    assert all(o.reason and '\n' not in o.reason for o in outcomes.values())


@pytest.mark.parametrize('variant', sorted(VARIANTS))
def test_each_reading_the_standard_allows_passes(variant):
    """A box's corners upper first, a cancel rejected...: the clauses about them still pass."""
    what, clause_ids = VARIANTS[variant]
    outcomes = run(clause_ids, defect=variant)
    other = {i: (o.status, o.reason) for i, o in outcomes.items() if o.status != PASS}
    assert not other, (what, other)


def test_time_run_while_the_kit_plays_to_pause_is_not_taken_for_no_reset():
    """
    A pause that takes 0.5 s (50 steps, over the kit's slack of 48): STATE-14 still passes.

    From STOPPED the kit plays to pause, and the time runs for as long as
    that takes (a CI machine under load took 333 ms against sim_node): the
    earliest time read meanwhile shows the reset, not the time at the pause.
    """
    outcome = run(['STATE-14'], defect='SLOW-PAUSE')['STATE-14']
    assert outcome.status == PASS, outcome


def test_a_simulator_in_a_namespace_is_not_taken_by_the_default_prefix():
    """The default prefix / is the root's own level: a toy under /victim is refused, untouched."""
    domain = next_domain_id()
    with ToySimulator(domain, prefix='/victim') as victim:
        with Kit(KitOptions(domain_id=domain, timeout_s=TIMEOUT_S)) as kit:
            with pytest.raises(KitError, match="--prefix /victim") as refused:
                kit.connect()
        assert '\n' not in str(refused.value)
        assert victim.changes == 0


def test_two_simulators_at_one_level_are_refused_and_neither_touched():
    """Two toys serving the same names: the kit would reach both, so it refuses in one line."""
    domain = next_domain_id()
    with ToySimulator(domain, prefix='/') as one, ToySimulator(domain, prefix='/') as two:
        with Kit(KitOptions(domain_id=domain, timeout_s=TIMEOUT_S)) as kit:
            with pytest.raises(KitError, match='several simulators') as refused:
                kit.connect()
        assert '\n' not in str(refused.value)
        assert one.changes == 0 and two.changes == 0


def test_the_kit_checks_the_simulator_at_its_prefix_and_names_the_others():
    """A toy at / and one under /victim: the root's is checked, the other named and untouched."""
    domain = next_domain_id()
    with ToySimulator(domain, prefix='/') as mine, ToySimulator(domain, prefix='/victim') as other:
        with Kit(KitOptions(domain_id=domain, timeout_s=TIMEOUT_S)) as kit:
            kit.connect()
            assert kit.target.others == ['/victim']
            outcomes = kit.run([BY_ID['STATE-03'], BY_ID['STATE-05']])
        assert [o.status for o in outcomes] == [PASS, PASS], outcomes
        assert mine.changes > 0 and other.changes == 0


def test_a_slow_simulator_cannot_hold_the_kit_past_its_total_time():
    """Replies of 0.5 s within a 2 s timeout: past the run's time limit, the rest is not run."""
    domain = next_domain_id()
    options = kit_options(domain)._replace(timeout_s=2.0, total_timeout_s=4.0)
    with ToySimulator(domain, defect='SLOW'):
        with Kit(options) as kit:
            outcomes = kit.run([c for c in CLAUSES if c.group == 'STATE'])
    late = [o for o in outcomes if 'time limit' in o.reason]
    assert late and outcomes[-1] in late, [(o.clause.id, o.status, o.reason) for o in outcomes]
    assert all(o.status != PASS for o in late)


# A service no feature stands for (GetEntities), and LoadWorld with its features left out:
# what the toy goes without, and what the skips then say.
NOT_SERVED = {'GetEntities': (('GetEntities',), 'GetEntities not served'),
              'LoadWorld': (('LoadWorld', 'WORLD_LOADING', 'WORLD_RESOURCE_STRING'),
                            'needs WORLD_LOADING')}


@pytest.mark.parametrize('service', sorted(NOT_SERVED))
def test_a_service_not_served_skips_the_clauses_that_need_it(service):
    """
    A toy without GetEntities (or LoadWorld): no clause fails for the missing interface.

    Each clause names what it calls among its needs, so it is skipped; and
    what the kit spawned is deleted by name, without a listing to find it.
    """
    without, says = NOT_SERVED[service]
    domain = next_domain_id()
    with ToySimulator(domain, without=without) as toy:
        with Kit(kit_options(domain)) as kit:
            outcomes = kit.run(CLAUSES)
            problems = kit.close()
        left = sorted(n for n in toy.entities if n.startswith('conformance_'))
    bad = {o.clause.id: o.reason for o in outcomes
           if o.status == FAIL or 'afterwards' in o.reason}
    assert not bad and not problems and not left, (bad, problems, left)
    assert any(o.status == SKIP and says in o.reason for o in outcomes)


# -- the world the kit finds, and what the user gives it --------------------------------------

def run_all(toy_options, kit_changes=None, clause_ids=None):
    """
    Run clauses (default: all) against a toy made with ``toy_options``; return the findings.

    (outcomes by id, what close() could not put back, kit.setup_problems(), the toy's world,
    state and entities after the kit).
    """
    domain = next_domain_id()
    options = kit_options(domain)._replace(**(kit_changes or {}))
    chosen = [BY_ID[i] for i in clause_ids] if clause_ids else CLAUSES
    with ToySimulator(domain, **toy_options) as toy:
        with Kit(options) as kit:
            outcomes = {o.clause.id: o for o in kit.run(chosen)}
            problems = kit.close()
            setup = kit.setup_problems()
        after = (toy.world, toy.state, sorted(toy.entities))
    return outcomes, problems, setup, after


def test_a_simulator_found_with_no_world_gets_one_for_the_run_and_none_after():
    """
    No world at the start: the kit loads one (an available one), runs every clause, unloads it.

    A simulation with no world "cannot be started, stopped, or paused": without a world of its
    own, no clause could start from STOPPED.
    """
    outcomes, problems, setup, after = run_all({'world': None})
    failed = {i: o.reason for i, o in outcomes.items() if o.status != PASS and i != 'FILTER-09'}
    assert not failed and not problems and not setup, (failed, problems, setup)
    assert after == (None, S.STATE_NO_WORLD, []), after


def test_a_simulator_with_no_world_and_none_to_load_skips_what_needs_one():
    """No world and no world to load: the clauses that start from STOPPED skip, saying why."""
    outcomes, problems, setup, after = run_all(
        {'world': None, 'without': ('AVAILABLE_WORLDS', 'WORLD_TAGS')})
    assert not [o for o in outcomes.values() if o.status == FAIL] and not problems
    starting = [o for o in outcomes.values() if o.clause.start]
    why = 'no world is loaded, and the kit has none to load: give it one (--world URI)'
    assert all(o.status == SKIP and (o.reason == why or o.reason.startswith(('needs ', 'moot')))
               for o in starting), [o for o in starting if o.reason != why]
    assert all(o.status == PASS for o in outcomes.values() if o.clause.group == 'FEAT')
    assert after == (None, S.STATE_NO_WORLD, []), after


@pytest.mark.parametrize('world', ['yard', None])
def test_a_world_the_simulator_refuses_is_one_setup_line_not_its_failure(world):
    """--world naming no world of the toy's: tried once, one setup line, dependent clauses skip."""
    outcomes, problems, setup, after = run_all(
        {'world': world}, {'world': 'toy://worlds/nowhere'},
        ['STATE-03', 'WORLD-04', 'WORLD-05', 'WORLD-10', 'NAMED-01'])
    assert setup == ["the world given, 'toy://worlds/nowhere', could not be loaded: LoadWorld "
                     "answered NO_RESOURCE (102): 'no world toy://worlds/nowhere'"], setup
    assert not [o for o in outcomes.values() if o.status == FAIL], outcomes
    for clause_id in ('WORLD-04', 'WORLD-05', 'WORLD-10'):
        assert outcomes[clause_id].status == SKIP and 'could not be loaded' in (
            outcomes[clause_id].reason), outcomes[clause_id]
    assert (outcomes['STATE-03'].status == PASS) == (world is not None), outcomes['STATE-03']
    assert not problems and after[0] == world, (problems, after)


def test_an_asset_the_simulator_refuses_is_one_setup_line_not_its_failure():
    """--asset naming nothing the toy has, no resource strings: one setup line, spawns skip."""
    outcomes, problems, setup, after = run_all(
        {'without': ('SPAWNING_RESOURCE_STRING',)}, {'asset': 'toy://nothing'},
        ['STATE-13', 'SPAWN-01', 'SPAWN-04', 'ENTITY-05', 'DELETE-01'])
    assert setup == ["the asset given, 'toy://nothing', could not be spawned: SpawnEntity "
                     "answered NO_RESOURCE (104): 'no asset toy://nothing'"], setup
    assert all(o.status == SKIP and o.reason == setup[0] for o in outcomes.values()), outcomes
    assert not problems and not [n for n in after[2] if n.startswith('conformance_')]


def test_a_world_the_kit_cannot_load_back_is_never_replaced():
    """A world named without its uri: the clauses that load another skip, and it stays."""
    loading = ['WORLD-04', 'WORLD-05', 'WORLD-06', 'WORLD-07', 'WORLD-09', 'WORLD-10',
               'WORLD-11', 'WORLD-12', 'WORLD-13', 'WORLD-14']
    outcomes, problems, setup, after = run_all({'defect': 'WORLD-NO-URI'}, None, loading)
    assert all(o.status == SKIP and 'could not load it back' in o.reason
               for o in outcomes.values()), {i: (o.status, o.reason) for i, o in outcomes.items()}
    assert not problems and not setup and after[0] == 'yard', (problems, after)
