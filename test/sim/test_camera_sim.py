"""The head camera's parameters, validated up front, and where it sits on the head."""

import math
from pathlib import Path
import re

import pytest

from common import REPO
from r2d2_sim.sim.settings.table import ConfigError
from r2d2_sim.sim.settings.config import parse_config


@pytest.mark.parametrize('name, value, fragment', [
    ('camera_rate', 480.0, 'cannot exceed'),
    ('camera_rate', -1.0, 'must be in [0.001, 10000] Hz (off with 0), got -1'),
    ('camera_width', 0, 'camera_width'),
    ('camera_height', 1.5, 'integer'),
    ('camera_fov', 180.0, 'below 180'),
])
def test_bad_camera_parameters(name, value, fragment):
    """Camera parameters are validated up front, one line each."""
    with pytest.raises(ConfigError, match=re.escape(fragment)):
        parse_config({name: value})


def test_the_lens_sits_on_r2d2s_head_as_it_always_did(make):
    """R2D2's head is a 0.16 m sphere: the lens 1 cm ahead of it, to the bit, at any yaw."""
    for yaw in (0.0, math.pi / 4):
        camera = make(camera_rate=1.0, initial_pose=[0.0, 0.0, yaw]).robot.camera
        assert camera.optical_mount.translation == (0.17, 0.0, 0.0)


def test_the_lens_offset_is_the_same_at_every_spawn_yaw(make, tmp_path):
    """
    A box head (0.4 m long): the lens 0.21 m ahead of the head's origin, however it was spawned.

    The head's size was read from its world bounding box, which a turned box
    widens: spawned at 45 degrees the lens sat 0.222 m ahead, its frame on
    /tf_static with it.
    """
    text = (Path(REPO) / 'urdf' / 'r2d2.urdf').read_text(encoding='utf-8')
    sphere = '<sphere radius="0.16"/>'
    assert text.count(sphere) == 2  # the head's visual and collision
    urdf = tmp_path / 'boxhead.urdf'
    urdf.write_text(text.replace(sphere, '<box size="0.4 0.2 0.2"/>'), encoding='utf-8')
    mounts = [make(urdf=str(urdf), camera_rate=1.0,
                   initial_pose=[0.0, 0.0, yaw]).robot.camera.optical_mount
              for yaw in (0.0, math.pi / 4, -2.0)]
    assert mounts[0].translation == pytest.approx((0.21, 0.0, 0.0), abs=1e-12)
    assert mounts[1] == mounts[0] and mounts[2] == mounts[0]
