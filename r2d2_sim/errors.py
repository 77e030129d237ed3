"""
The errors a user's own mistakes raise: one readable line each, never a traceback.

Every layer that validates a setting, a file or a robot description raises a
subclass of :class:`SetupError` (``ConfigError``, ``DriveConfigError``,
``SensorConfigError``, ``DescriptionError``, ``WorldError``), so the node
catches them in one place and turns them into :class:`StartupError`, which
``sim_node`` prints as one ``r2d2_sim: error: ...`` line with exit status 2.
No imports: the pure layers and the testing API use it without rclpy or PyBullet.
"""

__all__ = ['SetupError', 'StartupError', 'WorldError']


class SetupError(Exception):
    """A setting, file or description the simulator cannot run with (the message is one line)."""


class StartupError(RuntimeError):
    """The simulator node cannot start with the given parameters or files."""


class WorldError(SetupError, RuntimeError):
    """A robot description, body or world setting that cannot be simulated."""
