"""
The names the standard gives things in a world: entities, a world's models, its named poses.

One rule for all of them, so that a world's model becomes an entity under the
name its file gives it and a named pose can be a request's frame: a letter or
``_`` first, then letters, digits, ``_`` and ``-``, at most
:data:`MAX_NAME_LENGTH` characters. No imports: listing or reading a world
does not load the spawn path.
"""

import re

__all__ = ['NAME', 'MAX_NAME_LENGTH', 'is_name']

MAX_NAME_LENGTH = 255
NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_\-]*\Z')


def is_name(text: str) -> bool:
    """Return True when ``text`` is a valid name: the pattern, at most MAX_NAME_LENGTH long."""
    return len(text) <= MAX_NAME_LENGTH and NAME.match(text) is not None
