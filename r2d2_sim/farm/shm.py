"""
Fast DDS shared-memory segments a killed farm task leaves: noted while it runs, removed after.

Fast DDS (Jazzy's rmw_fastrtps) gives each participant files in
``/dev/shm``: its own segment (``fastrtps_<16 hex>`` and its ``_el`` lock),
the ports it listens on (``fastrtps_port<N>``, ``_el``, and the named
semaphore ``sem.fastrtps_port<N>_mutex``) and, for data sharing,
``fast_datasharing_*``. A participant that closes removes them; one whose
process is killed leaves them, and stale segments fill ``/dev/shm`` (Fast-DDS
#2790) or block the next participant on that port (rmw_fastrtps #812).

Only ours are removed, never another program's: a farm task notes the
segments its process holds (:func:`note`, after its simulator is built,
again after the user's nodes are added, and every :data:`NOTE_PERIOD_S` while
it runs: :func:`noting`, for the ports Fast DDS opens later) in a file of its own in a private
directory of this host (``$TMPDIR/r2d2_sim-farm-<uid>/tasks/<pid>-<start
time>``); a task that ends normally forgets them (:func:`forget`). When a
task's process is gone (its id and start time no longer name a live process:
an id reused by another process is not taken for it), :func:`clean_dead`
removes each segment it noted that no live process maps or holds open, or
that it owned and nobody owns now (the same file, noted with its inode while
the task held its ``_el`` lock, and that lock free: a zombie, which live
senders may still map; Fast DDS's own test), and its note once none is left
(one another process uses, a new owner's, stays noted for a later call).
A segment is removed only while the sweep holds its ``_el`` lock itself, and
its lock file and semaphore only with it. Anyone on the host may call it,
one sweep at a time: the local pool after a worker dies and at the end of a
run, every task on a cluster's host as it starts, and the farm on every host
at the end.
"""

import contextlib
import fcntl
import os
from pathlib import Path
import re
import stat as stat_module
import tempfile
import threading
from typing import Dict, Iterable, Iterator, List, Optional, Set, Tuple

__all__ = ['SHM_DIR', 'note', 'noting', 'forget', 'clean_dead', 'segments_of',
           'registry_dir', 'in_use', 'NOTE_PERIOD_S']

SHM_DIR = Path('/dev/shm')
# The files Fast DDS makes in /dev/shm (and the lock and semaphore beside a segment).
_FAST_DDS = re.compile(r'^(?:sem\.)?(?:fastrtps_|fast_datasharing)')
_PORT = re.compile(r'^fastrtps_port(\d+)$')
# A locked file in /proc/locks: major:minor:inode (the device's numbers in hex).
_LOCKED_FILE = re.compile(r'^([0-9a-f]+):([0-9a-f]+):(\d+)$')
# How often a running task notes its segments again (wall s): a port Fast DDS opens after
# the last note and before a kill is the only thing a killed task can leave.
NOTE_PERIOD_S = 0.2
_NOTE_LOCK = threading.Lock()


def registry_dir() -> Path:
    """Return this user's directory of task notes on this host (made 0700)."""
    path = Path(tempfile.gettempdir()) / f'r2d2_sim-farm-{os.getuid()}' / 'tasks'
    path.mkdir(mode=0o700, parents=True, exist_ok=True)
    return path


def _start_time(pid: int) -> Optional[str]:
    """Return a process's start time (clock ticks since boot), or None if it is gone."""
    try:
        with open(f'/proc/{pid}/stat', encoding='utf-8') as stat:
            # The command name may hold spaces and parentheses: fields follow the last ')'.
            return stat.read().rsplit(')', 1)[1].split()[19]
    except (OSError, IndexError):
        return None


def segments_of(pid: str = 'self') -> Set[str]:
    """Return the Fast DDS files in /dev/shm that process ``pid`` maps or holds open."""
    found: Set[str] = set()
    try:
        with open(f'/proc/{pid}/maps', encoding='utf-8', errors='replace') as maps:
            for line in maps:
                at = line.find('/dev/shm/')
                if at >= 0:
                    name = line[at + 9:].rstrip('\n').removesuffix(' (deleted)')
                    if _FAST_DDS.match(name):
                        found.add(name)
    except OSError:
        return found
    fd_dir = f'/proc/{pid}/fd'
    try:
        descriptors = os.listdir(fd_dir)
    except OSError:
        return found
    for fd in descriptors:
        try:
            target = os.readlink(f'{fd_dir}/{fd}')
        except OSError:
            continue
        if target.startswith('/dev/shm/') and _FAST_DDS.match(target[9:]):
            found.add(target[9:])
    return found


def _with_companions(names: Iterable[str]) -> Set[str]:
    """Add the lock file and semaphore Fast DDS keeps beside each segment."""
    every = set(names)
    for name in list(every):
        if not _is_segment(name):
            continue
        every.add(name + '_el')
        if _PORT.match(name):
            every.add(f'sem.{name}_mutex')
    return every


def _note_path(pid: int) -> Optional[Path]:
    start = _start_time(pid)
    return None if start is None else registry_dir() / f'{pid}-{start}'


def note() -> None:
    """
    Note the Fast DDS segments this process holds now (added to what it noted before).

    A segment whose ``_el`` lock this process holds (it owns the segment) is
    noted with the segment file's inode: after the process is gone, that very
    file, its lock free, is a zombie (:func:`clean_dead`).
    """
    with _NOTE_LOCK:
        path = _note_path(os.getpid())
        if path is None:
            return
        current = segments_of()
        mine = {key for pid, key in _locks() if pid == os.getpid()}
        owned: Dict[str, int] = {}
        for name in filter(_is_segment, current):
            file = _file_key(name)
            lock = _file_key(f'{name}_el')
            if file is not None and lock is not None and lock in mine:
                owned[name] = file[2]
        noted = _read_note(path) if path.exists() else {}
        for name in _with_companions(current):
            noted[name] = owned.get(name, noted.get(name))
        _write_note(path, noted)


def _read_note(path: Path) -> Dict[str, Optional[int]]:
    """Return a note's names, each with the inode of a segment the task owned (else None)."""
    noted: Dict[str, Optional[int]] = {}
    for line in path.read_text(encoding='utf-8').splitlines():
        fields = line.split()
        if fields:
            noted[fields[0]] = int(fields[1]) if len(fields) > 1 and fields[1].isdigit() else None
    return noted


def _write_note(path: Path, noted: Dict[str, Optional[int]]) -> None:
    lines = [name if noted[name] is None else f'{name} {noted[name]}' for name in sorted(noted)]
    scratch = path.with_name(f'{path.name}.{os.getpid()}.new')
    scratch.write_text('\n'.join(lines) + '\n', encoding='utf-8')
    os.replace(scratch, path)  # a reader never sees half a note


@contextlib.contextmanager
def noting(period_s: float = NOTE_PERIOD_S) -> Iterator[None]:
    """Note this process's segments every ``period_s`` (a thread) while the block runs."""
    done = threading.Event()

    def again() -> None:
        while not done.wait(period_s):
            try:
                note()
            except OSError:
                pass  # the registry went: the next note tries again

    thread = threading.Thread(target=again, name='r2d2_farm-shm-note', daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()


def forget() -> None:
    """Drop this process's note: its task ended and closed its segments itself."""
    path = _note_path(os.getpid())
    if path is not None:
        path.unlink(missing_ok=True)


def in_use(names: Set[str]) -> Set[str]:
    """Return which of ``names`` a live process of this host maps or holds open."""
    used: Set[str] = set()
    for entry in os.listdir('/proc'):
        if entry.isdigit():
            used |= segments_of(entry) & names
            if used == names:
                break
    return used


def _locks() -> List[Tuple[int, Tuple[int, int, int]]]:
    """Return (pid, (major, minor, inode)) of every lock /proc/locks lists on this host."""
    found: List[Tuple[int, Tuple[int, int, int]]] = []
    try:
        with open('/proc/locks', encoding='utf-8') as locks:
            for line in locks:
                fields = line.split()
                for at, field in enumerate(fields):
                    match = _LOCKED_FILE.match(field)
                    if match and at > 0 and fields[at - 1].isdigit():
                        found.append((int(fields[at - 1]), (int(match[1], 16),
                                                            int(match[2], 16), int(match[3]))))
                        break
    except OSError:
        pass
    return found


def _key(stat: os.stat_result) -> Tuple[int, int, int]:
    """Return a file's (major, minor, inode), as /proc/locks names it."""
    return os.major(stat.st_dev), os.minor(stat.st_dev), stat.st_ino


def _file_key(name: str) -> Optional[Tuple[int, int, int]]:
    """Return a /dev/shm file's :func:`_key`; None if it is gone."""
    try:
        return _key(os.stat(SHM_DIR / name))
    except OSError:
        return None


def _is_segment(name: str) -> bool:
    """Return True for a segment's own name (not a lock file or the semaphore beside it)."""
    return not (name.endswith(('_el', '_sl')) or name.startswith('sem.'))


def _segment_of(name: str) -> str:
    """Return the segment a lock file (``_el``, ``_sl``) or a port's semaphore belongs to."""
    return name[4:-6] if name.startswith('sem.') else name[:-3]


def _remove_segment(name: str, inode: int) -> List[str]:
    """
    Remove segment ``name``, with its lock file and semaphore, if it is file ``inode`` unowned.

    The segment's owner (the participant that listens on a port, or writes
    into its own segment) holds an exclusive ``flock`` on its ``_el`` file for
    as long as it lives. Taking that lock without waiting is Fast DDS's own
    zombie test (``Port::is_zombie``), and holding it while the files go is
    what makes this safe beside Fast DDS: a participant that opens the port
    meanwhile finds it locked and takes another, and one that made the file
    anew (another inode) keeps it. Returns the names removed. (Fast DDS also
    holds the port's named mutex to open one; taking it too made the sweep
    miss ports that a sender to a dead listener keeps re-opening.)
    """
    lock_name = f'{name}_el'
    try:
        lock: Optional[int] = os.open(SHM_DIR / lock_name,
                                      os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except FileNotFoundError:
        lock = None
    except OSError:
        return []
    try:
        held = None  # the lock file we hold, as its key
        if lock is not None:
            lock_stat = os.fstat(lock)
            if not stat_module.S_ISREG(lock_stat.st_mode):
                return []  # not a lock file Fast DDS made
            held = _key(lock_stat)
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                return []  # an owner holds it
        file = _file_key(name)
        if file is None or file[2] != inode:
            return []
        removed: List[str] = []
        for each in sorted(_with_companions([name])):
            if each == lock_name and (held is None or _file_key(each) != held):
                continue  # not the lock file we hold: another's, made since
            try:
                (SHM_DIR / each).unlink()
                removed.append(each)
            except OSError:
                pass
        return removed
    finally:
        if lock is not None:
            os.close(lock)  # and the lock with it


def _sweep_note(path: Path, noted: Dict[str, Optional[int]],
                seen: Dict[str, Optional[Tuple[int, int, int]]], used: Set[str],
                removed: List[str]) -> None:
    """
    Remove what a dead task's note names and nobody uses or owns; rewrite or drop the note.

    ``seen``: each file's key before the scan of every process that found
    the ``used`` ones (a file made again meanwhile, a new participant's port
    of the same number, is not the task's). What goes is added to ``removed``.
    """
    names = set(noted)
    used = used & names
    for name in sorted(n for n in names if _is_segment(n)):
        # One mapped still, by senders to a port the dead task owned, is a zombie if it is
        # the very file the task owned and its lock is free.
        if name in used:
            inode = noted[name]  # the owner's file, or None: not the task's to remove
        else:
            key = seen[name]
            inode = None if key is None else key[2]
        if inode is not None:
            removed += _remove_segment(name, inode)
    # A lock file or semaphore goes on its own only when its segment is gone.
    for name in sorted(n for n in names - used if not _is_segment(n)):
        if (SHM_DIR / _segment_of(name)).exists() or seen[name] is None \
                or _file_key(name) != seen[name]:
            continue
        try:
            (SHM_DIR / name).unlink()
            removed.append(name)
        except OSError:
            pass
    # What is still there, the same file, stays noted (a port another process maps now):
    # once it is let go of without being removed, a later sweep (a run's end) removes it.
    # A file made anew under a noted name since is another participant's.
    kept = {name: noted[name] for name in names
            if seen[name] is not None and _file_key(name) == seen[name]}
    if kept:
        _write_note(path, kept)
    else:
        path.unlink(missing_ok=True)


def clean_dead() -> List[str]:
    """
    Remove the segments of noted tasks whose process is gone, if no live process uses them.

    Returns the names removed. Notes of live processes are left alone, as
    are files that are not Fast DDS's (a note is read, never trusted as a path).
    One sweep runs at a time on a host (tasks starting together all call it);
    it never raises: what it cannot do now, a later sweep does.
    """
    removed: List[str] = []
    try:
        registry = registry_dir()
        sweep = os.open(registry / '.sweep', os.O_RDONLY | os.O_CREAT, 0o600)
    except OSError:
        return removed
    try:
        fcntl.flock(sweep, fcntl.LOCK_EX)
        _sweep(registry, removed)
    except (OSError, ValueError):
        pass  # the registry or /proc could not be read: the next sweep tries again
    finally:
        os.close(sweep)
    return removed


def _sweep(registry: Path, removed: List[str]) -> None:
    """Sweep every dead task's note in ``registry`` (the caller holds the sweep's lock)."""
    notes: Dict[Path, Dict[str, Optional[int]]] = {}
    for path in sorted(registry.iterdir()):
        pid, _, start = path.name.partition('-')
        if not pid.isdigit():
            continue  # the sweep's lock
        if '.' in start:  # a note being written: <note>.<writer's pid>.new
            writer = start.split('.')[1]
            if writer.isdigit() and not os.path.exists(f'/proc/{writer}'):
                path.unlink(missing_ok=True)  # its writer was killed writing it
            continue
        if _start_time(int(pid)) == start:
            continue  # still running
        try:
            notes[path] = {n: inode for n, inode in _read_note(path).items()
                           if _FAST_DDS.match(n) and '/' not in n}
        except (OSError, ValueError):
            continue  # gone meanwhile, or not a note (left alone)
    names: Set[str] = set().union(*notes.values())
    # Every file as it is now, then one scan of every process (milliseconds) for them all.
    seen = {name: _file_key(name) for name in names}
    used = in_use(names) if names else set()
    for path, noted in notes.items():
        try:
            _sweep_note(path, noted, seen, used, removed)
        except OSError:
            continue
