"""
Markers and fixtures for this project's own tests; this file imports no ROS.

The folders are tiers. ``model/``, ``physics/``, ``sim/`` and ``gym/`` (the learning
environments in process) are the fast tier (``./run.sh test fast``): they never
load rclpy (``model/`` not even PyBullet),
and a session of them alone fails if rclpy gets imported anyway. ``recording/``,
``ros/``, ``testing/``, ``apps/``, ``gym_ros/`` (the learning environments' ``ros``
backend) and ``conformance/`` run ROS in this process;
``osc/`` runs scenarios through scenario_execution (in this process, and its command);
``system/`` starts processes or builds things, and is marked ``system``; ``lint/`` checks style
and the package's layering. Helpers are in ``common.py`` (no ROS) and
``helpers.py`` (ROS); test modules import from those, never from a conftest.

The fixtures below import what they need when they run, so collecting or
running the fast tier loads no ROS. The user-facing fixtures of
:mod:`r2d2_sim.pytest_plugin` (which imports neither rclpy nor PyBullet) are
imported here for this suite too, rather than named in pytest_plugins: an
installed r2d2_sim registers the plugin under another name.
"""

import os
from pathlib import Path
import sys

import pytest

import common
from r2d2_sim.pytest_plugin import (  # noqa: F401
    r2d2_sim, r2d2_sim_factory, r2d2_sim_parameters, r2d2_sim_process)

# Discovery must stay on this host; set before any rclpy.init.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
# The README examples run in a subprocess (system/test_testing_api_system.py), as
# a user's own test files would, not as part of this suite.
collect_ignore = ['examples']

TEST_DIR = Path(__file__).resolve().parent
FAST_TIER = [TEST_DIR / 'model', TEST_DIR / 'physics', TEST_DIR / 'sim', TEST_DIR / 'gym']
# Fast-tier tests outside those folders: what they import of ROS, if anything, loads in
# interpreters of their own (the layering, the type check, the old module paths of the
# ROS layer), or they read files only (mixins, the changelog).
FAST_FILES = [TEST_DIR / 'lint' / name for name in (
    'test_layers.py', 'test_types.py', 'test_mixins.py', 'test_deprecations.py',
    'test_changelog.py')]
SYSTEM = TEST_DIR / 'system'
FAST_ONLY = pytest.StashKey[bool]()
# Set by .ci/run: every test must run there, a skip is a failure.
CI_ENV = 'R2D2_SIM_CI'
ROS_SEEN = pytest.StashKey[bool]()


def pytest_sessionstart(session):
    """Remove the Fast DDS shared-memory files that processes which died left (see below)."""
    if not hasattr(session.config, 'workerinput'):  # once, before xdist's workers start
        common.clean_fast_dds_zombies()


def in_fast_tier(path: Path) -> bool:
    """Return True for a test file of the fast tier (no rclpy in this process)."""
    return path in FAST_FILES or any(folder in path.parents for folder in FAST_TIER)


def pytest_collection_modifyitems(config, items):
    """Mark everything under system/ as ``system``; note whether only the fast tier runs."""
    for item in items:
        if SYSTEM in item.path.parents:
            item.add_marker(pytest.mark.system)
    config.stash[FAST_ONLY] = bool(items) and all(in_fast_tier(item.path) for item in items)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """In a fast-tier session (in each xdist worker too), fail the test that loaded rclpy."""
    outcome = yield
    report = outcome.get_result()
    config = item.config
    if (call.when == 'teardown' and config.stash.get(FAST_ONLY, False)
            and 'rclpy' in sys.modules and not config.stash.get(ROS_SEEN, False)):
        config.stash[ROS_SEEN] = True
        report.outcome = 'failed'
        report.longrepr = ('fast tier: rclpy was imported in this session (model/, physics/ and '
                           'sim/ must not load ROS); it was loaded by the end of this test')


def pytest_sessionfinish(session, exitstatus):
    """Under R2D2_SIM_CI (.ci/run), a skipped test fails the run: CI has what every test needs."""
    if not os.environ.get(CI_ENV):
        return
    reporter = session.config.pluginmanager.get_plugin('terminalreporter')
    skipped = reporter.stats.get('skipped', []) if reporter is not None else []
    if skipped and session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
        reporter.write_line(f'{CI_ENV}: {len(skipped)} test(s) skipped, which CI must not: it '
                            'installs the browser, the display and the interface packages '
                            '(reasons above, -rs)', red=True, bold=True)


@pytest.fixture(autouse=True)
def _release_domains():
    """Release the domains a test leased through helpers.next_domain_id, after all its fixtures."""
    yield
    while common.leases:
        common.leases.pop().release()


@pytest.fixture
def gym_make():
    """Provide gymnasium.make (learning environments), every environment closed after the test."""
    import gymnasium
    import r2d2_sim.gym  # noqa: F401  (registers the environments)
    made = []

    def build(env_id='R2D2Nav-v0', **kwargs):
        env = gymnasium.make(env_id, **kwargs)
        made.append(env)
        return env
    yield build
    for env in made:
        env.close()


@pytest.fixture
def world():
    """Provide a fresh world with the package's R2D2, closed afterwards."""
    from r2d2_sim.physics.world import SimWorld
    with SimWorld() as w:
        common.load_r2d2(w)
        yield w


@pytest.fixture
def robot(world):
    """Provide the world's R2D2 (a Body)."""
    return world.bodies['r2d2']


@pytest.fixture
def fake_package(tmp_path, monkeypatch):
    """Install a package 'fake_robots' with urdf/robot.urdf in a temporary ament prefix."""
    from r2d2_sim.physics.description import default_urdf_path
    index = tmp_path / 'share' / 'ament_index' / 'resource_index' / 'packages'
    index.mkdir(parents=True)
    (index / 'fake_robots').write_text('')
    urdf_dir = tmp_path / 'share' / 'fake_robots' / 'urdf'
    urdf_dir.mkdir(parents=True)
    with open(default_urdf_path(), encoding='utf-8') as handle:
        (urdf_dir / 'robot.urdf').write_text(handle.read())
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    return urdf_dir / 'robot.urdf'


@pytest.fixture
def lock_dir(tmp_path, monkeypatch):
    """Lease domains in a directory of this test's own, away from concurrent test runs."""
    from r2d2_sim import testing
    monkeypatch.setenv(testing.DOMAIN_LOCK_DIR_ENV, str(tmp_path))
    return tmp_path


@pytest.fixture
def ros():
    """Provide an isolated ROS harness, torn down after the test."""
    from r2d2_sim.testing import RosHarness
    with RosHarness() as harness:
        yield harness


@pytest.fixture
def sim(ros):
    """Provide the default simulator."""
    from helpers import make_sim
    return make_sim(ros)


@pytest.fixture
def probe(ros, sim):
    """Provide a probe node linked to the simulator."""
    from helpers import Probe
    return Probe(ros, sim)
