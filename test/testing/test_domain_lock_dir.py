"""
The domain lock directory in a shared ``$TMPDIR``: private, checked, never followed through a link.

Another user of the machine can create names in ``/tmp`` before we do: a
symbolic link where our directory or one of its lock files should be (once
made root create a file of that user's choosing), or a plain file there (once
a ``FileExistsError`` traceback). Each case here must end in one readable
line, or in that domain being skipped, with nothing created through the link.
These tests hold only the file half of a lease for real: the port half is
stubbed, so they neither need nor take a free port.
"""

import os
import socket
import stat
import tempfile

import pytest

from r2d2_sim.testing import domains, DomainUnavailable, domain_lock_dir, lease_domain


@pytest.fixture(autouse=True)
def any_port_is_free(monkeypatch):
    """Stub domain_coordinator's half: these tests are about the lock files alone."""
    monkeypatch.setattr(domains, '_try_coordinator_port', lambda domain_id: socket.socket())


@pytest.fixture
def victim(tmp_path):
    """Return a directory a symbolic link points into; nothing may appear in it."""
    path = tmp_path / 'victim'
    path.mkdir()
    return path


def lock_dir_at(monkeypatch, path):
    monkeypatch.setenv(domains.DOMAIN_LOCK_DIR_ENV, str(path))
    monkeypatch.setenv(domains.DOMAIN_IDS_ENV, '5-6')
    return path


def refusal(domain_id=5):
    """Return the one-line message of the DomainUnavailable that leasing ``domain_id`` raises."""
    with pytest.raises(DomainUnavailable) as info:
        lease_domain(domain_id, timeout_s=0.2).release()
    message = str(info.value)
    assert '\n' not in message
    return message


def test_the_default_lock_dir_is_private_and_so_are_its_files(tmp_path, monkeypatch):
    """Under $TMPDIR, a directory per user, 0700, and lock files only its owner can open."""
    monkeypatch.delenv(domains.DOMAIN_LOCK_DIR_ENV, raising=False)
    monkeypatch.setattr(tempfile, 'tempdir', str(tmp_path))
    monkeypatch.setenv(domains.DOMAIN_IDS_ENV, '5-6')
    path = domain_lock_dir()
    assert path.parent == tmp_path and str(os.getuid()) in path.name
    facts = os.lstat(path)
    assert stat.S_ISDIR(facts.st_mode) and facts.st_uid == os.getuid()
    assert stat.S_IMODE(facts.st_mode) == 0o700
    with lease_domain(5, timeout_s=1.0):
        facts = os.lstat(path / 'domain-5.lock')
    assert stat.S_ISREG(facts.st_mode) and stat.S_IMODE(facts.st_mode) & 0o077 == 0


def test_a_default_lock_dir_squatted_by_a_link_is_refused(tmp_path, victim, monkeypatch):
    """Another user's link at our directory's name: refused, nothing created where it points."""
    monkeypatch.delenv(domains.DOMAIN_LOCK_DIR_ENV, raising=False)
    monkeypatch.setattr(tempfile, 'tempdir', str(tmp_path))
    (tmp_path / f'r2d2_sim-domains-{os.getuid()}').symlink_to(victim)
    assert 'symbolic link' in refusal()
    assert list(victim.iterdir()) == []


def test_a_lock_dir_that_is_a_link_is_refused(tmp_path, victim, monkeypatch):
    """R2D2_SIM_DOMAIN_LOCK_DIR naming a symbolic link: one line, the link not followed."""
    link = lock_dir_at(monkeypatch, tmp_path / 'locks')
    link.symlink_to(victim)
    message = refusal()
    assert str(link) in message and 'symbolic link' in message
    assert list(victim.iterdir()) == []


def test_a_lock_dir_that_is_a_file_is_refused(tmp_path, monkeypatch):
    """A plain file where the directory should be: one line, not a FileExistsError."""
    squatted = lock_dir_at(monkeypatch, tmp_path / 'locks')
    squatted.write_text('')
    assert str(squatted) in refusal()


def test_a_lock_dir_others_may_write_is_refused(tmp_path, monkeypatch):
    """A directory others may write (as /tmp is) would let them plant links among our locks."""
    shared = lock_dir_at(monkeypatch, tmp_path / 'locks')
    shared.mkdir()
    shared.chmod(0o1777)
    assert 'writable' in refusal()
    assert list(shared.iterdir()) == []


def plant(entry, kind, victim):
    if kind == 'link_to_nowhere':
        entry.symlink_to(victim / 'planted')
    elif kind == 'link_to_a_file':
        (victim / 'planted').write_text('keep')
        entry.symlink_to(victim / 'planted')
    elif kind == 'directory':
        entry.mkdir()
    else:
        os.mkfifo(entry)


@pytest.mark.parametrize('kind', ['link_to_nowhere', 'link_to_a_file', 'directory', 'fifo'])
def test_a_squatted_lock_file_is_skipped_and_never_followed(tmp_path, victim, monkeypatch,
                                                            kind):
    """A lock file that is not a plain file of ours: that domain is taken, nothing followed."""
    locks = lock_dir_at(monkeypatch, tmp_path / 'locks')
    locks.mkdir(mode=0o700)
    plant(locks / 'domain-5.lock', kind, victim)
    assert 'domain-5.lock' in refusal(5)
    for _ in range(4):  # wherever the search starts, 5 is passed over
        with lease_domain(timeout_s=1.0) as lease:
            assert lease.domain_id == 6
    planted = victim / 'planted'
    assert (planted.read_text() == 'keep') if kind == 'link_to_a_file' else not planted.exists()
