"""
An SDF model as a spawn request brings it: by ``uri`` or as ``resource_string``, one body.

No ROS, no PyBullet. SpawnEntity's ``uri`` may be an ``.sdf`` file, a
``model://`` URI or a Fuel URL (from the local cache); its
``resource_string`` may be SDF text (``<sdf>`` root). The model is read as a
world's would be (includes, nested models, meshes, the same bounds), then
must be one body: an entity is one body, so a model whose links no joint
joins is refused, as is a file of several models or a world. Its own
``<pose>`` gives way to the request's. The model's file must lie where a
LoadWorld's may (the search paths, the Fuel cache, the places worlds load
from, ROS packages: ``SdfSettings.places``); its other files come from
there too and from the model's own directory.
"""

import os
from typing import NamedTuple

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.transforms import Transform
from r2d2_sim.sim.sdf.elements import read_limited, root_tag
from r2d2_sim.sim.sdf.loading import (
    build_bodies, GeneratedFiles, read_sdf, SdfSettings, summary_line)
from r2d2_sim.sim.sdf.mesh_cache import MeshCache
from r2d2_sim.sim.sdf.reader import MAX_SDF_BYTES
from r2d2_sim.sim.sdf.resources import FILE_SCHEME, Resources

__all__ = ['SdfSpawnable', 'is_sdf_spawn', 'read_sdf_spawnable']


class SdfSpawnable(NamedTuple):
    """A model to spawn: its URDF (file and text), name, base pose in its frame, notes."""

    path: str
    files: GeneratedFiles
    name: str
    text: str
    base: Transform
    notes: str


def is_sdf_spawn(uri: str, resource_string: str) -> bool:
    """
    Return True when a spawn request names SDF.

    That is a .sdf file, a Gazebo model directory (one holding ``model.config``
    or ``model.sdf``, as a path or ``file://``), model://, Fuel, or <sdf> text.
    """
    if uri:
        if uri.lower().endswith('.sdf') or uri.startswith('model://') or \
                uri.startswith(('https://fuel.', 'http://fuel.')):
            return True
        directory = uri[len(FILE_SCHEME):] if uri.startswith(FILE_SCHEME) else uri
        return any(os.path.isfile(os.path.join(directory, name))
                   for name in ('model.config', 'model.sdf'))
    return root_tag(resource_string) == 'sdf'


def read_sdf_spawnable(uri: str, resource_string: str, settings: SdfSettings
                       ) -> SdfSpawnable:
    """
    Return the spawnable body of an SDF model; RefusedError with SpawnEntity's codes.

    NOT_FOUND for no such file; UNSUPPORTED_FORMAT for a world, several
    models or not SDF; RESOURCE_PARSE_ERROR, MISSING_ASSETS and
    UNSUPPORTED_ASSETS as for a world; UNSUPPORTED_ASSETS too for a model of
    several bodies, or with anything not simulated when ``settings.strict``.
    """
    shown = uri[:200] if uri else 'the resource_string'
    resources = Resources(settings.model_paths, roots=list(settings.places))
    path = None
    if uri:
        try:  # found, and checked to lie in an allowed place, as LoadWorld's files are
            source = resources.model(uri, os.getcwd(), None)
        except RefusedError as exc:  # outside too: NOT_FOUND, as LoadWorld answers
            raise RefusedError('NOT_FOUND', exc.message) from None
        if source.path is None:  # a built-in model (the ground plane, the sun)
            text = source.text or ''
        else:
            path = source.path
            text = read_limited(path, shown, 'NOT_FOUND', MAX_SDF_BYTES)
            resources.allow(os.path.dirname(path))
    else:
        text = resource_string
    read = read_sdf(text, path, shown, resources, settings.read_options(), False)
    scene = read.scene
    if scene.world or len(scene.models) != 1:
        raise RefusedError('UNSUPPORTED_FORMAT', f'{shown} holds '
                           f'{"a world" if scene.world else f"{len(scene.models)} models"}: a '
                           'spawn is one model (LoadWorld loads worlds)')
    if settings.strict and read.summary:
        raise RefusedError('UNSUPPORTED_ASSETS', f'{shown}: {read.summary} (strict_worlds)')
    built = build_bodies(scene, MeshCache(), relative=True)
    if len(built.bodies) != 1:
        built.files.close()
        raise RefusedError('UNSUPPORTED_ASSETS', f'{shown}: the model\'s links make '
                                                 f'{len(built.bodies)} bodies that no joint '
                                                 'joins; an entity is one body')
    body = built.bodies[0]
    notes = [line for line in (read.summary,) if line] + list(scene.left_out)
    if built.not_simulated:
        notes.append(summary_line(built.not_simulated))
    if settings.strict and built.not_simulated:
        built.files.close()
        raise RefusedError('UNSUPPORTED_ASSETS', f'{shown}: {notes[-1]} (strict_worlds)')
    return SdfSpawnable(body.path, built.files, body.name, body.text, body.pose,
                        '; '.join(notes))
