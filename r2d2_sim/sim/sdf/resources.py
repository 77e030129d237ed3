"""
Where an SDF world's includes and meshes are found, and where they may come from.

No ROS, no PyBullet, never the network. A URI in an SDF file is one of:

- ``model://name/...``: a model directory on the search path: the
  ``model_paths`` parameter's directories, then those of the environment
  variables Gazebo users already set (``GZ_SIM_RESOURCE_PATH``,
  ``IGN_GAZEBO_RESOURCE_PATH``, ``GAZEBO_MODEL_PATH``, ``SDF_PATH``);
- a Fuel URL (``https://fuel.gazebosim.org/1.0/<owner>/models/<name>[/<version>]``,
  and files in it): the local cache Gazebo downloads Fuel models into
  (``~/.gz/fuel/<host>/<owner>/models/<name>/<version>/``, ``~/.ignition/fuel``,
  or ``GZ_FUEL_CACHE_PATH``), the highest version unless one is named. The
  ground plane and the sun, which almost every world includes, are built in
  when the cache has none; any other Fuel model missing is MISSING_ASSETS,
  naming it and how to download it;
- ``package://pkg/...``, ``file://...``, an absolute path, or a path relative
  to the file it is written in.

A world read for a request (LoadWorld, SpawnEntity) may only use files within
allowed places (``roots``): the world's own directory, the search paths, the
Fuel caches, ROS packages and the places worlds load from; outside them is
UNSUPPORTED_ASSETS. The ``world`` parameter is the operator's and may use any
file (``roots`` None).
"""

import os
from typing import List, Mapping, NamedTuple, Optional, Sequence, Tuple
from urllib.parse import unquote, urlsplit

from r2d2_sim.errors import RefusedError
from r2d2_sim.files import read_regular
from r2d2_sim.physics.description import DescriptionError, package_share_directory
from r2d2_sim.sim.sdf.elements import parse_xml

__all__ = ['Resources', 'ModelSource', 'MODEL_PATH_VARIABLES', 'FUEL_CACHE_VARIABLE',
           'FUEL_HOSTS', 'BUILT_IN']

MODEL_PATH_VARIABLES = ('GZ_SIM_RESOURCE_PATH', 'IGN_GAZEBO_RESOURCE_PATH', 'GAZEBO_MODEL_PATH',
                        'SDF_PATH')
FUEL_CACHE_VARIABLE = 'GZ_FUEL_CACHE_PATH'
DEFAULT_FUEL_CACHES = ('~/.gz/fuel', '~/.ignition/fuel')
FUEL_HOSTS = ('fuel.gazebosim.org', 'fuel.ignitionrobotics.org')
MODEL_SCHEME = 'model://'
PACKAGE_SCHEME = 'package://'
FILE_SCHEME = 'file://'
MISSING, UNSUPPORTED = 'MISSING_ASSETS', 'UNSUPPORTED_ASSETS'

_GROUND_PLANE = '''<sdf version="1.6"><model name="ground_plane"><static>true</static>
<link name="link"><collision name="collision"><geometry><plane><normal>0 0 1</normal>
<size>100 100</size></plane></geometry></collision><visual name="visual"><geometry><plane>
<normal>0 0 1</normal><size>100 100</size></plane></geometry><material>
<diffuse>0.8 0.8 0.8 1</diffuse></material></visual></link></model></sdf>'''
_SUN = '''<sdf version="1.6"><light type="directional" name="sun"><cast_shadows>true
</cast_shadows><pose>0 0 10 0 0 0</pose><diffuse>0.8 0.8 0.8 1</diffuse>
<direction>-0.5 0.1 -0.9</direction></light></sdf>'''
# The two models almost every Gazebo world includes, by (Fuel owner, name) and model:// name.
BUILT_IN = {('openrobotics', 'ground plane'): _GROUND_PLANE, ('openrobotics', 'sun'): _SUN,
            'ground_plane': _GROUND_PLANE, 'sun': _SUN}


class ModelSource(NamedTuple):
    """An included model: its SDF file (or built-in text) and its directory, as shown."""

    shown: str
    path: Optional[str]       # None: built in
    text: Optional[str]       # the built-in SDF, else None
    directory: Optional[str]  # where its relative URIs start


def _inside(path: str, root: str) -> bool:
    return path == root or path.startswith(root.rstrip(os.sep) + os.sep)


def _variable_paths(environ: Mapping[str, str], names: Sequence[str]) -> List[str]:
    found: List[str] = []
    for name in names:
        found += [p for p in environ.get(name, '').split(os.pathsep) if p]
    return found


class _FuelUrl(NamedTuple):
    owner: str
    name: str
    version: Optional[str]  # None or 'tip': the newest in the cache
    file: str               # a file inside the model ('' for the model itself)


def _fuel_url(uri: str) -> Optional[_FuelUrl]:
    """Read a Fuel model URL; None for anything else."""
    parts = urlsplit(uri)
    if parts.scheme not in ('http', 'https') or parts.hostname not in FUEL_HOSTS:
        return None
    steps = [unquote(s) for s in parts.path.split('/') if s]
    if len(steps) < 4 or steps[2].lower() != 'models':
        return None
    owner, name, rest = steps[1], steps[3], steps[4:]
    version = None
    if rest and rest[0] != 'files':
        version, rest = rest[0], rest[1:]
    if rest and rest[0] == 'files':
        rest = rest[1:]
    return _FuelUrl(owner, name, version, '/'.join(rest))


def _child_named(directory: str, name: str) -> Optional[str]:
    """Return the entry of ``directory`` named ``name`` regardless of case (Fuel's cache)."""
    exact = os.path.join(directory, name)
    if os.path.isdir(exact):
        return exact
    try:
        for entry in sorted(os.listdir(directory)):
            if entry.lower() == name.lower() and os.path.isdir(os.path.join(directory, entry)):
                return os.path.join(directory, entry)
    except OSError:
        pass
    return None


class Resources:
    """
    The search paths and caches of one load, and the places its files may come from.

    ``model_paths`` (the parameter's) come before the environment's;
    ``roots`` are the directories files may come from (None: any file).
    """

    def __init__(self, model_paths: Sequence[str] = (), roots: Optional[Sequence[str]] = None,
                 environ: Optional[Mapping[str, str]] = None) -> None:
        environ = os.environ if environ is None else environ
        self.search_paths = [os.path.abspath(os.path.expanduser(p)) for p in
                             list(model_paths) + _variable_paths(environ, MODEL_PATH_VARIABLES)]
        caches = _variable_paths(environ, (FUEL_CACHE_VARIABLE,)) or list(DEFAULT_FUEL_CACHES)
        self.fuel_caches = [os.path.abspath(os.path.expanduser(p)) for p in caches]
        self._roots = None if roots is None else [os.path.realpath(r) for r in (
            list(roots) + self.search_paths + self.fuel_caches)]

    def allow(self, directory: str) -> None:
        """Let files come from ``directory`` too (the world's own, a ROS package's share)."""
        if self._roots is not None:
            self._roots.append(os.path.realpath(directory))

    def check(self, path: str, shown: str, what: str) -> str:
        """Return ``path`` if it may be read here; UNSUPPORTED_ASSETS if it lies outside."""
        if self._roots is not None:
            real = os.path.realpath(path)
            if not any(_inside(real, root) for root in self._roots):
                raise RefusedError(UNSUPPORTED, f'{what} {shown} lies outside the places an '
                                                'SDF may use (its own directory, model_paths, '
                                                'the Gazebo search paths, the Fuel cache, '
                                                'world_paths, ROS packages)')
        return path

    # -- models -------------------------------------------------------------------------

    def model(self, uri: str, base_dir: Optional[str], current: Optional[str] = None
              ) -> ModelSource:
        """
        Return the model an ``<include><uri>`` names: a directory with model.config, or a file.

        ``current`` is the directory of the model the include is written in.
        MISSING_ASSETS when it is nowhere, UNSUPPORTED_ASSETS when it is
        remote or outside the allowed places.
        """
        shown = uri[:200]
        fuel = _fuel_url(uri)
        if fuel is not None:
            directory = self._fuel_model(fuel)
            if directory is None:
                text = BUILT_IN.get((fuel.owner.lower(), fuel.name.lower()))
                if text is not None:
                    return ModelSource(f'built-in {fuel.name}', None, text, None)
                raise RefusedError(MISSING, f'Fuel model {fuel.owner}/{fuel.name} is not in the '
                                            'local Fuel cache (~/.gz/fuel): r2d2_sim never '
                                            'downloads; fetch it once with gz fuel download -u '
                                            f'"{shown}"')
            return self._model_in(directory, shown)
        if uri.startswith(MODEL_SCHEME):
            name = uri[len(MODEL_SCHEME):].strip('/')
            for directory in self.search_paths:
                candidate = os.path.join(directory, name)
                if os.path.exists(candidate):
                    return self._model_in(candidate, shown)
            text = BUILT_IN.get(name)
            if text is not None:
                return ModelSource(f'built-in {name}', None, text, None)
            raise RefusedError(MISSING, f'model {shown} is in none of the model search paths '
                                        '(model_paths, GZ_SIM_RESOURCE_PATH, GAZEBO_MODEL_PATH, '
                                        'SDF_PATH)')
        path = self.file(uri, base_dir, 'model', current)
        return self._model_in(path, shown)

    def _fuel_model(self, fuel: _FuelUrl) -> Optional[str]:
        """Return the cached directory of a Fuel model's version (newest if none named)."""
        for cache in self.fuel_caches:
            for host in FUEL_HOSTS:
                owner = _child_named(os.path.join(cache, host), fuel.owner)
                models = owner and _child_named(owner, 'models')
                model = models and _child_named(models, fuel.name)
                if not model:
                    continue
                try:
                    versions = sorted((int(v) for v in os.listdir(model) if v.isdigit()))
                except OSError:
                    continue
                if fuel.version not in (None, 'tip'):
                    if fuel.version.isdigit() and int(fuel.version) in versions:
                        return os.path.join(model, str(int(fuel.version)))
                    continue
                if versions:
                    return os.path.join(model, str(versions[-1]))
        return None

    def _model_in(self, path: str, shown: str) -> ModelSource:
        """Return the SDF file of a model directory (model.config's choice) or of a file."""
        self.check(path, shown, 'model')
        if os.path.isfile(path):
            return ModelSource(shown, path, None, os.path.dirname(path))
        if not os.path.isdir(path):
            raise RefusedError(MISSING, f'model {shown}: no such file or directory')
        chosen = _config_sdf(path) or 'model.sdf'
        candidate = os.path.join(path, chosen)
        if not os.path.isfile(candidate):
            raise RefusedError(MISSING, f'model {shown}: its directory has no {chosen[:100]}')
        self.check(candidate, shown, 'model')
        return ModelSource(f'{shown}/{chosen[:100]}', candidate, None, path)

    # -- files (meshes, included files) -----------------------------------------------

    def file(self, uri: str, base_dir: Optional[str], what: str,
             current: Optional[str] = None) -> str:
        """
        Return the path of a file an SDF names (a mesh, a model file), checked allowed.

        MISSING_ASSETS when it does not exist, UNSUPPORTED_ASSETS when it is
        remote (and not a Fuel file in the cache) or outside the allowed places.
        """
        shown = uri[:200]
        path = self._locate(uri, base_dir, what, current)
        self.check(path, shown, what)
        if not os.path.exists(path):
            raise RefusedError(MISSING, f'{what} {shown}: no such file')
        return path

    def _locate(self, uri: str, base_dir: Optional[str], what: str,
                current: Optional[str]) -> str:
        shown = uri[:200]
        fuel = _fuel_url(uri)
        if fuel is not None:
            directory = self._fuel_model(fuel)
            if directory is None:
                raise RefusedError(MISSING, f'{what} {shown}: Fuel model {fuel.owner}/'
                                            f'{fuel.name} is not in the local Fuel cache')
            return os.path.join(directory, fuel.file)
        if uri.startswith(MODEL_SCHEME):
            relative = uri[len(MODEL_SCHEME):]
            name, _, rest = relative.partition('/')
            for directory in self.search_paths:
                candidate = os.path.join(directory, relative)
                if os.path.exists(candidate):
                    return candidate
            # A model's files may name it by model://<its name>/... wherever it lies (a
            # Fuel model's directory is .../models/<name>/<version>).
            if current is not None and name.lower() in (
                    os.path.basename(current).lower(),
                    os.path.basename(os.path.dirname(current)).lower()):
                return os.path.join(current, rest)
            raise RefusedError(MISSING, f'{what} {shown} is in none of the model search paths')
        if uri.startswith(PACKAGE_SCHEME):
            package, _, relative = uri[len(PACKAGE_SCHEME):].partition('/')
            try:
                share = package_share_directory(package)
            except DescriptionError:
                raise RefusedError(MISSING, f'{what} {shown}: no ROS package '
                                            f'{package[:100]!r}') from None
            path = os.path.join(share, relative)
            if not _inside(os.path.realpath(path), os.path.realpath(share)):
                raise RefusedError(UNSUPPORTED, f'{what} {shown} leaves its package')
            self.allow(share)
            return path
        if uri.startswith(FILE_SCHEME):
            return uri[len(FILE_SCHEME):]
        if '://' in uri:
            raise RefusedError(UNSUPPORTED, f'{what} {shown}: only local files and Fuel models in '
                                            'the local cache are loaded, never the network')
        if os.path.isabs(uri):
            return uri
        if base_dir is None:
            raise RefusedError(UNSUPPORTED, f'{what} {shown}: a relative path in text sent as a '
                                            'resource_string has nothing to be relative to')
        return os.path.join(base_dir, uri)


def _config_sdf(directory: str) -> Optional[str]:
    """Return the SDF file a model.config names (the newest version), if it can be read."""
    path = os.path.join(directory, 'model.config')
    try:
        root = parse_xml(read_regular(path, 100_000).decode('utf-8'), path)
    except (OSError, UnicodeDecodeError, RefusedError):  # a FIFO too: model.sdf, not a wait
        return None
    best: Optional[str] = None
    best_version: Tuple[int, ...] = (-1,)
    for element in root.findall('sdf'):
        name = (element.text or '').strip()
        try:
            version = tuple(int(v) for v in element.get('version', '0').split('.'))
        except ValueError:
            version = (0,)
        if name and '..' not in name.split('/') and not os.path.isabs(name) and \
                version > best_version:
            best, best_version = name, version
    return best
