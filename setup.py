"""Packaging for r2d2_sim (ament_python): executables go to lib/r2d2_sim for `ros2 run`."""

from glob import glob
import os
import runpy

from setuptools import find_packages, setup

package_name = 'r2d2_sim'

# What the package imports at run time, so that `pip install .` alone gives a
# working sim_node, demo and pytest plugin. ROS is pinned to Jazzy through the
# ros-jazzy-* names (the unprefixed ros-* names resolve to a newer distribution),
# at the versions of requirements.txt (test_install.py checks they agree).
# Under colcon these come from the ROS install instead (package.xml).
INSTALL_REQUIRES = [
    'setuptools',
    'ros-jazzy-rclpy[fastrtps]==7.1.6',        # rclpy, rcl_interfaces, rosgraph_msgs, ament_index
    'ros-jazzy-common-interfaces==5.3.6',      # geometry, sensor, nav, std msgs; std_srvs
    'ros-jazzy-rosidl-parser==4.6.6',          # serialization.py reads message definitions
    'pybullet==3.2.7',
    'numpy>=1.24,<3',
    # The standard's entity filters are regular expressions from any peer: RE2
    # matches in linear time (Python's re backtracks, exponentially).
    'google-re2>=1.1,<2',
    # World manifests (*.world.yaml), read with its safe loader. ros-jazzy-rclpy
    # brings it already; declared because r2d2_sim imports it itself.
    'PyYAML>=5.4',
    # SDF worlds and models (Gazebo's): XML from any peer read with defusedxml (no
    # DOCTYPE, no entities); COLLADA meshes with pycollada, STL and OBJ with trimesh.
    'defusedxml>=0.7,<0.8',
    'pycollada>=0.9,<0.10',
    'trimesh>=4,<6',
    # The demo executable, installed with the package, writes its plot with it.
    'matplotlib>=3.6,<4',
    # The live view (foxglove_port), MCAP recording (record) and the replay tool;
    # one abi3 wheel with no dependencies. Under colcon: pip install foxglove-sdk mcap.
    'foxglove-sdk>=0.30,<0.31',
    'mcap>=1.2,<2',
    # The scenario farm draws and shrinks scenarios with it (r2d2_sim.farm).
    'hypothesis>=6.100,<7',
]

# OpenSCENARIO scenarios through scenario_execution (r2d2_sim.osc): an extra, because
# scenario_execution pins its dependencies exactly (docs/scenarios.md says what that
# changes: PyYAML 6.0.1 in place of the 6.0.4 the ROS wheels bring, py-trees 2.4.0,
# antlr4-python3-runtime 4.9.2). Its entry points come from the package's one table of
# them, read without importing the package.
EXTRAS_REQUIRE = {'scenarios': ['scenario_execution==1.8.0']}
OSC_ENTRY_POINTS = runpy.run_path(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), 'r2d2_sim', 'osc', 'entry_points.py')
)['ENTRY_POINTS']
# Optional: `pip install r2d2_sim[gym]` for the learning environments (r2d2_sim.gym),
# `[rl]` adds the libraries of its recipes (Stable-Baselines3, RLlib on Ray), so that
# `pip install .` stays lean. RLlib's own extra pins Gymnasium 1.2.2: its dependencies
# are named here instead (it runs on Gymnasium 1.4).
GYM_REQUIRES = ['gymnasium>=1.4,<1.5', 'pettingzoo>=1.27,<1.28']
RL_REQUIRES = GYM_REQUIRES + [
    'stable-baselines3>=2.9,<3', 'ray>=2.60,<3', 'dm_tree', 'lz4', 'ormsgpack>=1.7.0', 'pandas',
    'pyarrow>=17.0.0', 'pydantic>=2.5,<3', 'requests', 'scipy', 'tensorboardX>=1.9']

setup(
    name=package_name,
    version='0.2.0',
    packages=find_packages(exclude=['test']),
    # PEP 561: the marker tells type checkers that r2d2_sim's own hints are to be read.
    package_data={package_name: ['py.typed'], package_name + '.osc': ['lib_osc/*.osc']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/urdf', glob('urdf/*')),
        ('share/' + package_name + '/foxglove', ['config/foxglove_layout.json']),
        ('share/' + package_name + '/launch', ['launch/sim.launch.xml']),
        ('share/' + package_name + '/rviz', ['config/r2d2_sim.rviz']),
    ],
    install_requires=INSTALL_REQUIRES,
    # The farm runner's cluster executors, imported only when chosen
    # (python -m r2d2_sim.farm run --executor ray|dask); requirements.txt pins them for tests.
    extras_require={**EXTRAS_REQUIRE, 'gym': GYM_REQUIRES, 'rl': RL_REQUIRES,
                    'ray': ['ray>=2.60,<3'], 'dask': ['dask[distributed]>=2026.8']},
    python_requires='>=3.10',
    # A zipped egg would hide py.typed from type checkers (PEP 561).
    zip_safe=False,
    maintainer='r2d2_sim maintainers',
    maintainer_email='maintainers@r2d2-sim.dev',
    description='A ROS 2 node that simulates R2D2 in PyBullet.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'sim_node = r2d2_sim.apps.sim_node:main',
            'demo = r2d2_sim.apps.demo:main',
            'drive = r2d2_sim.apps.drive:main',
            'replay = r2d2_sim.apps.replay:main',
            'sim_conformance = r2d2_sim.conformance.cli:main',
        ],
        'pytest11': ['r2d2_sim.pytest_plugin = r2d2_sim.pytest_plugin',
                     'r2d2_sim.farm.pytest_plugin = r2d2_sim.farm.pytest_plugin'],
        **OSC_ENTRY_POINTS,
    },
)
