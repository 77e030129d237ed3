"""
The drive executable's ``main``, called in this process (its processes: system/test_demo.py).

``python -m r2d2_sim.apps.drive`` has no wrapper to set
ROS_AUTOMATIC_DISCOVERY_RANGE, and discovered over the network where the
``.venv/bin/drive`` wrapper and ``demo`` keep it on this host. ``main`` now
sets LOCALHOST before rclpy starts, unless the user set a range. No ROS is
started here: ``init_ros`` is replaced by one that reads the environment.
"""

import os
import threading

import pytest

from r2d2_sim.apps import drive


@pytest.mark.parametrize('given, used', [(None, 'LOCALHOST'), ('SUBNET', 'SUBNET')],
                         ids=['unset', 'the user\'s own'])
def test_drive_keeps_discovery_on_this_host_unless_told(monkeypatch, given, used):
    seen = []

    def init_ros(argv, prog):
        seen.append(os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE'))
        return False  # as after its one error line: main returns 2, nothing started
    if given is None:
        monkeypatch.delenv('ROS_AUTOMATIC_DISCOVERY_RANGE', raising=False)
    else:
        monkeypatch.setenv('ROS_AUTOMATIC_DISCOVERY_RANGE', given)
    monkeypatch.setattr(drive, 'init_ros', init_ros)
    monkeypatch.setattr(drive, 'stop_on_signals', threading.Event)  # pytest keeps its own
    assert drive.main(['drive', '--linear', '0.3']) == 2
    assert seen == [used]
