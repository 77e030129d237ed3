"""
Reading SDF's XML safely and within bounds: elements, numbers, poses, and where they are.

No ROS, no PyBullet. SDF files come from any peer on the ROS domain (LoadWorld,
SpawnEntity) or from directories the operator listed, so every file is parsed
by defusedxml (no DOCTYPE, no entities, no external references) and counted
against a :class:`Budget` (files, elements, include depth). Every value is
read through a :class:`Place`, which names the file and the element in the
one-line RESOURCE_PARSE_ERROR a bad value gets, never the file's text.
"""

import errno
import math
import re
from typing import Optional, overload, Protocol, Sequence, Tuple
import xml.etree.ElementTree as ElementTree

from defusedxml import DefusedXmlException
import defusedxml.ElementTree as SafeElementTree

from r2d2_sim.errors import RefusedError
from r2d2_sim.files import read_regular, UnsafeFile
from r2d2_sim.model.health import MAX_DISTANCE_M
from r2d2_sim.model.sdf_poses import FrameError, pose_from_values
from r2d2_sim.model.transforms import IDENTITY, Transform

__all__ = ['Budget', 'Place', 'Notes', 'FileNotes', 'parse_xml', 'local_tag', 'read_limited',
           'root_tag', 'MAX_SDF_FILES', 'MAX_SDF_ELEMENTS', 'MAX_INCLUDE_DEPTH', 'PARSE']

PARSE = 'RESOURCE_PARSE_ERROR'
# What one world may cost to read, all its files together (turtlebot3_world: 3 files and
# 120 elements; AWS's small house: 69 files and about 7,000 elements).
MAX_SDF_FILES = 1000
MAX_SDF_ELEMENTS = 200_000
MAX_INCLUDE_DEPTH = 16
_NAMESPACED = re.compile(r'\{[^}]*\}')
# What root_tag reads of a text: the root element is in its first 100 kB or taken as absent.
ROOT_SEARCH_CHARS = 100_000
_XML_SPACE = ' \t\r\n'
_NAME_START = frozenset('ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz_')


class Budget:
    """What the files of one world may cost together: files, elements, include depth."""

    def __init__(self) -> None:
        self.files = MAX_SDF_FILES
        self.elements = MAX_SDF_ELEMENTS
        self.files_left = self.files
        self.elements_left = self.elements

    def take(self, root: ElementTree.Element, shown: str) -> None:
        """Count one file read (an include each time) and its elements; refuse past the budget."""
        self.files_left -= 1
        if self.files_left < 0:
            raise RefusedError(PARSE, f'{shown}: the world reads more than {self.files} files '
                                      '(includes counted each time)')
        self.elements_left -= sum(1 for _ in root.iter())
        if self.elements_left < 0:
            raise RefusedError(PARSE, f'{shown}: the world has more than {self.elements} XML '
                                      'elements in all its files')


def read_limited(path: str, shown: str, code: str, limit: int) -> str:
    """
    Read a regular file of at most ``limit`` bytes as UTF-8; ``code`` if it is not there.

    Read by :func:`r2d2_sim.files.read_regular`: a FIFO or a device is
    refused at once (opened the usual way, a FIFO waits for a writer forever).
    """
    try:
        data = read_regular(path, limit)
    except UnsafeFile as exc:
        if exc.errno == errno.EFBIG:
            raise RefusedError(PARSE, f'{shown} is larger than {limit} bytes') from None
        raise RefusedError(code, f'{shown} is not a regular file') from None
    except (FileNotFoundError, NotADirectoryError):
        raise RefusedError(code, f'{shown}: no such file') from None
    except OSError:
        raise RefusedError(code, f'{shown} cannot be read') from None
    try:
        return data.decode('utf-8')
    except UnicodeDecodeError:
        raise RefusedError(PARSE, f'{shown} is not UTF-8 text') from None


def root_tag(text: str) -> str:
    """
    Return the name of an XML text's root element, read without parsing ('' if none).

    One pass over the prolog: white space, the XML declaration, processing
    instructions and comments are each skipped with one ``str.find``, so
    the work is linear in the text. A regular expression with ``.*?``
    across comments backtracks instead: ``'<!---->' * 27`` before no root
    held every service 47 s. A DOCTYPE, or no root within
    ROOT_SEARCH_CHARS, gives ''.
    """
    end = min(len(text), ROOT_SEARCH_CHARS)
    at = 0
    while True:
        while at < end and text[at] in _XML_SPACE:
            at += 1
        if text.startswith('<!--', at):
            close, skip = text.find('-->', at + 4, end), 3
        elif text.startswith('<?', at):
            close, skip = text.find('?>', at + 2, end), 2
        else:
            break
        if close < 0:
            return ''
        at = close + skip
    if not text.startswith('<', at) or at + 1 >= end or text[at + 1] not in _NAME_START:
        return ''
    name_end = at + 2
    while name_end < end and (text[name_end].isalnum() or text[name_end] in '_.:-'):
        name_end += 1
    return text[at + 1:name_end]


def parse_xml(text: str, shown: str) -> ElementTree.Element:
    """Return the root element of ``text``; RESOURCE_PARSE_ERROR (naming ``shown``) if bad."""
    try:
        return SafeElementTree.fromstring(text, forbid_dtd=True, forbid_entities=True,
                                          forbid_external=True)
    except DefusedXmlException:
        raise RefusedError(PARSE, f'{shown} declares a DOCTYPE or entities, which SDF does '
                                  'not need') from None
    except ElementTree.ParseError as exc:
        raise RefusedError(PARSE, f'{shown}: not well-formed XML ({exc})') from None


def local_tag(element: ElementTree.Element) -> str:
    """Return an element's tag without its namespace (``{uri}tag`` -> ``tag``)."""
    return _NAMESPACED.sub('', element.tag) if isinstance(element.tag, str) else ''


def _truth(text: str) -> Optional[bool]:
    value = text.strip().lower()
    return True if value in ('true', '1') else False if value in ('false', '0') else None


class Place:
    """
    Where an element is: its file (as shown) and the path of named elements down to it.

    ``str(place)`` reads ``room.sdf: model wall, link base`` (without the
    file when ``shown`` is '': the caller names it); every reader here raises
    RESOURCE_PARSE_ERROR naming the place and the child element.
    """

    def __init__(self, shown: str, path: Tuple[str, ...] = ()) -> None:
        self.shown = shown
        self.path = path

    def child(self, element: ElementTree.Element) -> 'Place':
        """Return the place of a child element (named by its ``name`` attribute)."""
        name = element.get('name')
        step = local_tag(element) + (f' {name[:100]}' if name is not None else '')
        return Place(self.shown, self.path + (step,))

    def __str__(self) -> str:
        if not self.shown:  # the file the caller names itself (a world read_world reads)
            return ', '.join(self.path) or 'the file'
        return self.shown + (': ' + ', '.join(self.path) if self.path else '')

    def fail(self, problem: str, code: str = PARSE) -> RefusedError:
        """Return the one-line refusal of a problem found here."""
        return RefusedError(code, f'{self}: {problem}')

    def name(self, element: ElementTree.Element) -> str:
        """Return an element's required ``name`` attribute (1 to 255 characters)."""
        name = element.get('name', '')
        if not name or len(name) > 255:
            raise self.fail(f'a <{local_tag(element)}> needs a name of 1 to 255 characters')
        return name

    @overload
    def text(self, element: ElementTree.Element, tag: str, default: str) -> str:
        ...

    @overload
    def text(self, element: ElementTree.Element, tag: str, default: None = None
             ) -> Optional[str]:
        ...

    def text(self, element: ElementTree.Element, tag: str, default: Optional[str] = None
             ) -> Optional[str]:
        """Return the stripped text of child ``tag`` (``default`` when it is absent)."""
        child = element.find(tag)
        return default if child is None else (child.text or '').strip()

    @overload
    def numbers(self, element: ElementTree.Element, tag: str, count: int,
                default: Sequence[float]) -> Tuple[float, ...]:
        ...

    @overload
    def numbers(self, element: ElementTree.Element, tag: str, count: int,
                default: None = None) -> Optional[Tuple[float, ...]]:
        ...

    def numbers(self, element: ElementTree.Element, tag: str, count: int,
                default: Optional[Sequence[float]] = None) -> Optional[Tuple[float, ...]]:
        """Return the ``count`` finite numbers of child ``tag`` (``default`` when absent)."""
        text = self.text(element, tag)
        if text is None:
            return None if default is None else tuple(default)
        try:
            values = tuple(float(v) for v in text.split())
        except ValueError:
            values = ()
        if len(values) != count or not all(math.isfinite(v) for v in values):
            raise self.fail(f'<{tag}> must be {count} finite number{"s" * (count > 1)}')
        return values

    @overload
    def number(self, element: ElementTree.Element, tag: str, default: float,
               low: float = -math.inf, high: float = math.inf) -> float:
        ...

    @overload
    def number(self, element: ElementTree.Element, tag: str, default: None = None,
               low: float = -math.inf, high: float = math.inf) -> Optional[float]:
        ...

    def number(self, element: ElementTree.Element, tag: str, default: Optional[float] = None,
               low: float = -math.inf, high: float = math.inf) -> Optional[float]:
        """Return child ``tag``'s number, within [low, high] (``default`` when absent)."""
        values = self.numbers(element, tag, 1, None if default is None else (default,))
        if values is None:
            return None
        if not low <= values[0] <= high:
            raise self.fail(f'<{tag}> must lie in [{low:g}, {high:g}]')
        return values[0]

    def truth(self, element: ElementTree.Element, tag: str, default: bool) -> bool:
        """Return child ``tag`` as a boolean (true, false, 1, 0)."""
        text = self.text(element, tag)
        if text is None:
            return default
        value = _truth(text)
        if value is None:
            raise self.fail(f'<{tag}> must be true or false')
        return value

    def pose(self, element: ElementTree.Element) -> Tuple[Transform, str]:
        """
        Return an element's ``<pose>`` and the frame it is relative to ('' by default).

        SDF 1.9's ``rotation_format="quat_xyzw"`` and ``degrees="true"`` are
        read; an empty pose is the identity.
        """
        pose = element.find('pose')
        if pose is None:
            return IDENTITY, ''
        relative_to = pose.get('relative_to', '')
        text = (pose.text or '').strip()
        if not text:
            return IDENTITY, relative_to
        quaternion = pose.get('rotation_format', 'euler_rpy') == 'quat_xyzw'
        degrees = _truth(pose.get('degrees', 'false'))
        if pose.get('rotation_format', 'euler_rpy') not in ('euler_rpy', 'quat_xyzw') or \
                degrees is None:
            raise self.fail('<pose> has a rotation_format or degrees it cannot have')
        try:
            transform = pose_from_values([float(v) for v in text.split()], quaternion,
                                         bool(degrees))
        except (ValueError, FrameError) as exc:
            problem = str(exc) if isinstance(exc, FrameError) else 'a pose is numbers'
            raise self.fail(f'<pose>: {problem}') from None
        if max(map(abs, transform.translation)) > MAX_DISTANCE_M:
            raise self.fail(f'<pose> is more than {MAX_DISTANCE_M:g} m out')
        return transform, relative_to


class Notes(Protocol):
    """What a part of a world tells of what it does not simulate (counted by what it is)."""

    def note(self, what: str) -> None:
        """Count one element that is not simulated (``what``: its tag or kind)."""


class FileNotes(Notes, Protocol):
    """Notes that also find a mesh's file, for the parts of one file."""

    def mesh(self, uri: str, place: Place) -> Optional[str]:
        """Return a mesh's path; None (noted as left out) when missing and that is allowed."""
