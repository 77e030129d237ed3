"""The transform buffer of model/test_tf_buffer.py needs no ROS: a fresh interpreter proves it."""

import subprocess
import sys


def test_the_module_needs_no_ros():
    """Importing it loads neither rclpy nor any message package."""
    code = ('import sys, r2d2_sim.model.tf_buffer; '
            'print(sorted(m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "tf2_msgs", "geometry_msgs", "pybullet", "numpy")))')
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=60, check=True)
    assert result.stdout.strip().splitlines()[-1] == '[]'
