"""
An SDF world or model, read and turned into URDF files PyBullet loads: the steps in order.

No ROS, no PyBullet. :func:`read_sdf` reads the file and its includes
(:mod:`.reader`) and says in one line what is not simulated, before anything
costly happens, so a strict load refuses early; :func:`build_bodies` then
plans each model's bodies (:mod:`.bodies`), converts their meshes once
(:mod:`.mesh_cache`) and writes one URDF per distinct body into a temporary
directory (:class:`GeneratedFiles`) that lives as long as the world or the
entity does. A world whose ground plane is a plane at z = 0 has it merged into
r2d2_sim's own (``ground_plane``), rather than two planes in one place.
"""

import hashlib
import os
import shutil
import tempfile
from typing import Dict, Iterable, List, NamedTuple, Optional, Tuple

from r2d2_sim.errors import RefusedError
from r2d2_sim.model.transforms import compose, rotate, Transform
from r2d2_sim.sim.sdf.bodies import plan_bodies
from r2d2_sim.sim.sdf.description import Geometry, Model, Scene
from r2d2_sim.sim.sdf.elements import Place
from r2d2_sim.sim.sdf.mesh_cache import Converted, MeshCache
from r2d2_sim.sim.sdf.meshes import check_triangles, declared_triangles, read_mesh_bytes
from r2d2_sim.sim.sdf.reader import Reader, ReadOptions
from r2d2_sim.sim.sdf.resources import Resources
from r2d2_sim.sim.sdf.urdf import urdf_text

__all__ = ['GeneratedFiles', 'SdfSettings', 'SdfBody', 'SdfRead', 'SdfBuilt', 'read_sdf',
           'build_bodies', 'scene_meshes', 'summary_line', 'is_ground_plane', 'TriangleBudget',
           'MAX_WORLD_TRIANGLES']

# Triangles of all the meshes of one world, each use counted (a concave mesh's
# bounding-volume tree is built per use): some 10 s of a cold load on our 2 cores,
# going by the warehouse's 0.4 s for 153,000 (bench/sdf_world.py).
MAX_WORLD_TRIANGLES = 4_000_000


class TriangleBudget:
    """
    The mesh triangles one world or one spawn may load, each use of a mesh counted.

    Checked twice: :meth:`expect` before any mesh is converted, from what the
    files say they hold (an over-budget world is refused in the time it takes
    to read its files, not to convert them: 20 s for one a user met), then
    :meth:`take` as each mesh converts, with the count converted. For an SDF
    world's meshes (:func:`build_bodies`) and a URDF's, which PyBullet loads
    itself.
    """

    def __init__(self, limit: Optional[int] = None) -> None:
        self.limit = MAX_WORLD_TRIANGLES if limit is None else limit
        self.left = self.limit

    def _refused(self, shown: str) -> RefusedError:
        return RefusedError('UNSUPPORTED_ASSETS', f'{shown + ": " if shown else ""}the meshes '
                                                  f'have more than {self.limit} triangles in all')

    def expect(self, meshes: Iterable[str], shown: str) -> None:
        """
        Refuse (UNSUPPORTED_ASSETS) when these meshes say they hold more triangles than are left.

        ``meshes``: a mesh file's path for every use of it. Each file's count
        is :func:`~.meshes.declared_triangles`; a file that cannot be read, or
        holds more than a mesh may, counts 0 here (its conversion refuses it,
        or leaves it out, with its own reason). Takes nothing from the budget.
        """
        counts: Dict[str, int] = {}
        total = 0
        for path in meshes:
            if path not in counts:
                counts[path] = _declared(path)
            total += counts[path]
            if total > self.left:
                raise self._refused(shown)

    def take(self, triangles: int, shown: str) -> None:
        """Count a mesh's triangles; UNSUPPORTED_ASSETS (naming ``shown``) past the budget."""
        self.left -= triangles
        if self.left < 0:
            raise self._refused(shown)


def _declared(path: str) -> int:
    """Return the triangles a mesh file declares; 0 for one that is not a mesh may be."""
    try:
        count = declared_triangles(read_mesh_bytes(path, ''), os.path.splitext(path)[1].lower())
        check_triangles(count, '')
    except RefusedError:
        return 0
    return count


class SdfSettings(NamedTuple):
    """
    What an SDF load searches and compares with: the simulator's side of it.

    ``model_paths`` come before the Gazebo variables; ``time_step_s`` and
    ``gravity_m_s2`` are r2d2_sim's (a world's that differ are noted);
    ``ground_plane``: r2d2_sim loads its own; ``strict``: a spawn refuses a
    model with anything not simulated (LoadWorld has its own flag);
    ``places``: the directories worlds load from (``world_paths``, this
    package's ``urdf/``, pybullet_data), where a spawn's model file may lie
    too, beside the search paths and the Fuel caches.
    """

    model_paths: Tuple[str, ...] = ()
    time_step_s: Optional[float] = None
    gravity_m_s2: Optional[Tuple[float, float, float]] = None
    ground_plane: bool = False
    strict: bool = False
    places: Tuple[str, ...] = ()

    def read_options(self, ignore_missing: bool = False) -> ReadOptions:
        """Return the reader's options for a load with these settings."""
        return ReadOptions(self.time_step_s, self.gravity_m_s2, ignore_missing)


class GeneratedFiles:
    """A temporary directory of generated URDF files, one per distinct text; deleted by close."""

    def __init__(self) -> None:
        self.directory: Optional[str] = tempfile.mkdtemp(prefix='r2d2_sim_sdf_')

    def write(self, text: str) -> str:
        """Write ``text`` (once per distinct text) and return its file's path."""
        name = hashlib.sha256(text.encode('utf-8')).hexdigest()[:32] + '.urdf'
        assert self.directory is not None, 'URDF written after close'
        path = os.path.join(self.directory, name)
        if not os.path.exists(path):
            with open(path, 'w', encoding='utf-8') as handle:
                handle.write(text)
        return path

    def close(self) -> None:
        """Delete the directory and its files; safe to call twice."""
        if self.directory is not None:
            shutil.rmtree(self.directory, ignore_errors=True)
            self.directory = None


class SdfBody(NamedTuple):
    """One body to load: entity name, URDF file and text, base pose, the model it is of."""

    name: str
    path: str
    text: str
    pose: Transform   # in the world (for a spawn: in the model's frame)
    static: bool
    model: str


class SdfRead(NamedTuple):
    """A file read: what it describes, what is not simulated (one line, '' if nothing)."""

    scene: Scene
    summary: str
    merged_ground: Tuple[str, ...]   # models merged into r2d2_sim's ground plane


class SdfBuilt(NamedTuple):
    """What a load made: its bodies, generated files, triangles, and what it skipped."""

    bodies: Tuple[SdfBody, ...]
    files: GeneratedFiles
    triangles: int
    not_simulated: Tuple[Tuple[str, int], ...]   # by what, as the reader counts
    left_out: Tuple[str, ...]                    # meshes left out (ignore_missing)


def summary_line(counts: Iterable[Tuple[str, int]]) -> str:
    """Return 'not simulated: light x9, plugin x3, ...' for counts by what (empty for none)."""
    shown = [what if count == 1 else f'{what} x{count}' for what, count in counts]
    return 'not simulated: ' + ', '.join(shown) if shown else ''


def is_ground_plane(model: Model) -> bool:
    """Return True for a static model of planes only, at z = 0 facing up (Gazebo's ground)."""
    if not model.links or not all(link.static for link in model.links):
        return False
    shapes = [(link, s) for link in model.links for s in link.collisions + link.visuals]
    if not shapes:
        return False
    for link, shape in shapes:
        if shape.geometry.kind != 'plane':
            return False
        pose = compose(model.pose, compose(link.pose, shape.pose))
        normal = rotate(pose.rotation, shape.geometry.size[:3])
        height = sum(n * p for n, p in zip(normal, pose.translation))
        if normal[2] < 1.0 - 1e-6 or abs(height) > 1e-6:
            return False
    return True


def read_sdf(text: str, path: Optional[str], shown: str, resources: Resources,
             options: ReadOptions, ground_plane: bool) -> SdfRead:
    """
    Read an SDF file and its includes; say what is not simulated.

    ``ground_plane``: r2d2_sim has its own, so a world's plane at z = 0 is merged
    into it. RefusedError with LoadWorld's codes.
    """
    scene = Reader(resources, options).read(text, path, shown)
    merged = tuple(m.name for m in scene.models if ground_plane and is_ground_plane(m))
    if merged:
        scene = scene._replace(models=tuple(m for m in scene.models if m.name not in merged))
    return SdfRead(scene, summary_line(scene.not_simulated), merged)


class _Notes:
    """What the body planning and URDF writing skip, counted by what it is."""

    def __init__(self) -> None:
        self.counts: Dict[str, int] = {}

    def note(self, what: str) -> None:
        self.counts[what] = self.counts.get(what, 0) + 1


def scene_meshes(scene: Scene) -> List[str]:
    """Return the mesh file of every mesh shape of ``scene``'s models: each use, once."""
    return [shape.geometry.mesh for model in scene.models for link in model.links
            for shape in link.collisions + link.visuals
            if shape.geometry.kind == 'mesh' and shape.geometry.mesh is not None]


def build_bodies(scene: Scene, cache: MeshCache, ignore_missing: bool = False,
                 relative: bool = False, budget: Optional[TriangleBudget] = None
                 ) -> SdfBuilt:
    """
    Plan, convert and write every body of ``scene``'s models, names unique in the world.

    ``relative``: poses in the model's frame (a spawn), else in the world.
    ``ignore_missing``: a mesh that cannot be used is left out (noted), not
    refused. ``budget``: the world's triangles, when the scene is one of its
    files (a manifest's model), else the scene's own: checked first from
    what the mesh files say they hold, then as each converts. RefusedError:
    UNSUPPORTED_ASSETS past MAX_WORLD_TRIANGLES, or for a mesh that is too
    big or unreadable; RESOURCE_PARSE_ERROR for a moving link of mass 0
    or an invalid inertia.
    """
    budget = budget if budget is not None else TriangleBudget()
    files = GeneratedFiles()
    notes = _Notes()
    left_out: List[str] = []

    def meshes(geometry: Geometry) -> Optional[Converted]:
        path = geometry.mesh
        assert path is not None  # asked only of a mesh, whose file was found
        try:
            return cache.convert(path, geometry.uri or os.path.basename(path))
        except RefusedError as exc:
            if ignore_missing and exc.code in ('MISSING_ASSETS', 'UNSUPPORTED_ASSETS'):
                left_out.append(exc.message)
                return None
            raise
    try:
        # before any mesh is converted
        budget.expect(scene_meshes(scene), scene.models[0].source if scene.models else '')
        bodies: List[SdfBody] = []
        taken = set()
        triangles = 0
        for model in scene.models:
            for body in plan_bodies(model, notes):
                text, used = urdf_text(body, meshes, cache.hulls, notes)
                triangles += used
                budget.take(used, str(Place(model.source, (f'model {model.name[:100]}',))))
                name, number = body.name, 1
                while name in taken:
                    name, number = f'{body.name}_{number}', number + 1
                taken.add(name)
                if name != body.name:
                    text = text.replace(f'<robot name="{body.name}">', f'<robot name="{name}">',
                                        1)
                pose = body.base if relative else compose(model.pose, body.base)
                bodies.append(SdfBody(name, files.write(text), text, pose, body.static,
                                      model.name))
    except BaseException:
        files.close()
        raise
    return SdfBuilt(tuple(bodies), files, triangles, tuple(notes.counts.items()),
                    tuple(left_out))
