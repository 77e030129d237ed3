"""The recording's message definitions need no rclpy: an interpreter without it builds them."""

import os
from pathlib import Path
import sys

from r2d2_sim.recording.message_definitions import message_definition


def test_no_rclpy_needed():
    """The module imports and builds definitions in an interpreter that has no rclpy."""
    code = ('import sys; sys.modules["rclpy"] = None; '
            'from r2d2_sim.recording.message_definitions import message_definition; '
            'print(len(message_definition("sensor_msgs/msg/LaserScan")))')
    import subprocess
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parent.parent.parent))
    result = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True,
                            text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert int(result.stdout) == len(message_definition('sensor_msgs/msg/LaserScan'))
