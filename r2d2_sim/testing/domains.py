"""
ROS domain leases: each harness gets a ROS domain id that no other test on this machine uses.

Two mechanisms are held together, so every ROS test on the machine agrees:
our own ``flock`` on a file per id, and the one of ROS's own test tooling,
``domain_coordinator`` (used by launch_testing's ``add_ros_test`` and
ament_cmake_ros' isolated test runner), which reserves an id by binding TCP
port 32768 + id. A domain is ours only when we hold both; a colcon test run
beside an r2d2_sim suite then never picks the same domain. The port is one
per machine, so it also keeps apart the harnesses of two users, whose lock
files are in directories of their own.

A lease ends when it is released or when the last process holding it ends:
a child given its descriptors (:attr:`DomainLease.fds`, as ``SimProcess``
gives them to ``sim_node``) keeps it held after its parent died, so a
simulator that outlives its test never shares its domain.

The lock files are in a directory only their owner can write
(``$TMPDIR/r2d2_sim-domains-<uid>``, 0700), checked before use and opened
without following symbolic links: another user cannot make us create or lock
a file of their choosing. A lock file that is not a plain file of ours is
skipped (that domain counts as taken); a lock directory that is not ours is
refused with one line.

Domain ids come from ``R2D2_SIM_DOMAIN_IDS`` ("first-last", default 1-100),
read at each lease. Fast DDS maps domain d to UDP ports from 7400 + 250 * d:
up to about 100 they stay below the kernel's ephemeral range (32768+), where
another program's socket could already hold them. Domain 0, the default, is
left to the user's own ROS graph.
"""

import errno
import fcntl
import itertools
import numbers
import os
from pathlib import Path
import socket
import stat
import tempfile
import time
from typing import Any, Dict, Optional, Set, Tuple

from r2d2_sim.files import describe, open_private_directory, UnsafeFile

__all__ = ['DOMAIN_LOCK_DIR_ENV', 'DOMAIN_IDS_ENV', 'COORDINATOR_PORT_BASE',
           'DomainUnavailable', 'DomainLease', 'domain_ids', 'domain_lock_dir',
           'lease_domain', 'env_domain_id', 'held_here']

DOMAIN_IDS_ENV = 'R2D2_SIM_DOMAIN_IDS'
# A directory for the per-domain lock files instead of the default below.
DOMAIN_LOCK_DIR_ENV = 'R2D2_SIM_DOMAIN_LOCK_DIR'
# domain_coordinator's reservation: a bound TCP port at this base + the id.
COORDINATOR_PORT_BASE = 32768
# How often a waiting lease_domain tries again (s).
DOMAIN_RETRY_S = 0.05
# The largest ROS domain id handed out. Fast DDS refuses 233 and up ("Calculated
# port number is too high"); at 232 its port formula (7400 + 250 * d + 11 + 2 * p
# for participant p) passes 65535 from the 64th participant on: we stay below 232.
MAX_DOMAIN_ID = 231


def domain_ids() -> range:
    """Return the ids harnesses may lease now: ``R2D2_SIM_DOMAIN_IDS`` ("first-last") or 1-100."""
    text = os.environ.get(DOMAIN_IDS_ENV, '1-100')
    try:
        first, last = (int(part) for part in text.split('-'))
    except ValueError:
        raise ValueError(f'{DOMAIN_IDS_ENV} must be "first-last", e.g. "1-100", '
                         f'got {text!r}') from None
    if not 0 <= first <= last <= MAX_DOMAIN_ID:
        raise ValueError(f'{DOMAIN_IDS_ENV} must lie within 0-{MAX_DOMAIN_ID}, got {text!r}')
    return range(first, last + 1)


def __getattr__(name: str) -> Any:
    # DOMAIN_IDS reads the environment when asked, not once at import.
    if name == 'DOMAIN_IDS':
        return domain_ids()
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


class DomainUnavailable(RuntimeError):
    """No ROS domain could be leased: none came free in time, or the lock directory is unsafe."""


class DomainLease:
    """
    An exclusive claim on one ROS domain id among the processes of this machine.

    Held as an exclusive ``flock`` on a file per domain id plus
    domain_coordinator's bound port, so two leases never share a domain,
    whether they are in one process or in several (pytest-xdist workers, a
    launch_testing run beside). It ends when released and the last process
    holding :attr:`fds` (this one, and the children it gave them to) has ended.
    """

    def __init__(self, domain_id: int, fd: int, port: Optional[socket.socket] = None) -> None:
        self.domain_id = domain_id
        self._fd: Optional[int] = fd
        self._port = port
        self._pid = os.getpid()
        _held.add(self)

    @property
    def held(self) -> bool:
        """Return True until released."""
        return self._fd is not None

    @property
    def fds(self) -> Tuple[int, ...]:
        """
        Return the descriptors that hold the lease (none once released).

        Give them to a child that runs on the domain (``Popen(pass_fds=...)``):
        the lease then lasts as long as that child too, even past this
        process's death. They are not inherited otherwise.
        """
        if self._fd is None:
            return ()
        return (self._fd,) + ((self._port.fileno(),) if self._port is not None else ())

    def release(self) -> None:
        """Give the domain back (closing the file drops the lock); safe to call twice."""
        if self._port is not None:
            self._port.close()
            self._port = None
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        _held.discard(self)

    def __enter__(self) -> 'DomainLease':
        return self

    def __exit__(self, *exc_info: Any) -> None:
        self.release()

    def __repr__(self) -> str:
        return f'DomainLease({self.domain_id}, held={self.held})'


# The leases taken in this process and not released yet (a forked child's copy is not ours).
_held: Set[DomainLease] = set()


def held_here(domain_id: int) -> bool:
    """Return True when a lease of this process (not released yet) holds ``domain_id``."""
    pid = os.getpid()
    return any(lease.domain_id == domain_id and lease._pid == pid and lease.held
               for lease in list(_held))


# Where the next free-domain search starts in this process: spread by process
# id so xdist workers do not all race for domain 1, then rotated so a domain
# just released is not reused at once.
_search_starts = itertools.count(os.getpid())


def _lock_dir_path() -> Path:
    configured = os.environ.get(DOMAIN_LOCK_DIR_ENV)
    if configured:
        return Path(configured)
    return Path(tempfile.gettempdir()) / f'r2d2_sim-domains-{os.getuid()}'


def _open_lock_dir() -> Tuple[Path, int]:
    """
    Create (0700) or find the lock directory, check it and return it with an open descriptor.

    The directory must be a real directory (not a link), owned by this user
    and writable by nobody else (:func:`r2d2_sim.files.open_private_directory`,
    which the mesh cache holds its directory to as well); the lock files are
    then opened relative to the descriptor, so the path cannot be swapped under us.
    """
    path = _lock_dir_path()
    try:
        return path, open_private_directory(str(path))
    except UnsafeFile as exc:
        raise DomainUnavailable(f'the domain lock directory {exc.strerror}: remove it or set '
                                f'{DOMAIN_LOCK_DIR_ENV} to a directory of your own') from None


def domain_lock_dir() -> Path:
    """
    Return the directory of the per-domain lock files, created and checked.

    ``$R2D2_SIM_DOMAIN_LOCK_DIR``, else ``r2d2_sim-domains-<uid>`` in the
    temporary directory; raises :class:`DomainUnavailable` (one line) if it
    is a link, not a directory, not ours or writable by others.
    """
    path, fd = _open_lock_dir()
    os.close(fd)
    return path


class _Unusable(Exception):
    """A lock file we must not use (a link, a directory, another's file): its domain is taken."""


def _try_lock(dir_fd: int, domain_id: int) -> Optional[int]:
    """
    Return an fd holding the exclusive lock of ``domain_id``, or None if another holder has it.

    Raises _Unusable for an entry that is not a plain file of ours (never
    followed if it is a link).
    """
    name = f'domain-{domain_id}.lock'
    try:
        fd = os.open(name, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600,
                     dir_fd=dir_fd)
    except OSError as exc:
        try:
            what = f'{name} is {describe(os.lstat(name, dir_fd=dir_fd))}'
        except OSError:
            what = f'{name}: {exc.strerror}'
        raise _Unusable(what) from None
    facts = os.fstat(fd)
    if not stat.S_ISREG(facts.st_mode) or facts.st_uid != os.getuid():
        os.close(fd)
        owner = '' if facts.st_uid == os.getuid() else f' of user id {facts.st_uid}'
        raise _Unusable(f'{name} is {describe(facts)}{owner}')
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        os.close(fd)
        if exc.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
            return None
        raise _Unusable(f'{name} cannot be locked ({exc.strerror})') from None
    return fd


def _try_coordinator_port(domain_id: int) -> Optional[socket.socket]:
    """Bind domain_coordinator's port for ``domain_id`` as it does; None if someone holds it."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        sock.bind(('', COORDINATOR_PORT_BASE + domain_id))
    except OSError:
        sock.close()
        return None
    return sock


def _try_lease(dir_fd: int, domain_id: int) -> Optional[DomainLease]:
    fd = _try_lock(dir_fd, domain_id)
    if fd is None:
        return None
    port = _try_coordinator_port(domain_id)
    if port is None:
        os.close(fd)
        return None
    return DomainLease(domain_id, fd, port)


def lease_domain(domain_id: Optional[int] = None, timeout_s: float = 60.0) -> DomainLease:
    """
    Lease a ROS domain id that no other lease on this machine holds.

    :param domain_id: that id (waiting for its current holder); None for any
        free id of :func:`domain_ids`
    :param timeout_s: how long to wait for one to come free (wall clock)
    :raises DomainUnavailable: none came free in time, the lock file of
        ``domain_id`` (or of every id) is unusable, or the lock directory is
        unsafe (see :func:`domain_lock_dir`)
    :raises ValueError: ``domain_id`` outside 0-231, or a malformed ``R2D2_SIM_DOMAIN_IDS``

    Release the lease when done (or use it as a context manager); the
    harnesses do.
    """
    if domain_id is not None and (isinstance(domain_id, bool)
                                  or not isinstance(domain_id, numbers.Integral)
                                  or not 0 <= domain_id <= MAX_DOMAIN_ID):
        raise ValueError(f'a ROS domain id is an integer 0-{MAX_DOMAIN_ID}, got {domain_id!r}')
    directory, dir_fd = _open_lock_dir()
    try:
        return _lease_in(directory, dir_fd, domain_id, timeout_s)
    finally:
        os.close(dir_fd)


def _lease_in(directory: Path, dir_fd: int, domain_id: Optional[int],
              timeout_s: float) -> DomainLease:
    deadline = time.monotonic() + timeout_s
    unusable: Dict[int, str] = {}
    while True:
        if domain_id is not None:
            candidates = [domain_id]
        else:
            ids = domain_ids()
            start = next(_search_starts)
            candidates = [ids[(start + i) % len(ids)] for i in range(len(ids))]
        for candidate in candidates:
            try:
                lease = _try_lease(dir_fd, candidate)
            except _Unusable as exc:
                unusable[candidate] = str(exc)
                continue
            if lease is not None:
                return lease
        squatted = ''
        if unusable:
            one = len(unusable) == 1
            squatted = (f'; in {directory}, {"; ".join(unusable.values())}, not '
                        f'{"a plain file" if one else "plain files"} of ours: remove '
                        f'{"it" if one else "them"}')
            if set(candidates) <= set(unusable):  # waiting changes nothing
                raise DomainUnavailable(f'cannot lease {_wanted(domain_id)}{squatted}')
        if time.monotonic() > deadline:
            if domain_id is not None and held_here(domain_id):
                raise DomainUnavailable(
                    f'could not lease domain {domain_id} within {timeout_s:g} s: this process '
                    'holds it (another harness of its own, not closed yet)')
            raise DomainUnavailable(
                f'could not lease {_wanted(domain_id)} within {timeout_s:g} s: other '
                f'harnesses hold the locks in {directory} or domain_coordinator ports '
                f'({COORDINATOR_PORT_BASE} + id){squatted}')
        time.sleep(DOMAIN_RETRY_S)


def _wanted(domain_id: Optional[int]) -> str:
    return f'domain {domain_id}' if domain_id is not None else 'a free domain'


def env_domain_id() -> Optional[int]:
    """Return ``ROS_DOMAIN_ID`` from the environment as an int (None when unset or empty)."""
    value = os.environ.get('ROS_DOMAIN_ID', '').strip()
    if not value:
        return None
    try:
        return int(value)
    except ValueError:
        raise ValueError(f'ROS_DOMAIN_ID must be an integer, got {value!r}') from None
