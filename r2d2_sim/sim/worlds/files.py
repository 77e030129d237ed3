"""
The world files of a simulation: the one loaded now, the ones that can be, and reading one.

:class:`WorldFiles` owns the world file the simulation was built with (the
``world`` parameter's at start-up, LoadWorld's later, none after
UnloadWorld) and answers every question about worlds that changes nothing:
is one loaded, which can be loaded, its named poses. It also reads and checks
a world for LoadWorld without touching the simulation: the files, the SDF
and its meshes, and every URDF model loaded once in a physics world of its
own. That is all the slow part of a load, so a caller may do it outside the
simulator's lock; building the read world is :meth:`Simulation.load_world
<r2d2_sim.sim.simulation.Simulation.load_world>`'s.
"""

from typing import List, Optional, Sequence, Tuple

from r2d2_sim.errors import RefusedError, WorldError
from r2d2_sim.sim.sdf.loading import SdfSettings
from r2d2_sim.sim.tags import TagsFilter, tags_match
from r2d2_sim.sim.worlds.listing import list_worlds, WorldEntry
from r2d2_sim.sim.worlds.places import Places
from r2d2_sim.sim.worlds.reading import empty_world, LoadOptions, read_world
from r2d2_sim.sim.worlds.world import NamedPose, World

__all__ = ['WorldFiles']


class WorldFiles:
    """
    Which world is loaded and which can be; reading one, checked, without changing anything.

    ``places`` are where a request may load from; ``sdf`` what an SDF world
    is searched and compared with (its ``strict``, the ``strict_worlds``
    parameter, refuses what is not simulated whatever a request says),
    ``time_step_s`` the physics step URDF models are checked with. :attr:`current` is the
    world loaded (None after UnloadWorld); only the Simulation sets it,
    through :meth:`take`.
    """

    def __init__(self, places: Places, sdf: SdfSettings, time_step_s: float) -> None:
        self.places = places
        self.sdf = sdf
        self.time_step_s = time_step_s
        self.current: Optional[World] = None

    @property
    def is_loaded(self) -> bool:
        """Return False after UnloadWorld, until a world is loaded: the standard's NO_WORLD."""
        return self.current is not None

    def read_start(self, uri: str) -> World:
        """Read the ``world`` parameter's world (the operator's: any file); WorldError if bad."""
        if not uri:
            return empty_world()
        try:
            return read_world(uri, '', self.places, self._options(LoadOptions()), trusted=True,
                              sdf=self.sdf)
        except RefusedError as exc:
            raise WorldError(f'world {exc.message}') from None  # the message names the file

    def read(self, uri: str, resource_string: str = '',
             options: LoadOptions = LoadOptions()) -> World:
        """
        Read a world LoadWorld names and check its files; change nothing. Return it.

        RefusedError with LoadWorld's codes (see
        :func:`~r2d2_sim.sim.worlds.reading.read_world`); RESOURCE_PARSE_ERROR
        for a URDF model PyBullet cannot load. The caller closes the world
        it does not load (:meth:`World.close`).
        """
        world = read_world(uri, resource_string, self.places, self._options(options),
                           sdf=self.sdf)
        try:
            self._check_models(world)
        except BaseException:
            world.close()
            raise
        return world

    def _options(self, options: LoadOptions) -> LoadOptions:
        """Return a load's options with ``strict_worlds``: refuse what is not simulated."""
        return options._replace(
            fail_on_unsupported_element=options.fail_on_unsupported_element or self.sdf.strict)

    def _check_models(self, world: World) -> None:
        """
        Refuse a world whose models cannot load or crowd: RESOURCE_PARSE_ERROR.

        Each URDF model is loaded once in a physics world of its own. Crowded:
        its moving bodies, loaded at their poses in a scratch world, have too
        many moving links or too many of them touching at once
        (:mod:`r2d2_sim.physics.crowding`: the first step would last minutes).
        """
        # PyBullet only here: the testing API imports the worlds' names without it.
        from r2d2_sim.physics.crowding import check_placements, moving_links, Placement
        from r2d2_sim.physics.world import SimWorld
        # Models made from SDF were written here from checked parts: not loaded twice
        # to be checked, only (when they move) to see how crowded they are.
        given_as = {model.path: model.given_as for model in world.models if not model.sdf}
        paths = sorted(given_as)
        try:
            moving = set()
            with SimWorld(ground_plane=False, time_step_s=self.time_step_s) as scratch:
                sdf_flags = scratch.model_flags
                for path in paths:
                    if moving_links(scratch.load(path, given_as=given_as[path])):
                        moving.add(path)
            check_placements(
                [Placement(model.path, model.position, model.orientation,
                           sdf_flags if model.sdf else 0, model.made_from, model.given_as)
                 for model in world.models
                 if (model.sdf and not model.static) or model.path in moving],
                self.time_step_s, 'RESOURCE_PARSE_ERROR', 'the world')
        except WorldError as exc:
            raise RefusedError('RESOURCE_PARSE_ERROR', str(exc)) from None

    def take(self, world: Optional[World]) -> None:
        """Make ``world`` the one loaded (None: none is), closing the one it replaces."""
        if self.current is not None and self.current is not world:
            self.current.close()
        self.current = world

    def available(self, additional_sources: Sequence[str] = (),
                  tags: TagsFilter = TagsFilter(), offline_only: bool = False,
                  continue_on_error: bool = False) -> Tuple[List[WorldEntry], str]:
        """Return the worlds that can be loaded and a note (see :func:`listing.list_worlds`)."""
        return list_worlds(self.places, additional_sources, tags, offline_only,
                           continue_on_error)

    def named_poses(self, tags: TagsFilter = TagsFilter()) -> List[NamedPose]:
        """Return the loaded world's named poses whose tags pass the filter, in file order."""
        poses = self.current.named_poses if self.current is not None else ()
        return [pose for pose in poses if tags_match(pose.tags, tags)]

    def named_pose(self, name: str) -> NamedPose:
        """Return the named pose ``name``; RefusedError NOT_FOUND if the world has none such."""
        if self.current is None:
            raise RefusedError('NOT_FOUND', f'no named pose {name[:100]!r}: no world is loaded')
        return self.current.named_pose(name)

    def close(self) -> None:
        """Close the loaded world's temporary files; safe to call twice."""
        if self.current is not None:
            self.current.close()
