"""
The errors a user's own mistakes raise: one readable line each, never a traceback.

Every layer that validates a setting, a file or a robot description raises a
subclass of :class:`SetupError` (``ConfigError``, ``DriveConfigError``,
``SensorConfigError``, ``DescriptionError``, ``WorldError``), so the node
catches them in one place and turns them into :class:`StartupError`, which
``sim_node`` prints as one ``r2d2_sim: error: ...`` line with exit status 2.
A request to a running simulator that the simulation standard's rules refuse
is a :class:`RefusedError` with the standard's result code, raised by the
core, answered by the ROS services and raised again by the testing API.
A farm's scenario, space or world that cannot be is a :class:`ScenarioError`
(:mod:`r2d2_sim.farm` gives it with its scenarios).
No imports: the pure layers and the testing API use it without rclpy or PyBullet.
"""

__all__ = ['SetupError', 'StartupError', 'WorldError', 'RefusedError', 'ScenarioError']


class SetupError(Exception):
    """A setting, file or description the simulator cannot run with (the message is one line)."""


class StartupError(RuntimeError):
    """The simulator node cannot start with the given parameters or files."""


class WorldError(SetupError, RuntimeError):
    """A robot description, body or world setting that cannot be simulated."""


class RefusedError(RuntimeError):
    """
    A request refused with one of the simulation standard's results.

    ``code`` names the result (``NOT_FOUND``, ``NAME_NOT_UNIQUE``,
    ``INCORRECT_TRANSITION``...: a ``simulation_interfaces/Result`` constant
    without ``RESULT_``, or the service's own), ``message`` says why in one
    line that quotes no file; ``str()`` gives both: ``NOT_FOUND: no entity...``.
    """

    def __init__(self, code: str, message: str) -> None:
        super().__init__(f'{code}: {message}')
        self.code = code
        self.message = message


class ScenarioError(ValueError):
    """A farm's scenario or space that cannot be, or a world it cannot read: one line."""
