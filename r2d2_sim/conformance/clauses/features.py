"""FEAT: what the simulator declares against what it serves, and RESULT: result codes."""

from typing import Any, List, Optional

import functools

from r2d2_sim.conformance.clause import Clause, clause as any_clause, ClauseFailed
from r2d2_sim.conformance.discovery import (
    ACTION, FEATURE_INTERFACES, FEATURES, SERVICES, SUB_FEATURES)
from r2d2_sim.conformance.target import Target, UNKNOWN_NAME

CLAUSES: List[Clause] = []
# These only ask: they run wherever the simulator is, not from STOPPED.
clause = functools.partial(any_clause, start=False)


@clause(CLAUSES, 'FEAT-01', 'GetSimulatorFeatures is served and answers', (),
        'GetSimulatorFeatures.srv',
        'Simulators adhering to the standard need to implement at least this interface.')
def features_served(t: Target) -> None:
    """Read the features again (the runner read them on connecting)."""
    t.read_features()


@clause(CLAUSES, 'FEAT-02', 'every declared feature is one the standard defines', (),
        'SimulatorFeatures.msg',
        'uint16[] features # A list of simulation features as specified by the list above.')
def features_known(t: Target) -> None:
    """Values outside SimulatorFeatures' constants are named."""
    t.read_features()
    known = {getattr(t.msg.SimulatorFeatures, name) for name in FEATURES}
    unknown = sorted(set(t.feature_values) - known)
    if unknown:
        raise ClauseFailed(f'declared values that are no feature: {unknown}')


@clause(CLAUSES, 'FEAT-03', 'every declared feature\'s service or action is served', (),
        'SimulatorFeatures.msg',
        'SPAWNING = 0 # Supports spawn interface (SpawnEntity).')
def declared_are_served(t: Target) -> None:
    """Fail a declared interface feature whose service (or action) is not found."""
    found = t.scan()
    missing = []
    for feature in sorted(t.features or ()):
        for alternatives in FEATURE_INTERFACES.get(feature, ()):
            if not any(kind in found for kind in alternatives.split('|')):
                missing.append(f'{feature} ({alternatives.replace("|", " or ")})')
    if missing:
        raise ClauseFailed(f'declared but not served under {t.prefix!r}: {", ".join(missing)}')


@clause(CLAUSES, 'FEAT-04', 'a service or action served without its feature declared is named',
        (), 'Result.msg',
        'While feature support can sometimes be deduced from presence of corresponding service / '
        'action interface, in other cases it is about supporting certain call parameters, formats '
        'and options within interface call.', advisory=True)
def served_are_declared(t: Target) -> Optional[str]:
    """
    Note each served interface whose every feature is undeclared; never a failure.

    The standard does not forbid serving an interface whose feature is not
    declared (one may answer FEATURE_UNSUPPORTED, 0): a client that goes by
    GetSimulatorFeatures, as Result.msg tells it to, does not use it.
    """
    found = t.scan()
    undeclared = []
    for kind in list(SERVICES) + [ACTION]:
        owners = [f for f, kinds in FEATURE_INTERFACES.items()
                  if any(kind in alt.split('|') for alt in kinds)]
        if kind in found and owners and not any(f in (t.features or ()) for f in owners):
            undeclared.append(f'{kind} ({" or ".join(owners)})')
    if undeclared:
        return (f'note: served but not declared, so a client going by the features will not '
                f'use them: {", ".join(undeclared)}')
    return None


@clause(CLAUSES, 'FEAT-05', 'a feature of part of an interface comes with that interface\'s', (),
        'SimulatorFeatures.msg',
        'SIMULATION_STATE_PAUSE = 26 # Supports the STATE_PAUSED SimulationState in '
        'SetSimulationState interface.')
def sub_features_have_parents(t: Target) -> None:
    """SIMULATION_RESET_TIME without SIMULATION_RESET, and the like, fail."""
    declared = t.features or frozenset()
    orphans = [f'{sub} without {" or ".join(parents)}' for sub, parents in SUB_FEATURES.items()
               if sub in declared and not any(p in declared for p in parents)]
    if orphans:
        raise ClauseFailed('; '.join(orphans))


# -- RESULT: 0 means unsupported; NOT_FOUND for what does not exist --------------------

ZERO = ('Result.msg', 'RESULT_FEATURE_UNSUPPORTED = 0 # Feature is not supported by the '
        'simulator, check GetSimulatorFeatures.')
NOT_FOUND = ('Result.msg', 'RESULT_NOT_FOUND = 2 # No match for input (such as when entity '
             'name does not exist).')


@clause(CLAUSES, 'RESULT-01', 'GetSimulationState answers OK, not 0',
        ('SIMULATION_STATE_GETTING',), *ZERO)
def state_result(t: Target) -> None:
    """Ask a declared query: RESULT_OK."""
    t.ok('GetSimulationState', t.srv.GetSimulationState.Request(), 'GetSimulationState')


@clause(CLAUSES, 'RESULT-02', 'GetEntities answers OK, not 0', (), *ZERO,
        services=('GetEntities',))
def entities_result(t: Target) -> None:
    """Ask GetEntities (no feature stands for it: served is enough): RESULT_OK."""
    t.ok('GetEntities', t.srv.GetEntities.Request(), 'GetEntities')


@clause(CLAUSES, 'RESULT-03', 'GetEntitiesStates answers OK, not 0', ('ENTITY_STATE_GETTING',),
        *ZERO)
def entities_states_result(t: Target) -> None:
    """Ask a declared query: RESULT_OK."""
    t.ok('GetEntitiesStates', t.srv.GetEntitiesStates.Request(), 'GetEntitiesStates')


@clause(CLAUSES, 'RESULT-04', 'GetSpawnables answers OK, not 0', ('SPAWNABLES',), *ZERO)
def spawnables_result(t: Target) -> None:
    """Ask a declared query: RESULT_OK."""
    t.ok('GetSpawnables', t.srv.GetSpawnables.Request(), 'GetSpawnables')


def _not_found(t: Target, kind: str, **fields: Any) -> None:
    request = getattr(t.srv, kind).Request(**fields)
    t.expect(kind, request, (t.msg.Result.RESULT_NOT_FOUND,), f'{kind} of {UNKNOWN_NAME!r}')


@clause(CLAUSES, 'RESULT-05', 'GetEntityState of an unknown entity is NOT_FOUND',
        ('ENTITY_STATE_GETTING',), *NOT_FOUND)
def state_not_found(t: Target) -> None:
    """Name an entity nobody has: NOT_FOUND."""
    _not_found(t, 'GetEntityState', entity=UNKNOWN_NAME)


@clause(CLAUSES, 'RESULT-06', 'SetEntityState of an unknown entity is NOT_FOUND',
        ('ENTITY_STATE_SETTING',), *NOT_FOUND)
def set_state_not_found(t: Target) -> None:
    """Place an entity nobody has at a valid pose: NOT_FOUND."""
    t.expect('SetEntityState', t.entities.set_request(UNKNOWN_NAME, t.entities.slot(0)),
             (t.msg.Result.RESULT_NOT_FOUND,), f'SetEntityState of {UNKNOWN_NAME!r}')


@clause(CLAUSES, 'RESULT-07', 'GetEntityInfo of an unknown entity is NOT_FOUND',
        ('ENTITY_INFO_GETTING',), *NOT_FOUND)
def info_not_found(t: Target) -> None:
    """Name an entity nobody has: NOT_FOUND."""
    _not_found(t, 'GetEntityInfo', entity=UNKNOWN_NAME)


@clause(CLAUSES, 'RESULT-08', 'SetEntityInfo of an unknown entity is NOT_FOUND',
        ('ENTITY_INFO_SETTING',), *NOT_FOUND)
def set_info_not_found(t: Target) -> None:
    """Name an entity nobody has: NOT_FOUND."""
    _not_found(t, 'SetEntityInfo', entity=UNKNOWN_NAME)


@clause(CLAUSES, 'RESULT-09', 'GetEntityBounds of an unknown entity is NOT_FOUND',
        ('ENTITY_BOUNDS',), *NOT_FOUND)
def bounds_not_found(t: Target) -> None:
    """Name an entity nobody has: NOT_FOUND."""
    _not_found(t, 'GetEntityBounds', entity=UNKNOWN_NAME)


@clause(CLAUSES, 'RESULT-10', 'DeleteEntity of an unknown entity is NOT_FOUND', ('DELETING',),
        *NOT_FOUND)
def delete_not_found(t: Target) -> None:
    """Name an entity nobody has: NOT_FOUND."""
    _not_found(t, 'DeleteEntity', entity=UNKNOWN_NAME)


@clause(CLAUSES, 'RESULT-11', 'GetNamedPoseBounds of an unknown pose is NOT_FOUND',
        ('POSE_BOUNDS',), *NOT_FOUND)
def pose_bounds_not_found(t: Target) -> None:
    """Name a named pose nobody has: NOT_FOUND."""
    _not_found(t, 'GetNamedPoseBounds', name=UNKNOWN_NAME)
