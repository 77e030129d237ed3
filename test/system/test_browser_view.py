"""
The live view in a real browser: Foxglove Studio 1.48 in headless Chromium, fed by sim_node.

sim_node runs at real time in the room, driving a circle, with
``foxglove_port`` and ``record`` set. Studio opens its live view through the
subprotocol relay with the layout users get (``config/foxglove_layout.json``),
and the test reads the page over the DevTools protocol: the topic list with
rates, and the robot's blue in the 3D panel (drawn from ``/robot_description``
on TF). The recording the node made is then opened from a loopback HTTP
server (``ds=remote-file``).

Slow (about a minute; the first run also installs Studio from npm and, as
root, Debian's chromium). Skipped where neither is available or installable,
or with ``R2D2_SIM_BROWSER_TESTS=0``. ``R2D2_SIM_UPDATE_DOCS=1`` also saves
the screenshot to ``docs/foxglove_view.png``.
"""

import io
import os
from pathlib import Path
import re
import sys
import time

import pytest

from r2d2_sim.testing import SimProcess
from sample_messages import ROBOT_RGB

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / 'browser'))
import harness  # noqa: E402

REPO = Path(__file__).resolve().parent.parent.parent
# Topic -> the rate the node publishes it at (Hz), with these parameters.
RATES = {'/tf': 50.0, '/odom': 50.0, '/ground_truth': 50.0, '/scan': 10.0,
         '/camera/image_raw': 5.0}
SIMULATOR = {'world': 'package://r2d2_sim/urdf/room.urdf', 'publish_rate': 50.0,
             'scan_rate': 10.0, 'camera_rate': 5.0, 'cmd_vel_timeout': 0.0,
             'real_time_factor': 1.0}
LATCHED = ['/robot_description', '/tf_static']
# R2D2's blue body in a 730x830 3D view covers about 10,000 pixels; the blue
# z axes of the frames a few hundred.
MIN_ROBOT_PIXELS = 2000

TOPIC_STATS = """
Object.fromEntries([...document.querySelectorAll('[data-topic-stat]')].map(
    e => [e.dataset.topic + ' ' + e.dataset.topicStat, e.textContent]))
"""
# The 3D panel's canvas: the largest one (the layout gives it 62% of the width).
CANVAS_3D = """
(() => {
  const boxes = [...document.querySelectorAll('canvas')].map(c => c.getBoundingClientRect())
      .filter(r => r.width > 0 && r.height > 0);
  boxes.sort((a, b) => b.width * b.height - a.width * a.height);
  return boxes.length ? {x: boxes[0].x, y: boxes[0].y, width: boxes[0].width,
                         height: boxes[0].height} : null;
})()
"""


@pytest.fixture(scope='module')
def browser_tools():
    """Install (once, cached) and return (Chromium path, Studio directory, install seconds)."""
    if os.environ.get('R2D2_SIM_BROWSER_TESTS', '1') == '0':
        pytest.skip('R2D2_SIM_BROWSER_TESTS=0')
    started = time.monotonic()
    try:
        chromium = harness.ensure_chromium()
        studio = harness.ensure_studio()
    except harness.HarnessUnavailable as exc:
        pytest.skip(str(exc))
    return chromium, studio, time.monotonic() - started


def robot_pixels(png: bytes) -> int:
    """Count pixels of the robot's blue (its lit and shaded sides) in a PNG."""
    import numpy
    from PIL import Image
    pixels = numpy.asarray(Image.open(io.BytesIO(png)).convert('RGB'), dtype=numpy.int16)
    red, green, blue = ROBOT_RGB
    assert red == green == 0 and blue > 150
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    return int(numpy.count_nonzero((b >= 90) & (r <= 60) & (g <= 60)))


def rate_hz(text: str) -> float:
    """Parse the topic list's frequency column ('49.89 Hz'); 0 when there is none."""
    match = re.match(r'([\d.]+) Hz', text or '')
    return float(match.group(1)) if match else 0.0


def test_studio_shows_topics_rates_and_the_robot(browser_tools, tmp_path):
    """The topic list has every topic with its rate; the 3D panel draws R2D2 from the URDF."""
    chromium, studio, install_s = browser_tools
    print(f'browser tools ready in {install_s:.1f} s')
    recording = tmp_path / 'run.mcap'
    port = harness.free_port()
    sim = SimProcess(foxglove_port=port, record=str(recording), **SIMULATOR)
    relay = server = browser = None
    try:
        sim.send_cmd_vel(linear=0.2, angular=0.3)  # a circle of 0.67 m, inside the room
        relay = harness.Relay(port)
        server = harness.StaticServer(studio, files_dir=tmp_path)
        started = time.monotonic()
        browser = harness.Chromium(chromium, server.url(
            f'/index.html?ds=foxglove-websocket&ds.url={relay.url}'))
        assert browser.wait_for('window.r2d2HostReady || window.r2d2HostError', 60) is True, \
            browser.evaluate('window.r2d2HostError')

        # Studio's rate estimate starts high while the first messages arrive in
        # a burst: wait until every rate has settled near its true value.
        def settled(stats):
            return all(rate_hz(stats.get(f'{t} frequency')) == pytest.approx(hz, rel=0.25)
                       for t, hz in RATES.items())
        stats = {}
        deadline = time.monotonic() + 120
        while not settled(stats) and time.monotonic() < deadline:
            time.sleep(0.5)
            stats = browser.evaluate(TOPIC_STATS) or {}
        assert settled(stats), {t: stats.get(f'{t} frequency') for t in RATES}
        for topic in LATCHED:  # listed, and received (a count of at least 1)
            assert stats[f'{topic} count'].replace(',', '').isdigit(), (topic, stats)

        box = browser.evaluate(CANVAS_3D)
        assert box and box['width'] > 300, box
        pixels = 0
        deadline = time.monotonic() + 60
        while pixels < MIN_ROBOT_PIXELS and time.monotonic() < deadline:
            pixels = robot_pixels(browser.screenshot(clip=box))
        assert pixels >= MIN_ROBOT_PIXELS, f'{pixels} robot-blue pixels in the 3D panel'
        print(f'live view checked {time.monotonic() - started:.1f} s after opening the page; '
              f'{pixels} robot pixels')
        screenshot = browser.screenshot()
        (tmp_path / 'foxglove_view.png').write_bytes(screenshot)
        if os.environ.get('R2D2_SIM_UPDATE_DOCS') == '1':
            (REPO / 'docs' / 'foxglove_view.png').write_bytes(screenshot)

        # The recording, opened as a remote file once the node has closed it.
        assert sim.stop().returncode == 0
        browser.call('Page.navigate', url=server.url(
            f'/index.html?ds=remote-file&ds.url={server.url("/files/run.mcap")}'))
        assert browser.wait_for('window.r2d2HostReady || window.r2d2HostError', 60) is True
        listed = browser.wait_for(
            "[...document.querySelectorAll('[data-topic-stat=count]')]"
            ".map(e => e.dataset.topic)", 60)
        assert set(RATES) | set(LATCHED) <= set(listed or ()), listed
    finally:
        for part in (browser, relay, server):
            if part is not None:
                part.close()
        sim.stop()


def test_a_failing_farm_variations_recording_opens_in_studio(browser_tools, tmp_path):
    """A farm run into a box: its recording, kept on failure, lists its topics in Studio."""
    from r2d2_sim.farm import Box, run_scenario, Scenario
    from r2d2_sim.model.regions import circle_region
    chromium, studio, _ = browser_tools
    scenario = Scenario(obstacles=(Box(1.2, 0.0, 0.3, (0.3, 1.0, 0.5)),),
                        goal=circle_region(3.0, 0.0, 0.2), seed=11)
    outcome = run_scenario(scenario, lambda harness, _: harness.send_cmd_vel(linear=0.3),
                           seconds=5.0, record_failure=str(tmp_path / 'failed.mcap'))
    assert not outcome.passed and outcome.recording == str(tmp_path / 'failed.mcap')
    server = browser = None
    try:
        server = harness.StaticServer(studio, files_dir=tmp_path)
        browser = harness.Chromium(chromium, server.url(
            f'/index.html?ds=remote-file&ds.url={server.url("/files/failed.mcap")}'))
        assert browser.wait_for('window.r2d2HostReady || window.r2d2HostError', 60) is True, \
            browser.evaluate('window.r2d2HostError')
        listed = browser.wait_for(
            "[...document.querySelectorAll('[data-topic-stat=count]')]"
            ".map(e => e.dataset.topic)", 60)
        assert {'/clock', '/odom', '/scan', '/contacts'} <= set(listed or ()), listed
    finally:
        for part in (browser, server):
            if part is not None:
                part.close()
