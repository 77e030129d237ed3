"""
pytest integration for testing code against the simulator (a ``pytest11`` plugin).

Installed with the package, so it loads in every pytest run of the environment:
it imports nothing heavy until a fixture is used.
"""


def pytest_configure(config) -> None:
    """Hide the ROS wheels' own DeprecationWarnings (lark imports sre_parse on Python 3.11+)."""
    config.addinivalue_line('filterwarnings', r'ignore::DeprecationWarning:lark(\..*)?')
