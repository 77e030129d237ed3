"""
Each half of a domain lease on its own: the ``flock`` on its lock file, and the port of ROS tools.

A lease holds both (``r2d2_sim.testing.domains``), so a test that only ever
meets leases of its own kind cannot tell a lease without its port, or with a
shared lock, from a right one: the other half still keeps two of ours apart.
Here each half meets a holder of that half alone: a ROS tool holding only the
port, as launch_testing's ``domain_coordinator`` does, and a process holding
only the file lock, or only a shared one. The leases are taken in a lock
directory of the test's own, among ids 200-231, which the suite's harnesses
(1-100) never lease.
"""

import errno
import fcntl
import os
import socket

import pytest

from r2d2_sim.testing import domains, DomainUnavailable, lease_domain

# Ids no other test of the suite leases (their default range is 1-100).
SPARE_IDS = range(200, 232)


@pytest.fixture
def lock_dir(tmp_path, monkeypatch):
    """Lease among SPARE_IDS in a lock directory of this test's own."""
    monkeypatch.setenv(domains.DOMAIN_LOCK_DIR_ENV, str(tmp_path / 'locks'))
    monkeypatch.setenv(domains.DOMAIN_IDS_ENV, f'{SPARE_IDS[0]}-{SPARE_IDS[-1]}')
    return tmp_path / 'locks'


def bind_coordinator_port(domain_id):
    """Reserve ``domain_id`` as domain_coordinator does (bind TCP 32768 + id); None if taken."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        sock.bind(('', domains.COORDINATOR_PORT_BASE + domain_id))
    except OSError:
        sock.close()
        return None
    return sock


def spare_domain():
    """Return a spare id whose port is free, with its port bound by us (as a ROS tool would)."""
    for domain_id in SPARE_IDS:
        sock = bind_coordinator_port(domain_id)
        if sock is not None:
            return domain_id, sock
    pytest.fail(f'every port of {SPARE_IDS} is taken')


def lock_file(lock_dir, domain_id):
    return lock_dir / f'domain-{domain_id}.lock'


def test_a_lease_holds_the_port_ros_tooling_reserves(lock_dir):
    """While we hold a domain, domain_coordinator (launch_testing, colcon test) cannot take it."""
    with lease_domain(timeout_s=5.0) as lease:
        port = bind_coordinator_port(lease.domain_id)
        if port is not None:
            port.close()
        assert port is None, f'domain {lease.domain_id} is leased but its port is free'
    port = bind_coordinator_port(lease.domain_id)  # given back with the lease
    assert port is not None
    port.close()


def test_a_port_held_by_ros_tooling_alone_keeps_us_off_that_domain(lock_dir, monkeypatch):
    """A domain_coordinator holding the port (no lock file anywhere) makes our lease skip it."""
    domain_id, tool = spare_domain()
    try:
        monkeypatch.setenv(domains.DOMAIN_IDS_ENV, f'{domain_id}-{domain_id}')
        with pytest.raises(DomainUnavailable):
            lease_domain(domain_id, timeout_s=0.2)
        with pytest.raises(DomainUnavailable):
            lease_domain(timeout_s=0.2)  # the only id of the range
        # Skipping it left no lock behind: the file half is free again.
        fd = os.open(lock_file(lock_dir, domain_id), os.O_RDWR)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        finally:
            os.close(fd)
    finally:
        tool.close()
    with lease_domain(domain_id, timeout_s=5.0) as lease:  # ours once the tool lets go
        assert lease.domain_id == domain_id


def test_a_lock_file_held_alone_keeps_us_off_that_domain(lock_dir):
    """A process holding only the file lock (its port free) makes our lease skip that domain."""
    domain_id, probe = spare_domain()
    probe.close()  # the port stays free: only the lock file may keep us off
    lock_dir.mkdir(mode=0o700, exist_ok=True)
    holder = os.open(lock_file(lock_dir, domain_id), os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(holder, fcntl.LOCK_EX | fcntl.LOCK_NB)
        with pytest.raises(DomainUnavailable):
            lease_domain(domain_id, timeout_s=0.2)
    finally:
        os.close(holder)


def test_the_lock_of_a_lease_is_exclusive(lock_dir):
    """No other holder, not even a shared one, gets the lock file of a leased domain."""
    with lease_domain(timeout_s=5.0) as lease:
        other = os.open(lock_file(lock_dir, lease.domain_id), os.O_RDONLY)
        try:
            with pytest.raises(OSError) as refused:
                fcntl.flock(other, fcntl.LOCK_SH | fcntl.LOCK_NB)
            assert refused.value.errno in (errno.EAGAIN, errno.EWOULDBLOCK)
        finally:
            os.close(other)
    other = os.open(lock_file(lock_dir, lease.domain_id), os.O_RDONLY)
    try:
        fcntl.flock(other, fcntl.LOCK_SH | fcntl.LOCK_NB)  # free once released
    finally:
        os.close(other)
