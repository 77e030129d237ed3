"""
Where world files are: the places a request may load from, a URI resolved, a file read.

No ROS. :class:`Places` is the one answer to "where may this come from":
this package's ``urdf/``, the directories of the ``world_paths`` parameter,
pybullet_data, and any ROS package's share directory through ``package://``;
a relative name is looked for beside the world file first. Reading a world
(:func:`~r2d2_sim.sim.worlds.read_world`) and listing the worlds
(:func:`~r2d2_sim.sim.worlds.listing.list_worlds`) both ask it, and both read
files through :func:`read_text` (a regular file, bounded, UTF-8) and name
worlds by :func:`file_stem`. Refusals are
:class:`~r2d2_sim.errors.RefusedError` with LoadWorld's codes.
"""

import os
import re
from typing import List, Optional, Sequence, Tuple

import pybullet_data

from r2d2_sim.errors import RefusedError
from r2d2_sim.physics.description import (
    DescriptionError, PACKAGE_NAME, PACKAGE_SCHEME, package_share_directory, SOURCE_TREE)
from r2d2_sim.sim.sdf.elements import read_limited as read_text  # one reader for both

__all__ = ['Places', 'read_text', 'file_stem', 'PACKAGE_WORLDS', 'WORLD_SUFFIX',
           'SDF_SUFFIXES', 'FILE_SCHEME', 'is_remote']

PACKAGE_WORLDS = f'{PACKAGE_SCHEME}{PACKAGE_NAME}/urdf'
WORLD_SUFFIX = '.world.yaml'
SDF_SUFFIXES = ('.sdf', '.world')
FILE_SCHEME = 'file://'
_SCHEME = re.compile(r'[A-Za-z][A-Za-z0-9+.-]*://')


def file_stem(path: str) -> str:
    """Return a world file's name without its suffix: what a world is called by default."""
    name = os.path.basename(path)
    for suffix in (WORLD_SUFFIX, '.yaml', '.yml', '.urdf') + SDF_SUFFIXES:
        if name.endswith(suffix):
            return name[:-len(suffix)] or name
    return name


def _inside(path: str, root: str) -> bool:
    return path == root or path.startswith(root.rstrip(os.sep) + os.sep)


class Places:
    """
    Where worlds and their models come from, and where a request may load them from.

    ``world_paths`` are the directories the operator listed (paths,
    ``file://`` or ``package://`` URIs). A world or model URI is a path (a
    relative one is looked for beside the world file, then in this package's
    ``urdf/``, the ``world_paths`` and pybullet_data), a ``file://`` URI or a
    ``package://`` URI.
    """

    def __init__(self, world_paths: Sequence[str] = ()) -> None:
        self.world_paths = tuple(world_paths)

    def package_directory(self) -> Optional[str]:
        """Return this package's ``urdf/`` (installed, else beside the sources); None if lost."""
        try:
            directory = os.path.join(package_share_directory(PACKAGE_NAME), 'urdf')
        except DescriptionError:
            directory = os.path.join(SOURCE_TREE, 'urdf')
        return directory if os.path.isdir(directory) else None

    def directory(self, source: str) -> Tuple[str, Optional[str]]:
        """
        Return (directory, package share or None) of a source: a path, file:// or package://.

        NOT_FOUND when it is not a directory, or leaves its package.
        """
        share = None
        if source.startswith(PACKAGE_SCHEME):
            package, _, relative = source[len(PACKAGE_SCHEME):].partition('/')
            try:
                share = os.path.realpath(package_share_directory(package))
            except DescriptionError:
                raise RefusedError('NOT_FOUND', f'{source[:200]}: no ROS package '
                                                f'{package[:100]!r}') from None
            path = os.path.join(share, relative)
            if not _inside(os.path.realpath(path), share):
                raise RefusedError('NOT_FOUND', f'{source[:200]} leaves its package')
        else:
            path = source[len(FILE_SCHEME):] if source.startswith(FILE_SCHEME) else source
        if not os.path.isdir(path):
            raise RefusedError('NOT_FOUND', f'{source[:200]} is not a directory')
        return os.path.abspath(path), share

    def roots(self) -> List[str]:
        """Return the real paths of the directories a request may load worlds from."""
        roots = [os.path.realpath(pybullet_data.getDataPath())]
        own = self.package_directory()
        for directory in (own, os.path.join(SOURCE_TREE, 'urdf')):
            if directory is not None and os.path.isdir(directory):
                roots.append(os.path.realpath(directory))
        for source in self.world_paths:
            try:
                roots.append(os.path.realpath(self.directory(source)[0]))
            except RefusedError:
                pass  # GetAvailableWorlds reports it
        return roots

    def search(self) -> List[str]:
        """Return where a relative name is looked for: ``urdf/``, world_paths, pybullet_data."""
        found = [d for d in [self.package_directory()] if d is not None]
        for source in self.world_paths:
            try:
                found.append(self.directory(source)[0])
            except RefusedError:
                pass
        return found + [pybullet_data.getDataPath()]

    def resolve(self, uri: str, base_dir: Optional[str] = None) -> Tuple[str, Optional[str]]:
        """
        Return (path, root) for a URI; root is the directory it may not leave, or None.

        A ``package://`` URI may not leave its package; a relative path is
        looked for beside the world file (``base_dir``), then in the working
        directory (the operator's ``world`` only makes use of it), then in
        :meth:`search`'s places. NOT_FOUND for a remote URI, a missing package, or
        a NUL byte (no path holds one: Python's path functions raised ValueError).
        """
        if '\0' in uri:
            raise RefusedError('NOT_FOUND', f'{uri[:200]!r}: no such file (a path cannot hold '
                                            'a NUL byte)')
        if uri.startswith(PACKAGE_SCHEME):
            package, _, relative = uri[len(PACKAGE_SCHEME):].partition('/')
            if not package or not relative:
                raise RefusedError('NOT_FOUND', f'malformed package URI {uri[:200]!r}: expected '
                                                'package://pkg/path')
            try:
                share = package_share_directory(package)
            except DescriptionError:
                raise RefusedError('NOT_FOUND', f'{uri[:200]}: no ROS package '
                                                f'{package[:100]!r}') from None
            return os.path.join(share, relative), os.path.realpath(share)
        if uri.startswith(FILE_SCHEME):
            return uri[len(FILE_SCHEME):], None
        if _SCHEME.match(uri):
            raise RefusedError('NOT_FOUND', f'{uri[:200]}: only local files are loaded (paths, '
                                            'file:// and package:// URIs)')
        if os.path.isabs(uri):
            return uri, None
        if base_dir is not None and os.path.exists(os.path.join(base_dir, uri)):
            return os.path.join(base_dir, uri), None
        if base_dir is None and os.path.isfile(uri):
            return os.path.abspath(uri), None
        search = self.search()
        for directory in search:
            candidate = os.path.join(directory, uri)
            if os.path.isfile(candidate):
                return candidate, None
        # Nowhere: a name in the first place looked at, which says it is missing.
        return os.path.join(base_dir or search[0], uri), None

    def allowed(self, path: str, *anchors: Optional[str]) -> bool:
        """Return True when ``path`` (links followed) lies in an allowed place or an anchor."""
        real = os.path.realpath(path)
        return any(_inside(real, root) for root in self.roots() + [a for a in anchors if a])


def is_remote(source: str) -> bool:
    """Return True for a URI of a remote place (any scheme but file:// and package://)."""
    return bool(_SCHEME.match(source)) and not source.startswith((FILE_SCHEME, PACKAGE_SCHEME))
