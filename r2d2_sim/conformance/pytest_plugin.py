"""
The conformance kit under pytest: one test per clause, for a simulator's own CI (opt-in).

Not loaded by default. Enable it with ``-p r2d2_sim.conformance.pytest_plugin``
(or ``pytest_plugins = ['r2d2_sim.conformance.pytest_plugin']`` in the root
``conftest.py``), and collect the ready-made test in one of your test files::

    from r2d2_sim.conformance.pytest_plugin import test_simulation_standard  # noqa: F401

Each clause is a test named by its id (``test_simulation_standard[STATE-03]``,
so ``-k "STATE or STEP"`` picks groups), skipped when its feature is not
declared and failed with the clause's reason and the sentence it checks;
every one fails when no simulator's features could be read, and a session
whose clause tests were all skipped fails too (one line says so).
Where the simulator is comes from the options ``--conformance-prefix``,
``--conformance-domain``, ``--conformance-asset``, ``--conformance-world``,
``--conformance-timeout`` and ``--conformance-total-timeout``, or from your
own session-scoped ``conformance_options`` fixture returning a
:class:`~r2d2_sim.conformance.target.KitOptions` (start the simulator there).
The clauses reset the simulator: do not spread them over xdist workers.
"""

from typing import Iterator, TYPE_CHECKING

import pytest

from r2d2_sim.apps.cli import domain_id_arg, positive_number
from r2d2_sim.conformance.clause import Clause, FAIL, SKIP
from r2d2_sim.conformance.clauses import CLAUSES

if TYPE_CHECKING:  # typing only: rclpy is imported when the kit connects
    from r2d2_sim.conformance.runner import Kit
    from r2d2_sim.conformance.target import KitOptions

__all__ = ['test_simulation_standard', 'conformance_options', 'conformance_kit']


def pytest_addoption(parser: pytest.Parser) -> None:
    """Add the ``--conformance-*`` options: where the simulator is, what the kit may use."""
    group = parser.getgroup('conformance', 'simulation_interfaces conformance kit')
    group.addoption('--conformance-prefix', default='/', metavar='NS',
                    help='namespace of the simulator\'s services (default /)')
    group.addoption('--conformance-domain', type=domain_id_arg, default=None, metavar='ID',
                    help='ROS domain id (default: ROS_DOMAIN_ID, else 0)')
    group.addoption('--conformance-asset', default='', metavar='URI',
                    help='something SpawnEntity takes by uri')
    group.addoption('--conformance-world', default='', metavar='URI',
                    help='a world LoadWorld takes')
    group.addoption('--conformance-timeout', type=positive_number, default=10.0, metavar='S',
                    help='longest wait for discovery or one reply (s)')
    group.addoption('--conformance-total-timeout', type=positive_number, default=None,
                    metavar='S', help='longest the whole run may take (s; default: 30 timeouts)')


@pytest.fixture(scope='session')
def conformance_options(request: pytest.FixtureRequest) -> 'KitOptions':
    """Return the KitOptions of the command line (override to start a simulator first)."""
    from r2d2_sim.conformance.target import KitOptions
    option = request.config.getoption
    return KitOptions(prefix=option('--conformance-prefix'),
                      domain_id=option('--conformance-domain'),
                      asset=option('--conformance-asset'), world=option('--conformance-world'),
                      timeout_s=option('--conformance-timeout'),
                      total_timeout_s=option('--conformance-total-timeout'))


# The session's Kit, once a clause test made it: what pytest_sessionfinish judges the run by.
KIT = pytest.StashKey['Kit']()


@pytest.fixture(scope='session')
def conformance_kit(conformance_options: 'KitOptions',
                    request: pytest.FixtureRequest) -> Iterator['Kit']:
    """Provide one connected Kit for the session; it leaves the simulator as found at the end."""
    from r2d2_sim.conformance.runner import Kit
    from r2d2_sim.conformance.target import KitError
    try:
        kit = Kit(conformance_options)
    except KitError as exc:
        pytest.fail(str(exc), pytrace=False)
    request.config.stash[KIT] = kit
    try:
        try:
            kit.connect()
        except KitError as exc:  # which simulator to check is not clear: none is touched
            pytest.fail(str(exc), pytrace=False)
        yield kit
    finally:
        problems = kit.close()
        if problems:  # an error at the last test's teardown: the run did not end clean
            pytest.fail('could not leave the simulator as found: ' + '; '.join(problems),
                        pytrace=False)


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """Give ``conformance_clause`` every clause, in the kit's order, named by its id."""
    if 'conformance_clause' in metafunc.fixturenames:
        metafunc.parametrize('conformance_clause', CLAUSES, ids=[c.id for c in CLAUSES])


def test_simulation_standard(conformance_kit: 'Kit', conformance_clause: Clause) -> None:
    """Check one clause of the standard (collect this in a test file of yours)."""
    from r2d2_sim.conformance.target import KitError
    try:
        outcome = conformance_kit.run_clause(conformance_clause)
    except KitError as exc:  # another simulator came up at the prefix
        pytest.fail(str(exc), pytrace=False)
    clause = conformance_clause
    if conformance_kit.target.features is None:  # no simulator read: a failure, never a skip
        pytest.fail(f'{clause.id}: {conformance_kit.unchecked()}', pytrace=False)
    if outcome.status == SKIP:
        pytest.skip(f'{clause.id}: {outcome.reason}')
    if outcome.status == FAIL:
        pytest.fail(f'{clause.id} {clause.title}: {outcome.reason}\n'
                    f'  {clause.source}: "{clause.quote}"', pytrace=False)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """
    Fail a session whose clause tests checked nothing, or that was given what was refused.

    Every clause test skipped, or the world or asset given refused by the
    simulator (the clauses that need it skipped): one line each says so.
    """
    kit = session.config.stash.get(KIT, None)
    if kit is None:
        return
    problems = kit.setup_problems() + [p for p in [kit.unchecked()] if p]
    if not problems:
        return
    reporter = session.config.pluginmanager.get_plugin('terminalreporter')
    for problem in problems:
        if reporter is not None:
            reporter.write_line(f'conformance: {problem}', red=True)
    if session.exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
