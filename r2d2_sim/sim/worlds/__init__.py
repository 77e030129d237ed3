"""
Worlds: what one is, where they come from, reading one, listing them, and the one loaded.

No ROS. The modules, each one idea:

- :mod:`.world`: what a world is, as read: :class:`World`, :class:`WorldModel`,
  :class:`NamedPose` (plain data);
- :mod:`.places`: where a request may load from, a URI resolved, a file read;
- :mod:`.reading`: :func:`read_world`, one function for every format (URDF, the
  manifest, SDF) with LoadWorld's :class:`LoadOptions`;
- :mod:`.manifest`: r2d2_sim's ``*.world.yaml`` format;
- :mod:`.sdf_format`: SDF as a world format (the reader itself is :mod:`r2d2_sim.sim.sdf`);
- :mod:`.listing`: :func:`list_worlds`, what GetAvailableWorlds lists;
- :mod:`.files`: :class:`WorldFiles`, the world loaded now and the questions about it.

This face exports the names callers use; the modules import each other, never it.
"""

from r2d2_sim.sim.sdf.loading import SdfSettings
from r2d2_sim.sim.worlds.files import WorldFiles
from r2d2_sim.sim.worlds.listing import list_worlds, MAX_WORLDS_PER_SOURCE, WorldEntry
from r2d2_sim.sim.worlds.places import PACKAGE_WORLDS, Places, SDF_SUFFIXES, WORLD_SUFFIX
from r2d2_sim.sim.worlds.reading import (
    EMPTY_WORLD_URI, empty_world, FORMATS, LoadOptions, read_world, WorldFormat)
from r2d2_sim.sim.worlds.world import NamedPose, World, WorldModel

__all__ = ['World', 'WorldModel', 'WorldEntry', 'NamedPose', 'LoadOptions', 'Places',
           'SdfSettings', 'WorldFormat', 'FORMATS', 'read_world', 'list_worlds', 'empty_world',
           'WorldFiles', 'PACKAGE_WORLDS', 'EMPTY_WORLD_URI', 'WORLD_SUFFIX', 'SDF_SUFFIXES',
           'MAX_WORLDS_PER_SOURCE']
