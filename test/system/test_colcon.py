"""
The `ros2 run` layout: colcon builds the package and the ament index finds sim_node.

`ros2 run r2d2_sim sim_node` executes <prefix>/lib/r2d2_sim/sim_node, where the
prefix comes from the ament index; this test resolves it the same way (the
ros2 CLI itself is not installable from PyPI) and starts the executable.
simulation_interfaces comes from the system package where a ROS Jazzy install
has it for this Python (``/opt/ros/jazzy``, sourced first), else from the
venv's local build (tools/build_interfaces.sh); the started node serves the
standard either way, which needs the type support, not only the Python files.
"""

import json
import os
import shutil
import subprocess
import sys

from helpers import next_domain_id, REPO, ros_env, stop_process
import pytest

SYSTEM_ROS = '/opt/ros/jazzy'
RESOLVE_AND_RUN = '''
set -e
if [ -n "$2" ]; then source "$2/setup.bash"; fi
source "$1/install/setup.bash"
python3 -c "import os, simulation_interfaces as s
print('interfaces', os.path.dirname(s.__file__))"
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
    """
    The executable found as `ros2 run` would find it publishes joint_states, stops on SIGINT.

    It serves the simulation standard, from the system's simulation_interfaces
    when there is one, else from the local build.
    """
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState
    from simulation_interfaces.msg import SimulatorFeatures
    from simulation_interfaces.srv import GetSimulatorFeatures
    import time
    from r2d2_sim.client import spin_until
    from r2d2_sim.testing.remote import send_request

    # The system's packages only for the Python they were built for: sourcing
    # /opt/ros/jazzy puts them ahead of the venv's on PYTHONPATH.
    python = f'python{sys.version_info.major}.{sys.version_info.minor}'
    system = os.path.isdir(os.path.join(SYSTEM_ROS, 'lib', python, 'site-packages',
                                        'simulation_interfaces'))

    domain = next_domain_id()
    env = ros_env(domain)
    env['PYTHONPATH'] = ''  # only what install/setup.bash provides
    env['PATH'] = os.path.dirname(sys.executable) + os.pathsep + env.get('PATH', '')
    process = subprocess.Popen(['bash', '-c', RESOLVE_AND_RUN, 'run', str(colcon_workspace),
                                SYSTEM_ROS if system else ''],
                               cwd=colcon_workspace, env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain)
    node = rclpy.create_node('colcon_probe', context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    received = []
    node.create_subscription(JointState, 'joint_states', received.append, 10)
    features = node.create_client(GetSimulatorFeatures, '/get_simulator_features')
    reply = None
    try:
        deadline = time.monotonic() + 20.0
        while not received and time.monotonic() < deadline and process.poll() is None:
            executor.spin_once(timeout_sec=0.05)
        while not features.service_is_ready() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        # Sent again after 1 s without a reply (rmw_fastrtps drops a reply when the server
        # has not yet discovered the client's reply reader 100 ms after the request).
        reply = send_request(features, GetSimulatorFeatures.Request(),
                             lambda done, timeout_s: spin_until(executor, done, timeout_s),
                             max(deadline - time.monotonic(), 0.0), resend_after_s=1.0)
    finally:
        code, out, err = stop_process(process)
        node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=ctx)
    assert received, out + err
    assert code == 0, err
    assert 'resolved' in out and str(colcon_workspace) in out
    assert 'share/r2d2_sim/urdf/r2d2.urdf' in err + out  # the installed URDF, not the source one
    assert reply is not None, out + err
    assert SimulatorFeatures.SPAWNING in reply.features.features
    assert json.loads(reply.features.custom_info)['simulator'] == 'r2d2_sim'
    interfaces = next((line for line in out.splitlines() if line.startswith('interfaces ')), '')
    assert interfaces, out + err
    expected = SYSTEM_ROS if system else os.path.dirname(os.path.dirname(sys.executable))
    assert interfaces.split(' ', 1)[1].startswith(expected), interfaces
