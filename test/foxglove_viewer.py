"""The project's tests' Foxglove viewer: the public :class:`~r2d2_sim.testing.LiveViewClient`."""

from r2d2_sim.testing import LiveViewClient as Viewer

__all__ = ['Viewer']
