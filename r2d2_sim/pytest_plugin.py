"""
pytest fixtures for testing code against the simulator (a ``pytest11`` plugin).

Installed with the package, so it loads in every pytest run of the environment;
from a source tree, opt in with ``pytest_plugins = ['r2d2_sim.pytest_plugin']``.
It imports nothing heavy until a fixture is used.

- ``r2d2_sim``: a ready :class:`~r2d2_sim.testing.SimHarness` (the simulator
  in the test's process, advanced only when told) with the parameters of
  ``r2d2_sim_parameters``: the node's defaults but ``cmd_vel_timeout`` 0, so
  a command holds until the next one. Override that fixture to change them.
- ``r2d2_sim_factory``: ``r2d2_sim_factory(**parameters)`` builds more
  harnesses, each on its own domain; all are closed after the test.
- ``r2d2_sim_process``: ``r2d2_sim_process(**parameters)`` starts
  ``sim_node`` in a process of its own (:class:`~r2d2_sim.testing.SimProcess`)
  and returns once it is ready; all are stopped after the test.

Each harness leases a ROS domain no other harness on the machine uses, so
tests may run in parallel (``pytest -n auto``).
"""

from typing import Any, Callable, Iterator, TYPE_CHECKING

import pytest

if TYPE_CHECKING:  # the plugin imports nothing heavy until a fixture is used
    from r2d2_sim.testing import SimHarness, SimProcess


def pytest_configure(config: pytest.Config) -> None:
    """Hide the ROS wheels' own DeprecationWarnings (lark imports sre_parse on Python 3.11+)."""
    config.addinivalue_line('filterwarnings', r'ignore::DeprecationWarning:lark(\..*)?')


@pytest.fixture
def r2d2_sim_parameters() -> dict:
    """Return the simulator parameters of the ``r2d2_sim`` fixture (override to change them)."""
    # A test that sends one command and advances expects it to hold; the
    # node's default (brake 0.5 s after the last command) is for real teleop.
    return {'cmd_vel_timeout': 0.0}


@pytest.fixture
def r2d2_sim_factory() -> Iterator[Callable[..., 'SimHarness']]:
    """Provide ``make(**parameters) -> SimHarness``; each harness made closes after the test."""
    from r2d2_sim.testing import SimHarness
    yield from _made_and_closed(SimHarness, SimHarness.close)


@pytest.fixture
def r2d2_sim(r2d2_sim_factory: Callable[..., 'SimHarness'],
             r2d2_sim_parameters: dict) -> 'SimHarness':
    """
    Provide a ready in-process simulator harness (``SimHarness``) on a domain of its own.

    Parameters it cannot start with (``r2d2_sim_parameters``: a missing world,
    a bad value, a namespace or domain id ROS refuses) are the test's own
    mistake: the error is the harness's one line, without the library's traceback.
    """
    from r2d2_sim.errors import StartupError
    try:
        return r2d2_sim_factory(**r2d2_sim_parameters)
    except (StartupError, ValueError) as exc:  # ValueError: the harness's own keywords
        problem = str(exc)
    # Failed outside the except block: inside, pytest printed the error three times
    # (the StartupError, then "the direct cause of", then "during handling of").
    pytest.fail(f'r2d2_sim_parameters: {problem}', pytrace=False)


@pytest.fixture
def r2d2_sim_process() -> Iterator[Callable[..., 'SimProcess']]:
    """
    Provide ``start(**parameters) -> SimProcess``: ``sim_node`` in its own process, ready.

    Keywords are the simulator's parameters plus SimProcess's own
    (``ros_args``, ``domain_id``, ``timeout_s``...). Every process started is
    stopped after the test (SIGINT, then SIGKILL after a deadline).
    """
    from r2d2_sim.testing import SimProcess
    yield from _made_and_closed(SimProcess, SimProcess.stop)


def _made_and_closed(build: Callable[..., Any],
                     close: Callable[[Any], Any]) -> Iterator[Callable[..., Any]]:
    """Yield ``make(**parameters)`` that builds and keeps; close all it made afterwards."""
    made = []

    def make(**parameters: Any) -> Any:
        thing = build(**parameters)
        made.append(thing)
        return thing
    yield make
    _close_all(made, close)


def _close_all(harnesses: list, close: Callable[[Any], Any]) -> None:
    """Close every harness, newest first, even if one fails; then raise the first failure."""
    errors = []
    for harness in reversed(harnesses):
        try:
            close(harness)
        except Exception as exc:
            errors.append(exc)
    if errors:
        raise errors[0]
