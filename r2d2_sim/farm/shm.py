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
Anyone on the host may call it: the local pool after a worker dies
and at the end of a run, every task on a cluster's host as it starts, and the
farm on every host at the end.
"""

import contextlib
import os
from pathlib import Path
import re
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
        if name.endswith('_el') or name.startswith('sem.'):
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
        for name in current:
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
    scratch = path.with_suffix('.new')
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


def _file_key(name: str) -> Optional[Tuple[int, int, int]]:
    """Return a /dev/shm file's (major, minor, inode) as /proc/locks names it; None if gone."""
    try:
        stat = os.stat(SHM_DIR / name)
    except OSError:
        return None
    return os.major(stat.st_dev), os.minor(stat.st_dev), stat.st_ino


def _orphans(used: Set[str], owned: Dict[str, int]) -> Set[str]:
    """
    Return which of the ``used`` files of a dead task have lost their owner: the task.

    A segment's owner (the participant that listens on a port, or writes into
    its own segment) holds a lock on its ``_el`` file for as long as it lives;
    the others who map it only send to it or read from it. A segment the dead
    task owned (``owned``: noted with its inode while the task held the lock),
    still that very file, whose lock nobody holds now, is a zombie, which Fast
    DDS itself removes and makes anew when a participant next listens on that
    port: its remaining users keep their mappings, and the names, which would
    outlive them, go (with the lock file and the port's semaphore). A port
    made anew by a new owner is another file (another inode) and stays, even
    in the moment before its owner locks it; so does a port shared by several
    readers, which nobody locks.
    """
    candidates = [name for name in used if name in owned]
    if not candidates:
        return set()
    locked = {key for _, key in _locks()}
    orphans: Set[str] = set()
    for name in candidates:
        file, lock = _file_key(name), _file_key(f'{name}_el')
        if file is None or file[2] != owned[name] or lock is None or lock in locked:
            continue
        orphans |= _with_companions([name]) & used  # the segment is used: it is among them
    return orphans


def clean_dead() -> List[str]:
    """
    Remove the segments of noted tasks whose process is gone, if no live process uses them.

    Returns the names removed. Notes of live processes are left alone, as
    are files that are not Fast DDS's (a note is read, never trusted as a path).
    """
    removed: List[str] = []
    try:
        notes = [p for p in registry_dir().iterdir() if p.suffix != '.new']
    except OSError:
        return removed
    for path in notes:
        pid, _, start = path.name.partition('-')
        if pid.isdigit() and _start_time(int(pid)) == start:
            continue  # still running
        try:
            noted = {n: inode for n, inode in _read_note(path).items()
                     if _FAST_DDS.match(n) and '/' not in n}
        except OSError:
            continue
        names = set(noted)
        # Each file as it was before the scan of every process (milliseconds): one made
        # again meanwhile (a new participant's port of the same number) is not ours.
        seen = {name: _file_key(name) for name in names}
        used = in_use(names)
        used -= _orphans(used, {n: i for n, i in noted.items() if i is not None})
        for name in sorted(names - used):
            if seen[name] is None or _file_key(name) != seen[name]:
                continue
            try:
                (SHM_DIR / name).unlink()
                removed.append(name)
            except FileNotFoundError:
                pass
            except OSError:
                continue
        # A segment another process uses now (a port a later participant listens on
        # again) stays noted: once that process lets go of it without removing it, a
        # later call (the sweep at a run's end) removes it.
        kept = {name: noted[name] for name in used if (SHM_DIR / name).exists()}
        if kept:
            _write_note(path, kept)
        else:
            path.unlink(missing_ok=True)
    return removed
