"""
The head camera's images from the node, and their CameraInfo.

The pinhole math is checked by hand in model/test_camera.py; the intrinsics
CameraInfo publishes here are that math's, so the image and its CameraInfo agree.
"""

import math

from helpers import make_sim, RATE_HZ, wait_for
import numpy
import pytest
from sensor_msgs.msg import CameraInfo, Image

from common import classic_params
from r2d2_sim.ros.node import StartupError


def test_camera_needs_a_head(ros):
    """camera_rate on a robot without a 'head' link refuses to start, naming it."""
    with pytest.raises(StartupError, match="link named 'head'"):
        make_sim(ros, urdf='cube.urdf', camera_rate=10.0)


def test_camera_is_off_by_default(sim):
    """No camera topics unless camera_rate is set."""
    assert sim.simulation.robot.camera is None
    topics = [name for name, _ in sim.get_topic_names_and_types()]
    assert not any(name.startswith('/camera') for name in topics)


def _image_array(msg_or_bytes, width, height):
    data = msg_or_bytes.data if hasattr(msg_or_bytes, 'data') else msg_or_bytes
    return numpy.frombuffer(bytes(data), dtype=numpy.uint8).reshape(height, width, 3)


def test_images_and_camera_info_at_camera_rate(ros):
    """10 Hz for 1 simulated second: 10 rgb8 images stamped 0.1 s apart, matching info."""
    sim = make_sim(ros, camera_rate=10.0, camera_width=160, camera_height=120, camera_fov=50.0)
    node = ros.create_node('camera_probe', use_sim_time=False)
    images, infos = [], []
    node.create_subscription(Image, 'camera/image_raw', images.append, 20)
    node.create_subscription(CameraInfo, 'camera/camera_info', infos.append, 20)
    assert wait_for(lambda: sim.count_subscribers('camera/image_raw') > 0)
    for _ in range(RATE_HZ // 24):
        sim.advance(24)
        count = sim.step_count // 24
        assert wait_for(lambda: len(images) >= count and len(infos) >= count), 'no image'
    assert len(images) == len(infos) == 10
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in images]
    assert stamps == pytest.approx([0.1 * (i + 1) for i in range(10)], abs=1e-9)
    image, info = images[-1], infos[-1]
    assert (image.width, image.height, image.encoding, image.step) == (160, 120, 'rgb8', 480)
    assert len(image.data) == 160 * 120 * 3
    assert image.header.frame_id == info.header.frame_id == 'head_camera_optical'
    assert info.header.stamp == image.header.stamp
    fy = 60.0 / math.tan(math.radians(25.0))
    # The principal point where the renderer samples (test/sim/test_camera_info_samples.py).
    assert list(info.k) == pytest.approx([fy, 0, 80, 0, fy, 59, 0, 0, 1])
    assert list(info.p) == pytest.approx([fy, 0, 80, 0, 0, fy, 59, 0, 0, 0, 1, 0])
    assert list(info.r) == [1, 0, 0, 0, 1, 0, 0, 0, 1]
    assert info.distortion_model == 'plumb_bob' and list(info.d) == [0.0] * 5
    pixels = _image_array(image, 160, 120).astype(int)
    # Sky above, the checkered ground plane below.
    assert numpy.abs(pixels[:10].mean(axis=(0, 1)) - pixels[-10:].mean(axis=(0, 1))).max() > 20


def test_turning_the_head_turns_the_camera(ros):
    """head_swivel a quarter turn: the cube ahead leaves the centre of the image."""
    sim = make_sim(ros, camera_rate=5.0, camera_width=80, camera_height=60,
                   extra_models=['cube.urdf 3 0 0.5'])
    ahead = _image_array(sim.simulation.robot.camera.render().rgb, 80, 60).astype(int)
    swivel = sim.simulation.robot.body.joint('head_swivel').index
    sim.world.client.resetJointState(sim.simulation.robot.body.id, swivel, math.pi / 2)
    turned = _image_array(sim.simulation.robot.camera.render().rgb, 80, 60).astype(int)
    centre = (slice(25, 35), slice(35, 45))
    assert numpy.abs(ahead[centre] - turned[centre]).mean() > 20
    assert numpy.abs(ahead - turned).mean() > 5


@pytest.mark.parametrize('robot', ['ours', 'classic'])
def test_camera_looks_rep103_forward(ros, robot):
    """A cube 3 m ahead along world +x fills the image centre for both robots."""
    params = classic_params() if robot == 'classic' else {}
    sim = make_sim(ros, camera_rate=5.0, camera_width=80, camera_height=60,
                   extra_models=['cube.urdf 3 0 0.5'], **params)
    with_cube = _image_array(sim.simulation.robot.camera.render().rgb, 80, 60).astype(int)
    cube = sim.simulation.models[0].id
    sim.world.client.resetBasePositionAndOrientation(cube, (-20.0, 0.0, 0.5), (0, 0, 0, 1))
    without = _image_array(sim.simulation.robot.camera.render().rgb, 80, 60).astype(int)
    centre = (slice(25, 35), slice(35, 45))
    assert numpy.abs(with_cube[centre] - without[centre]).mean() > 20
