"""
Old public names that moved, in one table: each still works, warns, and goes in REMOVED_IN.

An old module path (``r2d2_sim.node``) is found by a finder that
:mod:`r2d2_sim` puts last on ``sys.meta_path``, so a real module always wins:
importing it imports the new module and gives that module itself
(``sys.modules`` holds it under both names), with one ``DeprecationWarning``
that names the new path. Where some of an old module's names went elsewhere,
the old path is a read-only view that finds each name where it went. A name
renamed on a public face (``r2d2_sim.testing.WorldError``) is served by that
module's ``__getattr__`` (PEP 562) through :func:`renamed`. ``python -m`` on
an old path runs the new module. Nothing is imported here until an old name is
used, so importing r2d2_sim stays cheap; ``test/lint/test_deprecations.py``
checks that every entry points somewhere and warns once.
"""

import sys
import types

TYPE_CHECKING = False  # typing costs milliseconds to import: for the type checker only
if TYPE_CHECKING:
    from importlib.machinery import ModuleSpec
    from types import CodeType
    from typing import Any, Sequence

__all__ = ['MOVED', 'REMOVED_IN', 'install', 'renamed']

REMOVED_IN = '0.3.0'

# Each old path and the path that replaced it: a module ('r2d2_sim.node'), or a name in
# one ('r2d2_sim.testing:WorldError'). A name under an old module path makes that path
# a view of its new module with the name found where it went.
MOVED = {
    # On the testing API's face, one name per concept (0cb9102): a refusal is
    # RefusedError in the core, both harnesses and the standard's client.
    'r2d2_sim.testing:WorldError': 'r2d2_sim.testing:RefusedError',
    'r2d2_sim.testing:EntityState': 'r2d2_sim.testing:BaseState',

    # Folders are the layers (f8effb4): the modules that sat side by side in r2d2_sim/.
    'r2d2_sim.cli': 'r2d2_sim.apps.cli',
    'r2d2_sim.demo': 'r2d2_sim.apps.demo',
    'r2d2_sim.drive_cmd': 'r2d2_sim.apps.drive',
    'r2d2_sim.manoeuvre': 'r2d2_sim.apps.manoeuvre',
    'r2d2_sim.plots': 'r2d2_sim.apps.plots',
    'r2d2_sim.replay': 'r2d2_sim.apps.replay',
    'r2d2_sim.sim_node': 'r2d2_sim.apps.sim_node',
    'r2d2_sim.camera': 'r2d2_sim.model.camera',
    'r2d2_sim.drive_controller': 'r2d2_sim.model.drive_controller',
    'r2d2_sim.health': 'r2d2_sim.model.health',
    'r2d2_sim.kinematics': 'r2d2_sim.model.kinematics',
    'r2d2_sim.sensors': 'r2d2_sim.model.sensors',
    'r2d2_sim.tf_buffer': 'r2d2_sim.model.tf_buffer',
    'r2d2_sim.timing': 'r2d2_sim.model.timing',
    'r2d2_sim.transforms': 'r2d2_sim.model.transforms',
    'r2d2_sim.body': 'r2d2_sim.physics.body',
    'r2d2_sim.bullet_records': 'r2d2_sim.physics.records',
    'r2d2_sim.description': 'r2d2_sim.physics.description',
    'r2d2_sim.raycast': 'r2d2_sim.physics.raycast',
    'r2d2_sim.stdio': 'r2d2_sim.physics.stdio',
    'r2d2_sim.world': 'r2d2_sim.physics.world',
    'r2d2_sim.foxglove_sink': 'r2d2_sim.recording.sink',
    'r2d2_sim.message_definitions': 'r2d2_sim.recording.message_definitions',
    'r2d2_sim.command_input': 'r2d2_sim.ros.cmd_vel',
    'r2d2_sim.control_services': 'r2d2_sim.ros.control_services',
    'r2d2_sim.entity_services': 'r2d2_sim.ros.standard.entities',
    'r2d2_sim.fleet': 'r2d2_sim.ros.fleet',
    'r2d2_sim.joint_info': 'r2d2_sim.ros.joint_info',
    'r2d2_sim.mirror': 'r2d2_sim.ros.mirror',
    'r2d2_sim.node': 'r2d2_sim.ros.node',
    'r2d2_sim.outputs': 'r2d2_sim.ros.outputs',
    'r2d2_sim.quiet_node': 'r2d2_sim.ros.quiet_node',
    'r2d2_sim.robot_interfaces': 'r2d2_sim.ros.robot_interfaces',
    'r2d2_sim.ros_parameters': 'r2d2_sim.ros.parameters',
    'r2d2_sim.serialization': 'r2d2_sim.ros.serialization',
    'r2d2_sim.sim_interfaces': 'r2d2_sim.ros.standard.server',
    'r2d2_sim.tf_outputs': 'r2d2_sim.ros.tf_outputs',
    'r2d2_sim.drive_train': 'r2d2_sim.sim.robots.drive_train',
    'r2d2_sim.entities': 'r2d2_sim.sim.entities',
    'r2d2_sim.entities:EntityError': 'r2d2_sim.errors:RefusedError',
    'r2d2_sim.entities:EntityState': 'r2d2_sim.model.transforms:BaseState',
    'r2d2_sim.parameter_readers': 'r2d2_sim.sim.settings.readers',
    'r2d2_sim.parameters': 'r2d2_sim.sim.settings.table',
    'r2d2_sim.parameters:SimConfig': 'r2d2_sim.sim.settings.config:SimConfig',
    'r2d2_sim.parameters:parse_config': 'r2d2_sim.sim.settings.config:parse_config',
    'r2d2_sim.parameters:read_value': 'r2d2_sim.sim.settings.config:read_value',
    'r2d2_sim.parameters:check_fields': 'r2d2_sim.sim.settings.config:check_fields',
    'r2d2_sim.parameters:parameter_help': 'r2d2_sim.sim.settings.reference:parameter_help',
    'r2d2_sim.robot': 'r2d2_sim.sim.robots.robot',
    'r2d2_sim.robot_parameters': 'r2d2_sim.sim.settings.robots',
    'r2d2_sim.sensor_mounts': 'r2d2_sim.sim.robots.sensors',
    'r2d2_sim.simulation': 'r2d2_sim.sim.simulation',
    # Names that left those modules later in 0.1.0 (one name per concept, 0cb9102; the
    # link tree out of transforms, c1f749b; what a spawn may load, out of entities).
    'r2d2_sim.bullet_records:BaseState': 'r2d2_sim.model.transforms:BaseState',
    'r2d2_sim.timing:ns_of': 'r2d2_sim.model.timing:stamp_ns',
    'r2d2_sim.sim_node:raise_if_stopped': 'r2d2_sim.apps.cli:raise_if_stopped',
    'r2d2_sim.entities:MAX_DESCRIPTION_BYTES': 'r2d2_sim.sim.spawnables:MAX_DESCRIPTION_BYTES',
    'r2d2_sim.entities:MAX_LINKS': 'r2d2_sim.sim.spawnables:MAX_LINKS',
    'r2d2_sim.transforms:JointModel': 'r2d2_sim.model.link_tree:JointModel',
    'r2d2_sim.transforms:JointTransform': 'r2d2_sim.model.link_tree:JointTransform',
    'r2d2_sim.transforms:LinkTransforms': 'r2d2_sim.model.link_tree:LinkTransforms',
    'r2d2_sim.transforms:parse_joints': 'r2d2_sim.model.link_tree:parse_joints',
    'r2d2_sim.transforms:root_link': 'r2d2_sim.model.link_tree:root_link',
    'r2d2_sim.transforms:joint_transform': 'r2d2_sim.model.link_tree:joint_transform',

    # sim/ by concept (0.2.0): settings/, worlds/, robots/ beside sdf/.
    'r2d2_sim.sim.parameters': 'r2d2_sim.sim.settings.table',
    'r2d2_sim.sim.parameters:SimConfig': 'r2d2_sim.sim.settings.config:SimConfig',
    'r2d2_sim.sim.parameters:parse_config': 'r2d2_sim.sim.settings.config:parse_config',
    'r2d2_sim.sim.parameters:read_value': 'r2d2_sim.sim.settings.config:read_value',
    'r2d2_sim.sim.parameters:check_fields': 'r2d2_sim.sim.settings.config:check_fields',
    'r2d2_sim.sim.parameter_readers': 'r2d2_sim.sim.settings.readers',
    'r2d2_sim.sim.parameter_docs': 'r2d2_sim.sim.settings.reference',
    'r2d2_sim.sim.robot_parameters': 'r2d2_sim.sim.settings.robots',
    'r2d2_sim.sim.robot': 'r2d2_sim.sim.robots.robot',
    'r2d2_sim.sim.drive_train': 'r2d2_sim.sim.robots.drive_train',
    'r2d2_sim.sim.sensor_mounts': 'r2d2_sim.sim.robots.sensors',
    'r2d2_sim.sim.world_data': 'r2d2_sim.sim.worlds.world',
    'r2d2_sim.sim.world_places': 'r2d2_sim.sim.worlds.places',
    'r2d2_sim.sim.world_list': 'r2d2_sim.sim.worlds.listing',
    'r2d2_sim.sim.world_manifest': 'r2d2_sim.sim.worlds.manifest',
    'r2d2_sim.sim.sdf_world': 'r2d2_sim.sim.worlds.sdf_format',
    'r2d2_sim.sim.sdf_world:SDF_SUFFIXES': 'r2d2_sim.sim.worlds:SDF_SUFFIXES',
    'r2d2_sim.sim.entity_bounds': 'r2d2_sim.sim.bounds',
    'r2d2_sim.sim.launch': 'r2d2_sim.sim.startup',
    'r2d2_sim.sim.launch:Launch': 'r2d2_sim.sim.startup:Startup',
}


def install() -> None:
    """Put the finder of MOVED's old module paths last on ``sys.meta_path``, once."""
    if not any(type(finder).__name__ == _OldPaths.__name__ for finder in sys.meta_path):
        sys.meta_path.append(_OldPaths())


def renamed(module: str, name: str) -> 'Any':
    """
    Return what ``module``'s old ``name`` is now, warning that it moved (a face's ``__getattr__``).

    AttributeError, as Python's own, for a name that is not in the table.
    """
    new = MOVED.get(f'{module}:{name}')
    if new is None:
        raise AttributeError(f'module {module!r} has no attribute {name!r}')
    import importlib
    new_module, _, new_name = new.partition(':')
    found = getattr(importlib.import_module(new_module), new_name)
    # For 'from package import name' the import system asks hasattr() first, then
    # the statement takes the name: warn for the statement only.
    asker = sys._getframe(1).f_back  # whoever asked the __getattr__ that called this
    if asker is None or asker.f_code.co_name != '_handle_fromlist':
        _warn(f'{module}:{name}', new)
    return found


def _message(old: str, new: str) -> str:
    dotted = [path.replace(':', '.') for path in (old, new)]
    return f'{dotted[0]} is deprecated and goes in r2d2_sim {REMOVED_IN}: use {dotted[1]}'


def _warn(old: str, new: str) -> None:
    """Warn that ``old`` moved to ``new``, pointing at the line that used it."""
    import warnings
    frame = sys._getframe(1)
    level = 2
    # The line that used the old name: past the import system, this module and a face's
    # __getattr__, so the default filter shows it when that line is in __main__. The
    # frames of importlib's frozen bootstrap are not counted: warn() skips them itself.
    while frame.f_back is not None and (
            frame.f_globals.get('__name__', '').startswith(('importlib', __name__))
            or (frame.f_code.co_name == '__getattr__'
                and frame.f_globals.get('__name__', '').startswith('r2d2_sim'))):
        frame = frame.f_back
        if not frame.f_code.co_filename.startswith('<frozen importlib._bootstrap'):
            level += 1
    warnings.warn(_message(old, new), DeprecationWarning, stacklevel=level)


class _OldPaths:
    """The finder and loader of the old module paths in MOVED."""

    def find_spec(self, fullname: str, path: 'Sequence[str] | None' = None,
                  target: 'types.ModuleType | None' = None) -> 'ModuleSpec | None':
        """Return a spec for an old module path whose new module exists, else None."""
        new = MOVED.get(fullname)
        if new is None:
            return None
        from importlib.machinery import ModuleSpec
        from importlib.util import find_spec
        new_spec = find_spec(new)
        if new_spec is None:
            return None
        # The import system duck-types loaders; typeshed wants importlib.abc.Loader, whose
        # import would cost more than all of this module.
        spec = ModuleSpec(fullname, self, origin=new_spec.origin)  # type: ignore[arg-type]
        spec.has_location = new_spec.has_location
        return spec

    def create_module(self, spec: 'ModuleSpec') -> None:
        """Let the import system create the module (a view needs one of its own)."""
        return None

    def exec_module(self, module: types.ModuleType) -> None:
        """Put the new module under the old name, or make ``module`` a view of where names went."""
        import importlib
        old = module.__name__
        new = MOVED[old]
        target = importlib.import_module(new)
        moved = {key.partition(':')[2] for key in MOVED if key.startswith(old + ':')}
        if moved:
            vars(module).update(
                __doc__=f'Deprecated: {old} is now {new}, and some of its names moved.',
                __all__=list(getattr(target, '__all__', ())),
                __getattr__=_view(old, target, moved),
                __dir__=lambda: sorted(set(dir(target)) | moved))
        else:
            # The import system hands out what sys.modules holds after exec_module.
            sys.modules[old] = target
        _warn(old, new)

    def get_code(self, fullname: str) -> 'CodeType | None':
        """Return the new module's code, for ``python -m`` on the old path."""
        import warnings
        from importlib.util import find_spec
        new = MOVED[fullname]
        spec = find_spec(new)
        get_code = getattr(spec.loader, 'get_code', None) if spec is not None else None
        if spec is None or get_code is None:
            return None
        # The code runs as __main__: said from there, the default filter shows it.
        warnings.warn_explicit(_message(fullname, new), DeprecationWarning,
                               filename=spec.origin or new, lineno=0, module='__main__')
        return get_code(new)


def _view(old: str, target: types.ModuleType, moved: 'set[str]') -> 'Any':
    """Return the ``__getattr__`` of a view: a moved name where it went, the rest from target."""
    def __getattr__(name: str) -> 'Any':
        if name in moved:
            return renamed(old, name)
        return getattr(target, name)
    return __getattr__
