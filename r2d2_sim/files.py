"""
Files others may have written, read safely, and directories only we may write: for every layer.

Worlds, models and meshes come from any peer on the ROS domain, and the
machine is shared: another user can leave a FIFO where a mesh should be, or
plant files in a cache directory they can write. So:

- :func:`read_regular` opens without blocking and reads only a regular file,
  checked on the descriptor it reads (a FIFO opened the usual way waits for a
  writer forever, and the node stops answering SIGINT; checking the path
  first leaves a moment to swap it), at most ``limit`` bytes;
- :func:`open_private_directory` and :func:`check_private` hold a directory
  or file to what the domain leases' lock directory is held to (the
  first user of this check): a real directory (or regular file), not a
  symbolic link, owned by this user and writable by nobody else.

Errors are :class:`UnsafeFile` (an ``OSError``: callers that already turn an
unreadable file into one line do so for these too), with a message that
names the path and what is wrong, never the file's contents. No imports from
the package: the physics, the core and the testing API all use it.
"""

import errno
import os
import stat
from typing import Optional

__all__ = ['UnsafeFile', 'read_regular', 'open_private_directory', 'check_private',
           'make_private_directories', 'describe']


class UnsafeFile(OSError):
    """A path that is not what it must be: not a regular file, too large, or not private."""


def describe(facts: os.stat_result) -> str:
    """Name what a path is, for a message: a symbolic link, a directory, a plain file..."""
    mode = facts.st_mode
    if stat.S_ISLNK(mode):
        return 'a symbolic link'
    if stat.S_ISDIR(mode):
        return 'a directory'
    if stat.S_ISREG(mode):
        return 'a plain file'
    return 'a special file (a FIFO, socket or device)'


def read_regular(path: str, limit: int) -> bytes:
    """
    Return the bytes of the regular file ``path``, which must hold at most ``limit`` bytes.

    Opened with O_NONBLOCK (a FIFO then opens at once instead of waiting for
    a writer) and checked on that descriptor: UnsafeFile for anything but a
    regular file, or one larger than ``limit`` (by its size, and by what was
    read: a file growing meanwhile). OSError (FileNotFoundError...) when it
    cannot be opened.
    """
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        facts = os.fstat(fd)
        if not stat.S_ISREG(facts.st_mode):
            raise UnsafeFile(errno.EINVAL, f'{describe(facts)}, not a regular file', path)
        if facts.st_size > limit:
            raise UnsafeFile(errno.EFBIG, f'larger than {limit} bytes', path)
        chunks, left = [], limit + 1
        while left > 0:
            chunk = os.read(fd, min(left, 1 << 20))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
    finally:
        os.close(fd)
    data = b''.join(chunks)
    if len(data) > limit:
        raise UnsafeFile(errno.EFBIG, f'larger than {limit} bytes', path)
    return data


def _problem(facts: os.stat_result, directory: bool) -> Optional[str]:
    """Return why a path's facts are not private (None when they are)."""
    wanted = stat.S_ISDIR if directory else stat.S_ISREG
    if not wanted(facts.st_mode):
        return f'is {describe(facts)}, not {"a directory" if directory else "a plain file"}'
    if facts.st_uid != os.getuid():
        return f'belongs to user id {facts.st_uid}, not to us ({os.getuid()})'
    if facts.st_mode & 0o022:
        return f'is writable by others (mode {stat.S_IMODE(facts.st_mode):o})'
    return None


def check_private(path: str, directory: bool = True) -> None:
    """
    Raise UnsafeFile unless ``path`` is a directory (or a plain file) only we may write.

    Not followed if it is a symbolic link (that is refused): it must be ours,
    and neither group nor others may write it. The message reads
    ``<path> belongs to user id 1001, not to us (1000)``.
    """
    try:
        facts = os.lstat(path)
    except OSError as exc:
        raise UnsafeFile(exc.errno, f'{path} cannot be read ({exc.strerror})', path) from None
    problem = _problem(facts, directory)
    if problem is not None:
        raise UnsafeFile(errno.EPERM, f'{path} {problem}', path)


def _checked(fd: int, path: str, tighten: bool) -> int:
    """
    Return ``fd`` (a directory's) when it is private; UnsafeFile (``fd`` closed) otherwise.

    ``tighten``: a directory of ours that group or others may write is made 0700 first.
    """
    facts = os.fstat(fd)
    if tighten and stat.S_ISDIR(facts.st_mode) and facts.st_uid == os.getuid() and \
            facts.st_mode & 0o022:
        os.fchmod(fd, 0o700)
        facts = os.fstat(fd)
    problem = _problem(facts, True)
    if problem is not None:
        os.close(fd)
        raise UnsafeFile(errno.EPERM, f'{path} {problem}', path)
    return fd


def _open_directory(name: str, path: str, dir_fd: Optional[int] = None) -> int:
    """Open the directory ``name`` (relative to ``dir_fd``) without following a link."""
    try:
        return os.open(name, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC,
                       dir_fd=dir_fd)
    except OSError as exc:
        try:
            what = describe(os.lstat(name, dir_fd=dir_fd))
        except OSError:
            what = exc.strerror or 'not there'
        raise UnsafeFile(errno.ENOTDIR, f'{path} is {what}, not a directory', path) from None


def open_private_directory(path: str, tighten: bool = False) -> int:
    """
    Create (0700) or find the directory ``path``, check it, and return a descriptor of it.

    The directory must be a real directory (not a link), owned by this user
    and writable by nobody else; files are then best opened relative to the
    descriptor, so the path cannot be swapped under them. Its parent is
    created as needed. ``tighten``: a directory of ours that group or others
    may write is made 0700 (one we made before with a looser umask) instead
    of refused. UnsafeFile (one line naming the path) otherwise.
    """
    try:
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        os.mkdir(path, 0o700)
    except FileExistsError:
        pass
    except OSError as exc:
        raise UnsafeFile(exc.errno, f'{path} cannot be created ({exc.strerror})',
                         path) from None
    return _checked(_open_directory(path, path), path, tighten)


def make_private_directories(root: str, *names: str, tighten: bool = False) -> str:
    """
    Return ``root/names...``, each level created 0700 where missing and each checked private.

    ``root`` is created and checked as :func:`open_private_directory` does;
    every level below is opened relative to the one above, never through a
    link, and held to the same: ours, writable by nobody else (``tighten``:
    made so, when ours). UnsafeFile otherwise. Returns the deepest path.
    """
    fd = open_private_directory(root, tighten)
    path = root
    try:
        for name in names:
            path = os.path.join(path, name)
            try:
                os.mkdir(name, 0o700, dir_fd=fd)
            except FileExistsError:
                pass
            except OSError as exc:
                raise UnsafeFile(exc.errno, f'{path} cannot be created ({exc.strerror})',
                                 path) from None
            child = _open_directory(name, path, fd)
            os.close(fd)
            fd = -1
            fd = _checked(child, path, tighten)
    finally:
        if fd >= 0:
            os.close(fd)
    return path
