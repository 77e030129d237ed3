"""
SDF as one of the world formats of :mod:`r2d2_sim.sim.worlds`: a Gazebo world, or a model in one.

No ROS, no PyBullet. :func:`read_sdf_world` is the SDF
:class:`~r2d2_sim.sim.worlds.WorldFormat`'s reader: the file and its
includes read (:mod:`r2d2_sim.sim.sdf`), one summary line of what is not
simulated (refused as UNSUPPORTED_ELEMENTS with
``fail_on_unsupported_element``), every body written as URDF, and the
world's models and named poses as the other formats give them. Named poses
are the world's own ``<frame>`` elements (``<world><frame name="goal">``),
in the world frame; a frame named ``start`` is the start pose the start-up
robots stand at. :func:`read_sdf_model` and :func:`sdf_models` give a world
manifest's models from an SDF file (read, then built: the whole world's
meshes are counted between the two); :func:`sdf_world_entry` is what
GetAvailableWorlds lists of one.
"""

import os
from typing import List, Optional, Protocol, Tuple

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.transforms import compose, Transform
from r2d2_sim.sim.names import is_name
from r2d2_sim.sim.sdf.bodies import entity_name
from r2d2_sim.sim.sdf.elements import local_tag, parse_xml, read_limited
from r2d2_sim.sim.sdf.loading import (
    build_bodies, read_sdf, SdfBuilt, SdfRead, SdfSettings, summary_line, TriangleBudget)
from r2d2_sim.sim.sdf.mesh_cache import MeshCache
from r2d2_sim.sim.sdf.reader import MAX_SDF_BYTES
from r2d2_sim.sim.sdf.resources import Resources
from r2d2_sim.sim.spawnables import Closable
from r2d2_sim.sim.worlds.manifest import check_world_pose, ModelEntry
from r2d2_sim.sim.worlds.places import Places
from r2d2_sim.sim.worlds.world import NamedPose, World, WorldModel

__all__ = ['read_sdf_world', 'read_sdf_model', 'sdf_models', 'sdf_world_entry', 'START_FRAME']

START_FRAME = 'start'
SDF_TAG = 'sdf'


class ReadingOptions(Protocol):
    """What a LoadWorld request asks of the reading (:class:`~.reading.LoadOptions`)."""

    @property
    def fail_on_unsupported_element(self) -> bool:
        """Refuse a world with an element that is not simulated."""

    @property
    def ignore_missing_or_unsupported_assets(self) -> bool:
        """Leave out (noted) a model or mesh that cannot be had."""


class WorldReading(Protocol):
    """What reading an SDF file asks of one world's reading (:mod:`~.reading`)."""

    trusted: bool                  # anything may be read (the operator's start-up world)
    places: Places                 # where else files may come from
    sdf: SdfSettings               # model paths; what a world is compared with
    triangles: TriangleBudget      # the world's mesh triangles, all its files together
    resources: List[Closable]      # the generated files to close with the world
    notes: List[str]               # the lines the world's description gets

    @property
    def options(self) -> ReadingOptions:
        """Return the request's options."""

    def not_simulated(self, line: str) -> None:
        """Note a summary of what is not simulated, or refuse it (a strict request)."""


def _resources(reading: WorldReading, anchor: Optional[str], path: Optional[str]) -> Resources:
    """Return where the world's files may come from: anywhere if trusted, else allowed places."""
    if reading.trusted:
        return Resources(reading.sdf.model_paths)
    roots = reading.places.roots() + [a for a in (anchor,) if a]
    return Resources(reading.sdf.model_paths, roots)


def _read(text: str, path: Optional[str], shown: str, reading: WorldReading, anchor: Optional[str]
          ) -> SdfRead:
    """
    Read an SDF file for a world, no mesh converted; refuse what is not simulated if strict.

    ``shown`` names the file in messages ('': read_world names it in front of them).
    """
    settings, options = reading.sdf, reading.options
    read = read_sdf(text, path, shown, _resources(reading, anchor, path),
                    settings.read_options(options.ignore_missing_or_unsupported_assets),
                    settings.ground_plane)
    if read.summary and options.fail_on_unsupported_element:
        reading.not_simulated(read.summary)  # refused before any mesh is converted
    return read


def _build(read: SdfRead, shown: str, reading: WorldReading, named: bool = False
           ) -> Tuple[SdfBuilt, str]:
    """
    Build a read SDF file's bodies for a world; return its summary line, noted (or refused).

    ``named``: the summary line names the file (one of a manifest's models).
    """
    ignore = reading.options.ignore_missing_or_unsupported_assets
    built = build_bodies(read.scene, MeshCache(), ignore, budget=reading.triangles)
    reading.resources.append(built.files)
    counts = dict(read.scene.not_simulated)
    for what, count in built.not_simulated:
        counts[what] = counts.get(what, 0) + count
    line = summary_line(counts.items())
    if line:
        reading.not_simulated(f'{shown}: {line}' if named else line)
    reading.notes += [f'left out: {m}' for m in read.scene.left_out + built.left_out]
    return built, line


def _models(built: SdfBuilt, source: str, entry: Optional[ModelEntry] = None
            ) -> List[WorldModel]:
    models = []
    for body in built.bodies:
        pose = body.pose
        name = body.name
        if entry is not None:  # a manifest's model: its pose, name and tags over the file's
            pose = compose(Transform(entry.position, entry.orientation), pose)
            if entry.name is not None:
                name = entry.name + body.name[len(entity_name(body.model)):]
        models.append(WorldModel(
            name, body.path, source, pose.translation, pose.rotation,
            (entry.description if entry is not None and entry.description else
             f'{body.model} from {source}'), entry.tags if entry is not None else (),
            sdf=True, static=body.static))
    return models


def read_sdf_world(text: str, path: Optional[str], uri: str, reading: WorldReading,
                   anchor: Optional[str]) -> World:
    """Return an SDF file as a World: its models as bodies, its frames as named poses."""
    shown = '' if uri else 'the resource_string'  # read_world puts a file's name in front
    read = _read(text, path, shown, reading, anchor)
    built, summary = _build(read, shown, reading)
    at = f'{shown}: ' if shown else ''
    poses = []
    for frame in read.scene.frames:
        name = entity_name(frame.name)
        if not is_name(name):
            raise RefusedError('RESOURCE_PARSE_ERROR', f'{at}frame {frame.name[:100]!r} '
                                                       'cannot name a named pose')
        orientation = check_world_pose(frame.pose.translation, frame.pose.rotation,
                                       f'{at}frame {name}')
        poses.append(NamedPose(name, 'a <frame> of the SDF world', ('frame',),
                               frame.pose.translation, orientation))
    if len({p.name for p in poses}) != len(poses):
        raise RefusedError('RESOURCE_PARSE_ERROR', f'{at}two frames have one name')
    models = _models(built, uri or 'resource_string')
    name = read.scene.world or (os.path.splitext(os.path.basename(path))[0] if path else 'world')
    description = [f'SDF world {name[:100]}: {len(models)} bodies, {built.triangles} mesh '
                   'triangles']
    if read.merged_ground:
        description.append('its ground plane is r2d2_sim\'s')
    if summary:
        description.append(summary)
    start = next((p for p in poses if p.name == START_FRAME), None)
    return World(name[:255], uri, '' if uri else text, '; '.join(description)[:4000],
                 (SDF_TAG,), tuple(models), tuple(poses), start)


def read_sdf_model(entry: ModelEntry, path: str, reading: WorldReading, anchor: Optional[str]
                   ) -> SdfRead:
    """Return a manifest's model that is an SDF file, read and checked, no mesh converted."""
    shown = f'model {entry.uri[:200]}'
    return _read(read_limited(path, shown, 'MISSING_ASSETS', MAX_SDF_BYTES), path, shown,
                 reading, anchor)


def sdf_models(entry: ModelEntry, read: SdfRead, reading: WorldReading) -> List[WorldModel]:
    """
    Return a manifest's model that is an SDF file (:func:`read_sdf_model`): its bodies.

    At the entry's pose, its meshes converted. The entry's name replaces the
    model's (its other bodies keep their ``__`` suffixes); a file of several
    models takes no name.
    """
    shown = f'model {entry.uri[:200]}'
    built, _ = _build(read, shown, reading, named=True)
    if entry.name is not None and len({body.model for body in built.bodies}) > 1:
        raise RefusedError('RESOURCE_PARSE_ERROR', f'{shown} holds several models: the entry '
                                                   'cannot give them one name')
    return _models(built, entry.uri, entry)


def sdf_world_entry(text: str, shown: str) -> Optional[str]:
    """Return the name of the world an SDF file holds (None: not an SDF world, a model file)."""
    root = parse_xml(text, shown)
    if local_tag(root) != 'sdf':
        return None
    worlds = [child for child in root if local_tag(child) == 'world']
    return (worlds[0].get('name') or '') if worlds else None
