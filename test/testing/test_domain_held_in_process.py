"""
A domain this process already leased: said at once, never a wait for itself.

A test with ``ROS_DOMAIN_ID`` set that starts a second ``SimProcess`` asks
for the domain its first one holds; the lease would wait for its own
process (60 s), then blame other harnesses. Leases here are taken in a lock
directory of the test's own, among ids 200-231, which the suite's harnesses
(1-100) never lease.
"""

import time

import pytest

from r2d2_sim.testing import domains, DomainUnavailable, lease_domain, SimProcess


@pytest.fixture
def lock_dir(tmp_path, monkeypatch):
    """Lease among 200-231 in a lock directory of this test's own."""
    monkeypatch.setenv(domains.DOMAIN_LOCK_DIR_ENV, str(tmp_path / 'locks'))
    monkeypatch.setenv(domains.DOMAIN_IDS_ENV, '200-231')
    return tmp_path / 'locks'


def test_a_lease_knows_the_domains_this_process_holds(lock_dir):
    """held_here is true from the lease to its release, and only for its id."""
    with lease_domain(timeout_s=5.0) as lease:
        assert domains.held_here(lease.domain_id)
        assert not domains.held_here(lease.domain_id + 1 if lease.domain_id < 231 else 200)
    assert not domains.held_here(lease.domain_id)


def test_waiting_for_a_domain_of_this_process_says_so_at_the_deadline(lock_dir):
    """Not 'other harnesses hold the locks': this process does."""
    with lease_domain(timeout_s=5.0) as lease:
        with pytest.raises(DomainUnavailable, match='this process holds it'):
            lease_domain(lease.domain_id, timeout_s=0.0)


def test_a_sim_process_on_ros_domain_id_this_process_holds_is_refused_at_once(
        lock_dir, monkeypatch):
    """One line naming use_env_domain=False, before any process starts, not after 60 s."""
    with lease_domain(timeout_s=5.0) as lease:  # as a first SimProcess on ROS_DOMAIN_ID holds it
        monkeypatch.setenv('ROS_DOMAIN_ID', str(lease.domain_id))
        started = time.monotonic()
        with pytest.raises(DomainUnavailable, match='use_env_domain=False') as refused:
            SimProcess(start_paused=True, timeout_s=5.0)
        assert time.monotonic() - started < 5.0
        assert '\n' not in str(refused.value)
