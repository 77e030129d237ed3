"""
Fixtures for this project's own tests; their helpers are in ``helpers.py``.

The user-facing fixtures of :mod:`r2d2_sim.pytest_plugin` are imported here
for this suite too (rather than named in pytest_plugins: an installed
r2d2_sim registers the plugin under another name).
"""

import os

import pytest

import helpers
from helpers import make_sim, Probe
from r2d2_sim.pytest_plugin import (  # noqa: F401
    r2d2_sim, r2d2_sim_factory, r2d2_sim_parameters, r2d2_sim_process)
from r2d2_sim.testing import RosHarness

# Discovery must stay on this host; set before any rclpy.init.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
# The README examples run in a subprocess (test_testing_api.py), as a user's
# own test files would, not as part of this suite.
collect_ignore = ['examples']


@pytest.fixture(autouse=True)
def _release_domains():
    """Release the domains a test leased through helpers.next_domain_id, after all its fixtures."""
    yield
    while helpers.leases:
        helpers.leases.pop().release()


@pytest.fixture
def ros():
    """Provide an isolated ROS harness, torn down after the test."""
    with RosHarness() as harness:
        yield harness


@pytest.fixture
def sim(ros):
    """Provide the default simulator."""
    return make_sim(ros)


@pytest.fixture
def probe(ros, sim):
    """Provide a probe node linked to the simulator."""
    return Probe(ros, sim)
