"""
Where robot and object descriptions come from: files, ROS packages, pybullet_data, XML text.

No ROS messaging here, only the ament index for ``package://`` URIs. Every
failure is a :class:`DescriptionError` with a one-line message.
"""

import math
import os
from pathlib import Path
import stat
import sys
import tempfile
from typing import Callable, Dict, List, NamedTuple, Optional, Set, Tuple
import xml.etree.ElementTree as ElementTree

import numpy
import pybullet_data

from r2d2_sim.errors import SetupError
from r2d2_sim.files import describe, read_regular

PACKAGE_SCHEME = 'package://'
PACKAGE_NAME = 'r2d2_sim'
# A description file the operator names (a URDF of R2D2 is 14 kB).
MAX_READ_BYTES = 64 << 20
# The checkout this module sits in (urdf/ and package.xml beside r2d2_sim/), if any.
SOURCE_TREE = str(Path(__file__).resolve().parents[2])
# The longest length a URDF may give (an origin's distance, a shape's size): the bound a
# pose has (10 km; the ground plane is 200 m across, pybullet_data's largest is 100 m).
# A joint origin of 1e300 m loaded, and the robot's state was NaN from its first step on.
MAX_LENGTH_M = 10_000.0
# The heaviest link and the largest inertia entry (each, in absolute value) a URDF may give,
# the bounds SDF models have too. A 1e300 kg link read NaN from the first step on, and from
# 1e12 kg a box sank through the ground plane; 1e9 kg stood. pybullet_data's heaviest link
# is 33 kg (husky), its largest inertia 100 kg m^2; a loaded mining truck is about 6e5 kg.
MAX_MASS_KG = 1e9
MAX_INERTIA_KG_M2 = 1e9
# The shortest joint axis: 1e-300 0 0 passed as "not all 0", and PyBullet's unit vector
# of it was NaN from the first step on.
MIN_AXIS_LENGTH = 1e-9


class DescriptionError(SetupError, RuntimeError):
    """A robot or model description that cannot be found, read or parsed."""


def resolve_description_path(spec: str) -> str:
    """
    Turn a description reference into an absolute file path.

    Accepted, in this order: ``package://pkg/relative/path`` (an installed
    ROS package's share directory), an existing file path, and a bare name
    found in pybullet_data (``r2d2.urdf``, ``cube.urdf``).
    """
    if spec.startswith(PACKAGE_SCHEME):
        return _resolve_package_uri(spec)
    if os.path.isfile(spec):
        return os.path.abspath(spec)
    if not os.path.isabs(spec):
        candidate = os.path.join(pybullet_data.getDataPath(), spec)
        if os.path.isfile(candidate):
            return candidate
    raise DescriptionError(f'URDF file not found: {spec} (not a file, nor in pybullet_data)')


def _resolve_package_uri(uri: str) -> str:
    package, _, relative = uri[len(PACKAGE_SCHEME):].partition('/')
    if not package or not relative:
        raise DescriptionError(f'malformed package URI {uri!r}: expected package://pkg/path')
    path = os.path.join(package_share_directory(package), relative)
    if not os.path.isfile(path):
        raise DescriptionError(f'URDF file not found: {path} (from {uri})')
    return path


def package_share_directory(package: str) -> str:
    """
    Return the share directory of an installed ROS package, as ``package://`` means it.

    Looked up, in this order: the ament index (colcon workspaces and ROS
    installs, through ``AMENT_PREFIX_PATH``); ``<sys.prefix>/share/<package>``,
    where ``pip install`` puts a package's data files and where nothing sets
    ``AMENT_PREFIX_PATH``; and, for r2d2_sim itself, its source tree.
    """
    from ament_index_python.packages import (
        get_package_share_directory, PackageNotFoundError)
    try:
        return get_package_share_directory(package)
    except (PackageNotFoundError, OSError, ValueError):
        pass  # OSError: AMENT_PREFIX_PATH is unset, as for every pip-only user
    candidates = [os.path.join(sys.prefix, 'share', package)]
    if package == PACKAGE_NAME:
        candidates.append(SOURCE_TREE)
    for candidate in candidates:
        if os.path.isfile(os.path.join(candidate, 'package.xml')):
            return candidate
    raise DescriptionError(
        f'cannot find package {package!r}: {package!r} is not in the ament index '
        f'(AMENT_PREFIX_PATH) nor under {os.path.join(sys.prefix, "share")}')


def default_urdf_path() -> str:
    """
    Return the package's own R2D2 description.

    The copy beside the sources wins (a source checkout, or an editable pip
    install, which installs no data files); otherwise the one installed under
    ``share/r2d2_sim`` by colcon or ``pip install .``.
    """
    source_copy = os.path.join(SOURCE_TREE, 'urdf', 'r2d2.urdf')
    if os.path.isfile(source_copy):
        return source_copy
    try:
        share = package_share_directory(PACKAGE_NAME)
    except DescriptionError as exc:
        raise DescriptionError(f'cannot find the package URDF: {exc}') from None
    return os.path.join(share, 'urdf', 'r2d2.urdf')


def read_description(path: str) -> str:
    """Return the text of a description file, with a one-line error if unreadable."""
    try:  # a regular file only: a FIFO would hold start-up (and SIGINT) forever
        return read_regular(path, MAX_READ_BYTES).decode('utf-8')
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise DescriptionError(f'cannot read {path}: {reason}') from None


def check_urdf_xml(text: str, source: str) -> ElementTree.Element:
    """
    Return the ``<robot>`` of ``text`` if it is a URDF PyBullet can read (:func:`check_urdf`).

    DescriptionError otherwise, ``cannot load source: problem``.
    """
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError as exc:
        raise DescriptionError(f'cannot load {source}: not well-formed XML ({exc})') from None
    if root.tag != 'robot':
        raise DescriptionError(
            f'cannot load {source}: the root element is <{root.tag}>, not <robot>')
    check_urdf(root, f'cannot load {source}')
    return root


def read_urdf(path: str) -> Tuple[str, ElementTree.Element]:
    """
    Return the URDF file ``path``'s text and ``<robot>``, checked as the operator's URDFs are.

    Its tree and numbers (:func:`check_urdf`) and the mesh files PyBullet
    would open (:func:`check_mesh_files`); DescriptionError (one line,
    ``cannot load path: problem``) otherwise.
    """
    text = read_description(path)
    root = check_urdf_xml(text, path)
    check_mesh_files(root, path, f'cannot load {path}')
    return text, root


def urdf_robot_name(path: str) -> str:
    """Return the ``<robot name>`` of the URDF file ``path`` as PyBullet takes it ('' if none)."""
    try:
        for _, element in ElementTree.iterparse(path, events=('start',)):
            return element.get('name', '')  # the root's: nothing more is read
    except (ElementTree.ParseError, OSError):
        pass  # PyBullet refuses it when it is loaded
    return ''


# The joint types PyBullet's URDF reader knows ('spherical' is its own).
URDF_JOINT_TYPES = frozenset(
    ('revolute', 'continuous', 'prismatic', 'fixed', 'floating', 'planar', 'spherical'))


def check_urdf(root: ElementTree.Element, source: str) -> None:
    """
    Raise DescriptionError unless a URDF's ``<robot>`` is one tree PyBullet reads as written.

    Every URDF a user gives passes here before PyBullet sees it (start-up, a
    world's, a spawn's). PyBullet 3.2 kills the whole process (SIGSEGV) on two
    joints of one name, a joint without a name or a type, a link that is the
    child of two joints and a second root link, and silently drops links no
    joint joins to the root: all are refused here in one line, ``source: problem``.
    """
    def refuse(problem: str) -> DescriptionError:
        return DescriptionError(f'{source}: {problem}')
    links = [link.get('name', '') for link in root.findall('link')]
    if not links:
        return  # no tree: PyBullet refuses it itself, or reads a <deformable> (torus_deform.urdf)
    _check_unique(links, 'link', refuse)
    joints = root.findall('joint')
    _check_unique([joint.get('name', '') for joint in joints], 'joint', refuse)
    known = set(links)
    parent_of: Dict[str, str] = {}
    children: Dict[str, List[str]] = {}
    for joint in joints:
        name = joint.get('name', '')[:100]
        kind = joint.get('type', '')
        if kind not in URDF_JOINT_TYPES:
            raise refuse(f'joint {name!r} has type {kind[:40]!r}, not one of '
                         f'{", ".join(sorted(URDF_JOINT_TYPES))}')
        ends = []
        for end in ('parent', 'child'):
            element = joint.find(end)
            link = '' if element is None else element.get('link', '')
            if link not in known:
                raise refuse(f'joint {name!r}: its {end} {link[:100]!r} names no link')
            ends.append(link)
        parent, child = ends
        if child in parent_of:
            raise refuse(f'link {child[:100]!r} is the child of two joints')
        parent_of[child] = parent
        children.setdefault(parent, []).append(child)
    roots = [link for link in links if link not in parent_of]
    if len(roots) != 1:
        shown = ', '.join(repr(link[:100]) for link in roots[:3])
        raise refuse(f'the links must make one tree, but {len(roots)} links are no joint\'s '
                     f'child{": " + shown if roots else " (a loop)"}')
    reached, queue = {roots[0]}, [roots[0]]
    while queue:
        for child in children.get(queue.pop(), []):
            if child not in reached:
                reached.add(child)
                queue.append(child)
    if len(reached) != len(links):
        apart = next(link for link in links if link not in reached)
        raise refuse(f'link {apart[:100]!r} is on a loop of joints, not joined to the root '
                     f'{roots[0][:100]!r}')
    _check_values(root, refuse)


def _check_values(root: ElementTree.Element,
                  refuse: Callable[[str], DescriptionError]) -> None:
    """
    Raise ``refuse``'s error for a number PyBullet would misread, naming the link or joint.

    PyBullet reads an unparsable number as 0 and a vector of fewer than 3 as
    (0, 0, 0), with a warning on stdout only: a box of size ``1 1`` or
    ``a b c`` became size 0, an origin of ``nan`` put NaN in the body's
    bounds, a mass of -5 made a floating static body, a joint axis of 0 0 0
    (or none given) NaN positions. What it cannot simulate is refused too: a
    joint axis shorter than MIN_AXIS_LENGTH (1e-300 0 0), an origin or a
    shape's size beyond MAX_LENGTH_M (1e300) and a mass beyond MAX_MASS_KG
    gave NaN from the first step on, so that a driven robot blew up and was
    put back on every step, for ever (an inertia beyond MAX_INERTIA_KG_M2 on
    a driven robot the same).
    What its own data does and it reads right
    stays: an absent or blank origin (zeros), mass 0 (a static link), a
    vector of more than 3 numbers (the first 3), a number with a comma after
    it (``0.07, 0, -0.69``), a mesh scale of one number (uniform), a visual
    of size 0 (drawn as nothing), lower > upper limits (no limits).
    """
    for link in root.findall('link'):
        name = f'link {link.get("name", "")[:100]!r}'
        for inertial in link.findall('inertial'):
            _check_origins(inertial, f'{name}: inertial', refuse)
            for mass in inertial.findall('mass'):
                _check(mass, 'value', f'{name}: mass', refuse, 1, _at_least_zero,
                       'a finite number >= 0')
                _check(mass, 'value', f'{name}: mass', refuse, 1, _light,
                       f'{MAX_MASS_KG:.0e} kg or less'.replace('e+0', 'e'))
            for inertia in inertial.findall('inertia'):
                for entry in ('ixx', 'ixy', 'ixz', 'iyy', 'iyz', 'izz'):
                    _check(inertia, entry, f'{name}: inertia', refuse, 1, None,
                           'a finite number')
                    _check(inertia, entry, f'{name}: inertia', refuse, 1, _moderate,
                           f'within {MAX_INERTIA_KG_M2:.0e} kg m^2 of 0'.replace('e+0', 'e'))
        for part in ('visual', 'collision'):
            for element in link.findall(part):
                _check_origins(element, f'{name}: {part}', refuse)
                for shape in element.findall('geometry/*'):
                    _check_shape(shape, f'{name}: {part} {shape.tag}', part == 'visual',
                                 refuse)
    for joint in root.findall('joint'):
        name = f'joint {joint.get("name", "")[:100]!r}'
        _check_origins(joint, name, refuse)
        if joint.get('type') in ('revolute', 'continuous', 'prismatic', 'planar'):
            for axis in joint.findall('axis'):
                _check(axis, 'xyz', f'{name}: axis', refuse, 3, _not_all_zero,
                       '3 finite numbers, not all 0', required=True)
                _check(axis, 'xyz', f'{name}: axis', refuse, 3, _long_enough,
                       f'a vector of length {MIN_AXIS_LENGTH:g} or more')
        for limit in joint.findall('limit'):
            for entry in ('lower', 'upper', 'effort', 'velocity'):
                _check(limit, entry, f'{name}: limit', refuse, 1, None, 'a finite number')
        for dynamics in joint.findall('dynamics'):
            for entry in ('damping', 'friction'):
                _check(dynamics, entry, f'{name}: dynamics', refuse, 1, None,
                       'a finite number')


def _check_origins(parent: ElementTree.Element, where: str,
                   refuse: Callable[[str], DescriptionError]) -> None:
    """Check the ``<origin>`` of ``parent``: xyz and rpy absent, blank or 3 finite numbers."""
    for origin in parent.findall('origin'):
        for entry in ('xyz', 'rpy'):
            _check(origin, entry, f'{where} origin', refuse, 3, None, '3 finite numbers',
                   blank=True)
        _check(origin, 'xyz', f'{where} origin', refuse, 3, _near,
               f'within {MAX_LENGTH_M:g} m of its frame', blank=True)


def _check_shape(shape: ElementTree.Element, where: str, visual: bool,
                 refuse: Callable[[str], DescriptionError]) -> None:
    """Check a geometry: its sizes above 0 (a visual's: 0 too), MAX_LENGTH_M at most; a scale."""
    holds, above = (_at_least_zero, '>= 0') if visual else (_above_zero, 'above 0')
    sizes = {'box': ('size',), 'sphere': ('radius',), 'cylinder': ('radius', 'length'),
             'capsule': ('radius', 'length')}.get(shape.tag, ())
    for entry in sizes:
        count, wanted = (3, '3 finite numbers') if entry == 'size' else (1, 'a finite number')
        _check(shape, entry, where, refuse, count, holds, f'{wanted} {above}', required=True)
        _check(shape, entry, where, refuse, count, _small,
               f'{MAX_LENGTH_M:g} m or less' + (' each' if count == 3 else ''))
    if shape.tag == 'mesh' and shape.get('scale') is not None:
        counts = 1 if len(shape.get('scale', '').split()) == 1 else 3
        _check(shape, 'scale', where, refuse, counts, _none_zero,
               '3 finite numbers (or 1), none 0')


def _above_zero(values: List[float]) -> bool:
    return all(value > 0.0 for value in values)


def _at_least_zero(values: List[float]) -> bool:
    return all(value >= 0.0 for value in values)


def _none_zero(values: List[float]) -> bool:
    return all(value != 0.0 for value in values)


def _not_all_zero(values: List[float]) -> bool:
    return any(value != 0.0 for value in values)


def _long_enough(values: List[float]) -> bool:
    return math.hypot(*values) >= MIN_AXIS_LENGTH


def _near(values: List[float]) -> bool:
    return math.hypot(*values) <= MAX_LENGTH_M


def _small(values: List[float]) -> bool:
    return all(value <= MAX_LENGTH_M for value in values)


def _light(values: List[float]) -> bool:
    return all(value <= MAX_MASS_KG for value in values)


def _moderate(values: List[float]) -> bool:
    return all(abs(value) <= MAX_INERTIA_KG_M2 for value in values)


def _check(element: ElementTree.Element, attribute: str, where: str,
           refuse: Callable[[str], DescriptionError], count: int,
           holds: Optional[Callable[[List[float]], bool]], wanted: str,
           required: bool = False, blank: bool = False) -> None:
    """
    Raise ``refuse``'s error unless ``attribute`` is ``count`` finite numbers that hold.

    An absent attribute passes unless ``required`` (PyBullet has a default, or
    refuses it itself); a blank one only when ``blank`` (PyBullet reads zeros).
    A vector (``count`` 3) may have more numbers: PyBullet reads the first 3.
    """
    text = element.get(attribute)
    if text is None and not required or blank and text is not None and not text.strip():
        return
    values = _floats(text or '')
    if values is not None and count == 3:
        values = values[:3] if len(values) >= 3 else None
    if values is None or len(values) != count or (holds is not None and not holds(values)):
        shown = 'none' if text is None else repr(text[:40])
        raise refuse(f'{where} {attribute} {shown} is not {wanted}')


def _first(element: Optional[ElementTree.Element], attribute: str) -> float:
    """Return the first number of an attribute checked already; 0 when absent."""
    values = _floats('' if element is None else element.get(attribute, ''))
    return values[0] if values else 0.0


def _floats(text: str) -> Optional[List[float]]:
    """Return the finite numbers in ``text``, None if any is not one (as C's strtod reads it)."""
    values = []
    for word in text.split():
        word = word[:-1] if word.endswith(',') else word  # strtod stops at the comma
        try:
            value = float(word)
        except ValueError:
            return None
        if '_' in word or not math.isfinite(value):  # Python reads 1_0 as 10, strtod as 1
            return None
        values.append(value)
    return values


def _check_unique(names: List[str], what: str,
                  refuse: Callable[[str], DescriptionError]) -> None:
    """Raise ``refuse``'s error for an empty name or one that is taken twice."""
    seen: Set[str] = set()
    for name in names:
        if not name:
            raise refuse(f'a <{what}> has no name')
        if name in seen:
            raise refuse(f'two {what}s are named {name[:100]!r}')
        seen.add(name)


# The mesh formats PyBullet's URDF reader opens; a file named otherwise it never opens.
PYBULLET_MESH_SUFFIXES = ('.dae', '.stl', '.obj', '.cdf', '.vtk')
# Where PyBullet looks for a mesh beyond the URDF's own directories: from the working
# directory, and up to five levels above it.
_UPWARDS = ('', '../', '../../', '../../../', '../../../../', '../../../../../')


def pybullet_mesh_path(urdf_path: Optional[str], filename: str) -> Optional[str]:
    """
    Return the file PyBullet's loadURDF opens for a ``<mesh filename>``, or None if none.

    As bullet3's UrdfFindMeshFile looks (PyBullet 3.2; its search path, where
    ``loadURDF`` finds pybullet_data's URDFs, is not used for meshes): a
    ``package://`` or ``model://`` in front dropped, the name tried after
    the URDF's own path, after each of its directories from the nearest, then
    from the working directory and up to five levels above it; the first
    that exists and can be read (a directory or a FIFO too: ``fopen`` opens
    both). None for a name it never opens (too short, another format) or
    finds nowhere: PyBullet then refuses the URDF itself, in one line.
    """
    if len(filename) <= 4 or filename[-4:].lower() not in PYBULLET_MESH_SUFFIXES:
        return None
    for scheme in ('package://', 'model://'):
        if filename.startswith(scheme):
            filename = filename[len(scheme):]
            break
    prefixes: List[str] = []
    if urdf_path:
        prefixes.append(urdf_path)
        prefixes += [urdf_path[:i] + '/' for i in range(len(urdf_path) - 1, -1, -1)
                     if urdf_path[i] in '/\\']
    for prefix in prefixes + list(_UPWARDS):
        attempt = prefix + filename
        if os.path.exists(attempt) and os.access(attempt, os.R_OK):
            return attempt
    return None


def check_mesh_files(root: ElementTree.Element, urdf_path: Optional[str], source: str) -> None:
    """
    Raise DescriptionError for a mesh PyBullet would open that is not a regular file.

    ``urdf_path`` is the file PyBullet loads the URDF from (its meshes are
    found from there: :func:`pybullet_mesh_path`). PyBullet 3.2 ends the
    process on a mesh that is a directory (``std::bad_alloc``, exit 134)
    and waits for a writer for ever on a FIFO. For the operator's own URDFs
    (the ``urdf``, ``robot_description``, ``extra_models`` and ``world``
    parameters), whose meshes may lie anywhere; a spawn's or a request's
    world's are held to more (:mod:`r2d2_sim.sim.spawnables`).
    """
    for link in root.findall('link'):
        for part in ('visual', 'collision'):
            for mesh in link.findall(f'{part}/geometry/mesh'):
                filename = mesh.get('filename', '')
                found = pybullet_mesh_path(urdf_path, filename)
                if found is None:
                    continue
                try:
                    facts = os.stat(found)
                except OSError:
                    continue  # gone since: PyBullet finds it nowhere and refuses it itself
                if not stat.S_ISREG(facts.st_mode):
                    where = os.path.abspath(found)[:300]
                    raise DescriptionError(
                        f'{source}: link {link.get("name", "")[:100]!r}: {part} mesh '
                        f'{filename[:200]!r} ({where}) is {describe(facts)}, not a regular file')


def check_robot_inertias(root: ElementTree.Element, source: str) -> None:
    """
    Raise DescriptionError for a driven robot's inertia PyBullet reads as 0 (``source: problem``).

    A driven robot is loaded with its inertias from the file
    (``URDF_USE_INERTIA_FROM_FILE``); other bodies get theirs from their
    shapes, whatever the file says. PyBullet reads an inertia whose
    principal moments are not all >= 0 with none above the other two
    together as 0, with a warning on stdout only; a robot of two such links,
    or one such base on wheels, blew up on its first step, and again on
    every step it was put back. So every link of mass above 0 needs
    principal moments above 0, none above the other two together, as every
    solid's are: one rule a user can follow, though a single such link
    beside a real base (a sensor of 0.1 kg) happened to simulate. A link of
    mass 0 (a static base, a frame) and one without ``<inertial>``
    (PyBullet's 1 kg of inertia 1) are left as they are. The numbers are
    checked ones (:func:`check_urdf`).
    """
    for link in root.findall('link'):
        inertial = link.find('inertial')
        if inertial is None:
            continue
        kg = _first(inertial.find('mass'), 'value')
        if kg <= 0.0:
            continue
        inertia = inertial.find('inertia')
        xx, xy, xz, yy, yz, zz = (_first(inertia, entry)
                                  for entry in ('ixx', 'ixy', 'ixz', 'iyy', 'iyz', 'izz'))
        tensor = numpy.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        low, middle, high = (float(m) for m in numpy.linalg.eigvalsh(tensor))  # ascending
        if low <= 0.0 or high > (low + middle) * (1.0 + 1e-9):
            raise DescriptionError(
                f'{source}: link {link.get("name", "")[:100]!r}: a driven robot\'s link of '
                f'{kg:g} kg needs an inertia of principal moments above 0, none above the '
                f'other two together, not ({low:.3g}, {middle:.3g}, {high:.3g}): PyBullet '
                'reads it as 0')


class DescriptionFile:
    """
    A URDF given as text, written to a temporary file PyBullet can load.

    The text is one its caller has checked (:func:`check_urdf_xml`, or a spawn's
    or a world's own checks): each checked it once, before. The file lives in
    its own temporary directory until :meth:`close`.
    """

    def __init__(self, text: str) -> None:
        self._directory: Optional[str] = tempfile.mkdtemp(prefix='r2d2_sim_')
        self.path = os.path.join(self._directory, 'robot_description.urdf')
        with open(self.path, 'w', encoding='utf-8') as handle:
            handle.write(text)

    def close(self) -> None:
        """Delete the file and its directory; safe to call twice."""
        if self._directory is not None:
            try:
                os.remove(self.path)
                os.rmdir(self._directory)
            except OSError:
                pass
            self._directory = None


class RobotDescription(NamedTuple):
    """A robot's URDF ready to load: a file path, its text, and a temporary file to close."""

    path: str
    text: str
    temporary: Optional[DescriptionFile]

    @staticmethod
    def load(urdf: str = '', text: str = '') -> 'RobotDescription':
        """
        Read a description as the ``urdf`` and ``robot_description`` parameters give it.

        XML ``text`` wins (written to a temporary file PyBullet can load); else
        ``urdf`` resolved as a path, URI or pybullet_data name, else the
        package's own R2D2. DescriptionError (one line) when it cannot be had
        or PyBullet would crash on it (:func:`read_urdf`: its tree, numbers
        and mesh files), or its inertias cannot drive (:func:`check_robot_inertias`).
        """
        if text:
            root = check_urdf_xml(text, 'robot_description')
            check_robot_inertias(root, 'cannot load robot_description')
            temporary = DescriptionFile(text)
            try:  # its meshes are found from where PyBullet reads it
                check_mesh_files(root, temporary.path, 'cannot load robot_description')
            except DescriptionError:
                temporary.close()
                raise
            return RobotDescription(temporary.path, text, temporary)
        path = resolve_description_path(urdf) if urdf else default_urdf_path()
        text, root = read_urdf(path)
        check_robot_inertias(root, f'cannot load {path}')
        return RobotDescription(path, text, None)

    def close(self) -> None:
        """Delete the temporary file, if there is one."""
        if self.temporary is not None:
            self.temporary.close()
