"""The head camera's matrices (model/test_camera.py) against PyBullet's own helpers."""

import pybullet
import pytest

from r2d2_sim.model import camera


def test_projection_matrix_matches_pybullet():
    """Same numbers as pybullet.computeProjectionMatrixFOV."""
    ours = camera.projection_matrix(320, 240, 60.0, 0.01, 100.0)
    theirs = pybullet.computeProjectionMatrixFOV(60.0, 320 / 240, 0.01, 100.0)
    assert ours == pytest.approx(list(theirs), rel=1e-6)


@pytest.mark.parametrize('eye, forward, up', [
    ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    ((0.5, -2.0, 0.3), (0.3, 0.8, -0.2), (0.0, 0.0, 1.0)),
    ((1.0, 2.0, 3.0), (0.0, -1.0, 0.0), (0.2, 0.0, 1.0)),
])
def test_view_matrix_matches_pybullet(eye, forward, up):
    """Same numbers as pybullet.computeViewMatrix(eye, eye + forward, up)."""
    target = [e + f for e, f in zip(eye, forward)]
    theirs = pybullet.computeViewMatrix(eye, target, up)
    assert camera.view_matrix(eye, forward, up) == pytest.approx(list(theirs), abs=1e-6)
