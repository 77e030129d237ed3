"""
The names the standard gives things in a world: entities, a world's models, its named poses.

One rule for all of them, so that a world's model becomes an entity under the
name its file gives it and a named pose can be a request's frame: a letter or
``_`` first, then letters, digits, ``_`` and ``-``, at most
:data:`MAX_NAME_LENGTH` characters. An entity named after its URDF's robot name
(a start-up one, a world's model with no name, a spawn allowed to be renamed)
takes it made valid (:func:`entity_name`). No imports but ``re``: listing or
reading a world does not load the spawn path.
"""

import re

__all__ = ['NAME', 'MAX_NAME_LENGTH', 'is_name', 'entity_name']

MAX_NAME_LENGTH = 255
NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_\-]*\Z')


def is_name(text: str) -> bool:
    """Return True when ``text`` is a valid name: the pattern, at most MAX_NAME_LENGTH long."""
    return len(text) <= MAX_NAME_LENGTH and NAME.match(text) is not None


def entity_name(text: str) -> str:
    """
    Return ``text`` made a valid entity name: ``text`` itself when it is one.

    A name too long is cut, with room left for a ``_N`` suffix; every other
    character is replaced by ``_``; one that does not start with a letter or
    ``_`` gets ``entity_`` in front (``entity`` for an empty one).
    """
    if len(text) > MAX_NAME_LENGTH:
        text = text[:MAX_NAME_LENGTH - 8]  # room for a _N suffix
    if NAME.match(text) is None:
        text = re.sub(r'[^A-Za-z0-9_\-]', '_', text) or 'entity'
        if not text[0].isalpha() and text[0] != '_':
            text = 'entity_' + text
    return text
