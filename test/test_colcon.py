"""
The `ros2 run` layout: colcon builds the package and the ament index finds sim_node.

`ros2 run r2d2_sim sim_node` executes <prefix>/lib/r2d2_sim/sim_node, where the
prefix comes from the ament index; this test resolves it the same way (the
ros2 CLI itself is not installable from PyPI) and starts the executable.
"""

import os
import shutil
import subprocess
import sys

from helpers import next_domain_id, REPO, ros_env, stop_process
import pytest

RESOLVE_AND_RUN = '''
set -e
source "$1/install/setup.bash"
prefix=$(python3 -c "from ament_index_python.packages import get_package_prefix as p
print(p('r2d2_sim'))")
exe="$prefix/lib/r2d2_sim/sim_node"
test -x "$exe"
echo "resolved $exe"
exec "$exe" --ros-args -p real_time_factor:=1.0
'''


@pytest.fixture(scope='module')
def colcon_workspace(tmp_path_factory):
    """Build the package with colcon into a temporary workspace."""
    colcon = shutil.which('colcon') or os.path.join(os.path.dirname(sys.executable), 'colcon')
    ws = tmp_path_factory.mktemp('ws')
    env = dict(os.environ)
    env['PATH'] = os.path.dirname(sys.executable) + os.pathsep + env.get('PATH', '')
    result = subprocess.run(
        [colcon, '--log-base', str(ws / 'log'), 'build', '--base-paths', REPO,
         '--build-base', str(ws / 'build'), '--install-base', str(ws / 'install')],
        cwd=ws, env=env, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    return ws


def test_colcon_installs_executables_and_data(colcon_workspace):
    """lib/r2d2_sim holds the three executables; share/ holds package.xml and the URDF."""
    prefix = colcon_workspace / 'install' / 'r2d2_sim'
    for exe in ('sim_node', 'demo', 'drive'):
        assert os.access(prefix / 'lib' / 'r2d2_sim' / exe, os.X_OK), exe
    assert (prefix / 'share' / 'r2d2_sim' / 'package.xml').is_file()
    assert (prefix / 'share' / 'r2d2_sim' / 'urdf' / 'r2d2.urdf').is_file()
    marker = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / 'r2d2_sim'
    assert marker.is_file()


def test_sim_node_resolved_through_ament_index_starts(colcon_workspace):
    """The executable found as `ros2 run` would find it publishes joint_states, stops on SIGINT."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState
    import time

    domain = next_domain_id()
    env = ros_env(domain)
    env['PYTHONPATH'] = ''  # only what install/setup.bash provides
    env['PATH'] = os.path.dirname(sys.executable) + os.pathsep + env.get('PATH', '')
    process = subprocess.Popen(['bash', '-c', RESOLVE_AND_RUN, 'run', str(colcon_workspace)],
                               cwd=colcon_workspace, env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain)
    node = rclpy.create_node('colcon_probe', context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    received = []
    node.create_subscription(JointState, 'joint_states', received.append, 10)
    try:
        deadline = time.monotonic() + 20.0
        while not received and time.monotonic() < deadline and process.poll() is None:
            executor.spin_once(timeout_sec=0.05)
    finally:
        code, out, err = stop_process(process)
        node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=ctx)
    assert received, out + err
    assert code == 0, err
    assert 'resolved' in out and str(colcon_workspace) in out
    assert 'share/r2d2_sim/urdf/r2d2.urdf' in err + out  # the installed URDF, not the source one
