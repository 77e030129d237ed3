"""
The worlds that can be loaded, as GetAvailableWorlds lists them.

No ROS. :func:`list_worlds` scans the default sources (this package's
``urdf/`` and the ``world_paths``) and a request's ``additional_sources``
for world manifests (``*.world.yaml``) and SDF files that hold a
``<world>``, each read and checked, and filters them by tags; which sources
may be searched is :class:`~r2d2_sim.sim.worlds.places.Places`' answer.
Refusals are :class:`~r2d2_sim.errors.RefusedError` with GetAvailableWorlds'
codes.
"""

import os
from typing import List, NamedTuple, Sequence, Tuple

from r2d2_sim.errors import RefusedError
from r2d2_sim.physics.description import PACKAGE_SCHEME
from r2d2_sim.sim.worlds.sdf_format import sdf_world_entry
from r2d2_sim.sim.tags import TagsFilter, tags_match
from r2d2_sim.sim.worlds.manifest import load_yaml, MAX_WORLD_BYTES, read_manifest
from r2d2_sim.sim.worlds.places import (
    FILE_SCHEME, file_stem, is_remote, PACKAGE_WORLDS, Places, read_text, SDF_SUFFIXES,
    WORLD_SUFFIX)

__all__ = ['WorldEntry', 'list_worlds', 'MAX_WORLDS_PER_SOURCE']

MAX_WORLDS_PER_SOURCE = 1000


class WorldEntry(NamedTuple):
    """A world GetAvailableWorlds lists: its name, the URI that loads it, description, tags."""

    name: str
    uri: str
    description: str
    tags: Tuple[str, ...]


def _scan(places: Places, source: str) -> List[WorldEntry]:
    """
    Return the worlds of one source: its ``*.world.yaml`` files, read and checked.

    Its ``*.sdf`` and ``*.world`` files too, those that hold a ``<world>``
    (model files are left out): named by the world, tagged ``sdf``.
    """
    directory = places.directory(source)[0]
    try:
        names = sorted(n for n in os.listdir(directory)
                       if n.endswith(WORLD_SUFFIX) or n.lower().endswith(SDF_SUFFIXES))
    except OSError:
        raise RefusedError('NOT_FOUND', f'{source[:200]} cannot be listed') from None
    prefix = source.rstrip('/') if source.startswith(PACKAGE_SCHEME) else \
        FILE_SCHEME + directory
    entries = []
    for name in names[:MAX_WORLDS_PER_SOURCE]:
        shown = f'{source[:200].rstrip("/")}/{name}'
        path = os.path.join(directory, name)
        if not os.path.isfile(path):
            continue
        try:
            text = read_text(path, shown, 'NOT_FOUND', MAX_WORLD_BYTES)
            if not name.endswith(WORLD_SUFFIX):
                world = sdf_world_entry(text, shown)
                if world is not None:
                    entries.append(WorldEntry(world or file_stem(name), f'{prefix}/{name}',
                                              'SDF world', ('sdf',)))
                continue
            manifest = read_manifest(load_yaml(text), file_stem(name))
        except RefusedError as exc:
            raise RefusedError(exc.code, f'{shown}: {exc.message}') from None
        entries.append(WorldEntry(manifest.name, f'{prefix}/{name}', manifest.description,
                                  manifest.tags))
    return entries


def list_worlds(places: Places, additional_sources: Sequence[str] = (),
                tags: TagsFilter = TagsFilter(), offline_only: bool = False,
                continue_on_error: bool = False) -> Tuple[List[WorldEntry], str]:
    """
    Return GetAvailableWorlds' worlds (tags filtered) and a note of what was left out.

    The default sources are this package's ``urdf/`` and the ``world_paths``;
    ``additional_sources`` are directories (paths, ``file://``,
    ``package://``) within the places a request may load from. Every source
    is local, so ``offline_only`` only leaves out remote sources, which are
    never searched. A source that fails fails the call, with
    DEFAULT_SOURCES_FAILED for a default one, NOT_FOUND (or
    FEATURE_UNSUPPORTED, remote) for an additional one; with
    ``continue_on_error`` it is left out instead (named in the note), and the
    call fails only when no source yielded any world. A world file that does
    not read fails its source (OPERATION_FAILED for an additional one).
    """
    sources = [(PACKAGE_WORLDS, True)] + [(s, True) for s in places.world_paths] + \
        [(s, False) for s in additional_sources]
    worlds: List[WorldEntry] = []
    failures: List[Tuple[bool, RefusedError]] = []
    skipped = []
    yielded = False
    for source, default in sources:
        try:
            if is_remote(source):
                if offline_only:
                    skipped.append(source[:200])
                    continue
                raise RefusedError('FEATURE_UNSUPPORTED', f'{source[:200]}: remote sources are '
                                                          'not searched, only local directories')
            if not default and not places.allowed(*places.directory(source)):
                raise RefusedError('NOT_FOUND', f'{source[:200]} lies outside the places worlds '
                                                'are loaded from')
            found = _scan(places, source)
        except RefusedError as exc:
            if default:
                exc = RefusedError('DEFAULT_SOURCES_FAILED', exc.message)
            elif exc.code not in ('NOT_FOUND', 'FEATURE_UNSUPPORTED'):
                exc = RefusedError('OPERATION_FAILED', exc.message)  # a world file in it
            if not continue_on_error:
                raise exc from None
            failures.append((default, exc))
            continue
        yielded = yielded or bool(found)
        worlds += [world for world in found if tags_match(world.tags, tags)]
    if failures and not yielded:
        default, first = next((f for f in failures if f[0]), failures[0])
        raise RefusedError(first.code, '; '.join(f.message for _, f in failures))
    notes = [f'left out: {exc.message}' for _, exc in failures]
    if skipped:
        notes.append(f'remote sources not searched (offline_only): {", ".join(skipped)}')
    return worlds, '; '.join(notes)
