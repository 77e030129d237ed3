"""
Tags, as the simulation standard uses them: on entities, named poses and worlds, and in filters.

No ROS here. Tags come from any peer on the ROS domain (SetEntityInfo, a
filter, a world file), and every entity's tags are matched against every
filter a peer sends, so a list of tags is bounded: at most MAX_TAGS, each
a non-empty line of at most MAX_TAG_LENGTH characters. Refusals are
:class:`~r2d2_sim.errors.RefusedError` with the code the caller names.
"""

from typing import Iterable, NamedTuple, Sequence, Tuple

from r2d2_sim.errors import RefusedError

__all__ = ['MAX_TAGS', 'MAX_TAG_LENGTH', 'MAX_DESCRIPTION_LENGTH', 'FILTER_MODE_ANY',
           'FILTER_MODE_ALL', 'TagsFilter', 'check_tags', 'check_description_text',
           'check_filter', 'tags_match']

MAX_TAGS = 64
MAX_TAG_LENGTH = 255
# A human-readable description of an entity, a named pose or a world.
MAX_DESCRIPTION_LENGTH = 10_000
# simulation_interfaces/TagsFilter's modes.
FILTER_MODE_ANY = 0
FILTER_MODE_ALL = 1


class TagsFilter(NamedTuple):
    """The standard's tags filter: no tags matches everything; else ANY or ALL of them."""

    tags: Tuple[str, ...] = ()
    mode: int = FILTER_MODE_ANY


def check_tags(tags: Iterable[str], what: str, code: str = 'OPERATION_FAILED') -> Tuple[str, ...]:
    """
    Return ``tags`` as a tuple without repeats, in order; RefusedError ``code`` if out of bounds.

    ``what`` names the list in the message (``the entity's tags``,
    ``named_poses[2].tags``). A tag is a non-empty string of at most
    MAX_TAG_LENGTH characters with no control characters; a list holds at
    most MAX_TAGS.
    """
    tags = list(tags)
    if len(tags) > MAX_TAGS:
        raise RefusedError(code, f'{what}: {len(tags)} tags, more than {MAX_TAGS}')
    kept = []
    for i, tag in enumerate(tags):
        if not isinstance(tag, str) or not tag:
            raise RefusedError(code, f'{what}[{i}]: a tag is a non-empty string')
        if len(tag) > MAX_TAG_LENGTH:
            raise RefusedError(code, f'{what}[{i}]: a tag is at most {MAX_TAG_LENGTH} '
                                     f'characters, not {len(tag)}')
        if any(ord(c) < 32 or ord(c) == 127 for c in tag):
            raise RefusedError(code, f'{what}[{i}]: a tag has no control characters')
        if tag not in kept:
            kept.append(tag)
    return tuple(kept)


def check_description_text(text: str, what: str, code: str = 'OPERATION_FAILED') -> str:
    """Return ``text`` if it is a description of at most MAX_DESCRIPTION_LENGTH characters."""
    if not isinstance(text, str):
        raise RefusedError(code, f'{what}: a description is a string')
    if len(text) > MAX_DESCRIPTION_LENGTH:
        raise RefusedError(code, f'{what}: a description is at most {MAX_DESCRIPTION_LENGTH} '
                                 f'characters, not {len(text)}')
    return text


def check_filter(tags: Sequence[str], mode: int) -> TagsFilter:
    """
    Return a request's tags filter, checked: bounded tags, mode ANY (0) or ALL (1).

    No tags is no filter, whatever the mode says.
    """
    if not tags:
        return TagsFilter()
    if mode not in (FILTER_MODE_ANY, FILTER_MODE_ALL):
        raise RefusedError('OPERATION_FAILED', f'unknown tags filter_mode {mode}: 0 (any) or '
                                               '1 (all)')
    return TagsFilter(check_tags(tags, 'the tags filter'), mode)


def tags_match(have: Sequence[str], wanted: TagsFilter) -> bool:
    """Return True when tags ``have`` pass the filter: any or all of its tags, or it has none."""
    if not wanted.tags:
        return True
    if wanted.mode == FILTER_MODE_ALL:
        return all(tag in have for tag in wanted.tags)
    return any(tag in have for tag in wanted.tags)
