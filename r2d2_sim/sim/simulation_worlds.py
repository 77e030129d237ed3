"""
The world file around the robots: read at start-up, loaded and unloaded while running.

:class:`SimulationWorlds` is mixed into :class:`~r2d2_sim.sim.simulation.Simulation`:
the ``world`` parameter's world read at start-up, LoadWorld's world read
and checked in full before anything changes (so that a refusal leaves the
world as it was) and then built as launched, UnloadWorld, the worlds that
can be loaded, and the named poses of the world loaded. Reading the files
is :mod:`r2d2_sim.sim.worlds`'s; building the world is the Launch's.
"""

from typing import List, Optional, Sequence, Tuple

from r2d2_sim.errors import RefusedError, WorldError
from r2d2_sim.model.transforms import Transform
from r2d2_sim.physics.crowding import check_placements, moving_links, Placement
from r2d2_sim.physics.world import SimWorld
from r2d2_sim.sim.tags import TagsFilter, tags_match
from r2d2_sim.sim.world_manifest import NamedPose
from r2d2_sim.sim.world_list import list_worlds, WorldEntry
from r2d2_sim.sim.worlds import empty_world, LoadOptions, read_world, World


class SimulationWorlds:
    """The Simulation's world file: start-up, LoadWorld, UnloadWorld, its named poses."""

    def _start_world(self, uri: str) -> World:
        """Read the ``world`` parameter's world (the operator's: any file); WorldError if bad."""
        if not uri:
            return empty_world()
        try:
            return read_world(uri, '', self.places, self._options(LoadOptions()), trusted=True,
                              sdf=self.sdf)
        except RefusedError as exc:
            raise WorldError(f'world {exc.message}') from None  # the message names the file

    def _options(self, options: LoadOptions) -> LoadOptions:
        """Return a load's options with ``strict_worlds``: refuse what is not simulated."""
        strict = options.fail_on_unsupported_element or self.config.strict_worlds
        return options._replace(fail_on_unsupported_element=strict)

    def _world_loaded(self, world_file: Optional[World]) -> None:
        """Take ``world_file`` as the world now: its named poses, each entity's start-up info."""
        if self.world_file is not None and self.world_file is not world_file:
            self.world_file.close()
        if world_file is not None and world_file is not self.world_file and world_file.notes:
            self._warn(f'world {world_file.name}: {"; ".join(world_file.notes)}')
        self.world_file = world_file
        poses = world_file.named_poses if world_file is not None else ()
        self.entities.named_frames = {p.name: Transform(p.position, p.orientation)
                                      for p in poses}
        self.entities.restore_info(self._launch.infos())

    @property
    def world_is_loaded(self) -> bool:
        """Return False after unload_world, until a world is loaded: the standard's NO_WORLD."""
        return self.world_file is not None

    def available_worlds(self, additional_sources: Sequence[str] = (),
                         tags: TagsFilter = TagsFilter(), offline_only: bool = False,
                         continue_on_error: bool = False) -> Tuple[List[WorldEntry], str]:
        """Return the worlds that can be loaded and a note (see :func:`worlds.list_worlds`)."""
        return list_worlds(self.places, additional_sources, tags, offline_only,
                           continue_on_error)

    def load_world(self, uri: str, resource_string: str = '',
                   options: LoadOptions = LoadOptions()) -> World:
        """
        Load a world in place of the current one, as LoadWorld asks; return it.

        Everything is read and checked first (the files, every model loaded
        once in a physics world of its own, the models' names against the
        robots'), so a refusal leaves the world exactly as it was. Then the
        world is built as launched with the new world: spawned entities gone,
        the start-up robots (deleted ones too) at its start pose, the ground
        and ``extra_models`` as at start-up, time at 0 and nothing changed
        since (STOPPED, once the caller pauses). RefusedError with LoadWorld's
        codes (see :func:`~r2d2_sim.sim.worlds.read_world`); OPERATION_FAILED
        for a model named like a robot or a start-up model.
        """
        world_file = read_world(uri, resource_string, self.places, self._options(options),
                                sdf=self.sdf)
        try:
            self._check_world(world_file)
        except BaseException:
            world_file.close()
            raise
        self._switch(world_file)
        return world_file

    def unload_world(self) -> None:
        """
        Unload the world: its models and named poses leave, and every spawned entity.

        The ground, the robots and ``extra_models`` stay, built again as
        launched with no world, at time 0; :attr:`world_is_loaded` is False
        until a world is loaded (the standard's NO_WORLD). RefusedError
        NO_WORLD_LOADED when none is.
        """
        if self.world_file is None:
            raise RefusedError('NO_WORLD_LOADED', 'no world is loaded')
        self._switch(empty_world())
        self._world_loaded(None)

    def named_poses(self, tags: TagsFilter = TagsFilter()) -> List[NamedPose]:
        """Return the world's named poses whose tags pass the filter, in the world file's order."""
        poses = self.world_file.named_poses if self.world_file is not None else ()
        return [pose for pose in poses if tags_match(pose.tags, tags)]

    def named_pose(self, name: str) -> NamedPose:
        """Return the named pose ``name``; RefusedError NOT_FOUND if the world has none such."""
        if self.world_file is None:
            raise RefusedError('NOT_FOUND', f'no named pose {name[:100]!r}: no world is loaded')
        return self.world_file.named_pose(name)

    def _check_world(self, world_file: World) -> None:
        """
        Refuse a world whose models take a start-up entity's name, cannot load, or crowd.

        Crowded: its moving bodies, loaded at their poses in a scratch world,
        have too many moving links or too many of them touching at once
        (:mod:`r2d2_sim.physics.crowding`: the first step would last minutes).
        """
        taken = set(self._launch.names())
        for model in world_file.models:
            if model.name is not None and model.name in taken:
                raise RefusedError('OPERATION_FAILED', f'the world\'s model {model.name!r} '
                                   'would take the name of one of the simulator\'s own '
                                   'entities (a robot, the ground plane, extra_models)')
        # Models made from SDF were written here from checked parts: not loaded twice
        # to be checked, only (when they move) to see how crowded they are.
        paths = sorted({model.path for model in world_file.models if not model.sdf})
        try:
            moving = set()
            with SimWorld(ground_plane=False, time_step_s=self.time_step_s) as scratch:
                sdf_flags = scratch.model_flags
                for path in paths:
                    if moving_links(scratch.load(path)):
                        moving.add(path)
            check_placements(
                [Placement(model.path, model.position, model.orientation,
                           sdf_flags if model.sdf else 0)
                 for model in world_file.models
                 if (model.sdf and not model.static) or model.path in moving],
                self.time_step_s, 'RESOURCE_PARSE_ERROR', 'the world')
        except WorldError as exc:
            raise RefusedError('RESOURCE_PARSE_ERROR', str(exc)) from None

    def _switch(self, world_file: World) -> None:
        """Build the world as launched with ``world_file``: spawned ones gone, time at 0."""
        self._forget_robots([r for r in self.robots if r.body.spawned])
        for name, body in list(self.world.bodies.items()):
            if body.spawned:
                self.entities.dropped(name)
        for name in [n for n in self.world.bodies if n not in self._launch.names()]:
            self.entities.dropped(name)  # the old world's models: their info goes with them
        try:
            rebuilt = self._launch.switch(world_file, self.robots)
        except WorldError as exc:
            # Only a file changed between the check and the load gets here.
            self._error(f'the world {world_file.name} could not be built ({exc}): building the '
                        'previous one again, as launched')
            world_file.close()
            self._take(self._launch.rebuild([], as_launched=True))
            self.entities.restore_info(self._launch.infos())
            raise RefusedError('OPERATION_FAILED', f'the world could not be built: {exc}; the '
                                                   'previous world was built again as '
                                                   'launched') from None
        self._take(rebuilt)
        self._world_loaded(world_file)

    def _take(self, rebuilt) -> None:
        """Take a rebuilt world's robots and models, time at 0, and tell the robots' watchers."""
        for robot in self.robots:
            if robot not in rebuilt.robots:
                robot.close()  # a second close of a robot the launch closed does nothing
        self.robots = rebuilt.robots
        self.models = rebuilt.models
        self._restart_time()
        self.pristine = True
        self._robots_changed()
