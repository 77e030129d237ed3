"""FILTER: EntityFilters: a name regex, categories, tags, bounds, all combined with AND."""

import re
from typing import Any, List, Sequence, Tuple

from r2d2_sim.conformance.clause import Clause, clause, ClauseFailed, ClauseSkipped
from r2d2_sim.conformance.entity_verbs import Point
from r2d2_sim.conformance.target import Target

CLAUSES: List[Clause] = []

LISTED = ('GetEntities',)
SPAWNING = 'SPAWNING'
# Entities whose categories the category clauses read one by one, at most.
MOST_ENTITIES = 200
REGEX_QUOTE = ('string filter # ... Entity names are matched with the filter regular expression. '
               '... The regular expression syntax is POSIX Extended')
TAGS = ('ENTITY_TAGS', 'ENTITY_INFO_SETTING', SPAWNING)
RED, BIG = 'conformance_red', 'conformance_big'


def _picked(t: Target, filters: Any, doing: str) -> set:
    return set(t.entities.names(filters, doing))


def _expect_set(got: set, wanted: set, doing: str) -> None:
    if got != wanted:
        raise ClauseFailed(f'{doing} gave {sorted(got)[:6]}, expected {sorted(wanted)[:6]}')


@clause(CLAUSES, 'FILTER-01', 'a ^name$ filter picks exactly that entity', (SPAWNING,),
        'EntityFilters.msg', REGEX_QUOTE, services=LISTED)
def whole_name(t: Target) -> None:
    """Two boxes: ^a$ gives a alone."""
    a = t.entities.spawn(0)
    t.entities.spawn(1)
    _expect_set(_picked(t, t.entities.filters(f'^{a}$'), 'GetEntities'), {a}, f'the filter ^{a}$')


@clause(CLAUSES, 'FILTER-02', 'filters are POSIX extended: alternation, brackets, +', (SPAWNING,),
        'EntityFilters.msg', REGEX_QUOTE, services=LISTED)
def extended_syntax(t: Target) -> None:
    """Three boxes: ^(a|b)$ gives a and b; ^conformance_b[a-z]x_[0-9]+$ gives all the kit's."""
    a, b, _ = t.entities.spawn(0), t.entities.spawn(1), t.entities.spawn(2)
    _expect_set(_picked(t, t.entities.filters(f'^({a}|{b})$'), 'GetEntities'), {a, b},
                f'the filter ^({a}|{b})$')
    pattern = '^conformance_b[a-z]x_[0-9]+$'
    wanted = {n for n in t.entities.names() if re.fullmatch(pattern[1:-1], n)}
    _expect_set(_picked(t, t.entities.filters(pattern), 'GetEntities'), wanted,
                f'the filter {pattern}')


@clause(CLAUSES, 'FILTER-03', 'GetEntitiesStates applies the filter too',
        ('ENTITY_STATE_GETTING', SPAWNING), 'GetEntitiesStates.srv', 'EntityFilters filters # '
        'Optional filters for the query, including name, category, tags, and overlap filters.')
def states_filtered(t: Target) -> None:
    """Two boxes: GetEntitiesStates with ^a$ gives a and one state."""
    a = t.entities.spawn(0)
    t.entities.spawn(1)
    request = t.srv.GetEntitiesStates.Request(filters=t.entities.filters(f'^{a}$'))
    reply = t.ok('GetEntitiesStates', request, 'GetEntitiesStates')
    if list(reply.entities) != [a] or len(reply.states) != 1:
        raise ClauseFailed(f'GetEntitiesStates with ^{a}$ gave {list(reply.entities)[:5]} and '
                           f'{len(reply.states)} states')


def _categories(t: Target) -> dict:
    names = t.entities.names()
    if len(names) > MOST_ENTITIES:
        raise ClauseSkipped(f'{len(names)} entities: more than the {MOST_ENTITIES} whose '
                            'categories the kit reads')
    return {n: t.entities.info(n).category.category for n in names}


CATEGORIES_QUOTE = ('EntityCategory[] categories # ... Entities matching any of the categories '
                    'will be returned.')


@clause(CLAUSES, 'FILTER-04', 'a category filter picks the entities of that category',
        ('ENTITY_CATEGORIES', 'ENTITY_INFO_GETTING'), 'EntityFilters.msg', CATEGORIES_QUOTE,
        services=LISTED)
def one_category(t: Target) -> None:
    """For each category present: exactly the entities GetEntityInfo puts in it."""
    categories = _categories(t)
    for category in sorted(set(categories.values())):
        wanted = {n for n, c in categories.items() if c == category}
        _expect_set(_picked(t, t.entities.filters(categories=[category]), 'GetEntities'), wanted,
                    f'the category filter [{category}]')


@clause(CLAUSES, 'FILTER-05', 'two categories pick the entities of either',
        ('ENTITY_CATEGORIES', 'ENTITY_INFO_GETTING'), 'EntityFilters.msg', CATEGORIES_QUOTE,
        services=LISTED)
def two_categories(t: Target) -> None:
    """ROBOT and STATIC_OBJECT together: the entities of both."""
    categories = _categories(t)
    pair = (t.msg.EntityCategory.CATEGORY_ROBOT, t.msg.EntityCategory.CATEGORY_STATIC_OBJECT)
    wanted = {n for n, c in categories.items() if c in pair}
    _expect_set(_picked(t, t.entities.filters(categories=list(pair)), 'GetEntities'), wanted,
                f'the category filter {list(pair)}')


def _near_and_far(t: Target, bounds: Tuple[int, Sequence[Point]], doing: str) -> None:
    """Box a at slot 0 must be picked by ``bounds``, box b 3 m away must not."""
    a, b = t.entities.spawn(0), t.entities.spawn(1)
    got = _picked(t, t.entities.filters(bounds=bounds), 'GetEntities')
    if a not in got or b in got:
        raise ClauseFailed(f'{doing} around {a} gave {sorted(got)[:6]}: it must hold {a}, '
                           f'not {b} 3 m away')


def _cube(t: Target, half: float = 0.5) -> List[Tuple[float, float, float]]:
    x, y, z = t.entities.slot(0)
    return [(x + dx, y + dy, z + dz) for dx in (-half, half) for dy in (-half, half)
            for dz in (-half, half)]


def _box_corners(t: Target) -> List[Tuple[float, float, float]]:
    """Return a TYPE_BOX's points as Bounds.msg orders them: the upper corner, then the lower."""
    corners = _cube(t)
    return [corners[-1], corners[0]]


@clause(CLAUSES, 'FILTER-06', 'a sphere picks the entities that overlap it', (SPAWNING,),
        'EntityFilters.msg', 'Bounds bounds # ... though at least TYPE_SPHERE needs to be '
        'supported.', services=LISTED)
def sphere_filter(t: Target) -> None:
    """Filter by a sphere of 0.5 m around box a: a, not box b 3 m away."""
    _near_and_far(t, (t.msg.Bounds.TYPE_SPHERE, [t.entities.slot(0), (0.5, 0.0, 0.0)]), 'a sphere')


@clause(CLAUSES, 'FILTER-07', 'a box picks the entities that overlap it',
        ('ENTITY_BOUNDS_BOX', SPAWNING), 'SimulatorFeatures.msg', 'ENTITY_BOUNDS_BOX = 6 # '
        'Supports entity filtering with bounds with TYPE_BOX.', services=LISTED)
def box_filter(t: Target) -> None:
    """
    Filter by an axis-aligned box of 1 m around box a: a, not box b 3 m away.

    Its corners go as Bounds.msg orders them ("upper right and lower left
    corners of the box"): the upper one first.
    """
    _near_and_far(t, (t.msg.Bounds.TYPE_BOX, _box_corners(t)), 'a box')


@clause(CLAUSES, 'FILTER-08', 'a convex hull picks the entities that overlap it',
        ('ENTITY_BOUNDS_CONVEX', SPAWNING), 'SimulatorFeatures.msg', 'ENTITY_BOUNDS_CONVEX = 7 # '
        'Supports entity filtering with Bounds TYPE_CONVEX_HULL.', services=LISTED)
def hull_filter(t: Target) -> None:
    """Filter by the hull of a 1 m cube around box a: a, not box b 3 m away."""
    _near_and_far(t, (t.msg.Bounds.TYPE_CONVEX_HULL, _cube(t)), 'a convex hull')


@clause(CLAUSES, 'FILTER-09', 'a bounds type not declared is FEATURE_UNSUPPORTED', (),
        'EntityFilters.msg', 'If service is called with filter bounds set to an unsupported type, '
        'a FEATURE_UNSUPPORTED result will be returned.',
        unless=('ENTITY_BOUNDS_BOX', 'ENTITY_BOUNDS_CONVEX'), services=LISTED)
def unsupported_bounds(t: Target) -> None:
    """Filter by a box (or a hull) where that type is not declared: 0, not an answer."""
    B = t.msg.Bounds
    kind, points = ((B.TYPE_BOX, _box_corners(t))
                    if not t.declared('ENTITY_BOUNDS_BOX') else (B.TYPE_CONVEX_HULL, _cube(t)))
    request = t.srv.GetEntities.Request(filters=t.entities.filters(bounds=(kind, points)))
    t.expect('GetEntities', request, (t.msg.Result.RESULT_FEATURE_UNSUPPORTED,),
             f'GetEntities with bounds of the undeclared type {kind}')


def _tagged(t: Target) -> Tuple[str, str]:
    """Spawn a (tags red, big) and b (red); return their names."""
    a, b = t.entities.spawn(0), t.entities.spawn(1)
    _tag(t, ((a, [RED, BIG]), (b, [RED])))
    return a, b


def _tag(t: Target, tagging: Sequence[Tuple[str, List[str]]]) -> None:
    """Give each (name, tags) of ``tagging`` those tags with SetEntityInfo."""
    for name, tags in tagging:
        info = t.msg.EntityInfo(description='tagged by the conformance kit', tags=tags)
        t.ok('SetEntityInfo', t.srv.SetEntityInfo.Request(entity=name, info=info),
             f'SetEntityInfo of {name}')


@clause(CLAUSES, 'FILTER-10', 'a tags filter in ANY mode picks entities with any of the tags',
        TAGS, 'TagsFilter.msg', 'FILTER_MODE_ANY = 0 # Filter with OR mode (any tag can match).',
        services=LISTED)
def tags_any(t: Target) -> None:
    """Tag a red and big, b red: ANY [big, x] gives a; ANY [red] gives a and b."""
    a, b = _tagged(t)
    any_mode = t.msg.TagsFilter.FILTER_MODE_ANY
    _expect_set(_picked(t, t.entities.filters(tags=[BIG, 'conformance_x'], mode=any_mode),
                        'GetEntities'), {a}, f'ANY [{BIG}, conformance_x]')
    _expect_set(_picked(t, t.entities.filters(tags=[RED], mode=any_mode), 'GetEntities'), {a, b},
                f'ANY [{RED}]')


@clause(CLAUSES, 'FILTER-11', 'a tags filter in ALL mode picks entities with all the tags', TAGS,
        'TagsFilter.msg', 'FILTER_MODE_ALL = 1 # Filter with AND mode (all tags need to match).',
        services=LISTED)
def tags_all(t: Target) -> None:
    """Tag a red and big, b red: ALL [red, big] gives a; ALL [red] gives a and b."""
    a, b = _tagged(t)
    all_mode = t.msg.TagsFilter.FILTER_MODE_ALL
    _expect_set(_picked(t, t.entities.filters(tags=[RED, BIG], mode=all_mode), 'GetEntities'), {a},
                f'ALL [{RED}, {BIG}]')
    _expect_set(_picked(t, t.entities.filters(tags=[RED], mode=all_mode), 'GetEntities'), {a, b},
                f'ALL [{RED}]')


@clause(CLAUSES, 'FILTER-12', 'the name filter applies together with a tags filter (AND)', TAGS,
        'EntityFilters.msg',
        'string filter # ... Applies together with other filters (categories, tags).',
        services=LISTED)
def filters_and(t: Target) -> None:
    """
    Tag boxes a and b red, not c; the name filter ^(a|c)$ with ANY [red] gives a alone.

    The filters the sentence names, so that neither may be ignored: the name
    filter alone gives a and c, the tags alone a and b.
    """
    a, b, c = t.entities.spawn(0), t.entities.spawn(1), t.entities.spawn(2)
    _tag(t, ((a, [RED]), (b, [RED])))
    filters = t.entities.filters(f'^({a}|{c})$', tags=[RED],
                                 mode=t.msg.TagsFilter.FILTER_MODE_ANY)
    _expect_set(_picked(t, filters, 'GetEntities'), {a}, f'the name filter ^({a}|{c})$ with ANY '
                f'[{RED}]')
