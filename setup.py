"""Packaging for r2d2_sim (ament_python): executables go to lib/r2d2_sim for `ros2 run`."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'r2d2_sim'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/urdf', glob('urdf/*')),
        ('share/' + package_name + '/foxglove', ['resource/foxglove_layout.json']),
    ],
    install_requires=['setuptools'],
    # The live view and MCAP recording (foxglove_sink) and the replay tool.
    extras_require={'foxglove': ['foxglove-sdk>=0.30,<0.31', 'mcap>=1.2,<2']},
    zip_safe=True,
    maintainer='r2d2_sim maintainers',
    maintainer_email='maintainers@r2d2-sim.dev',
    description='A ROS 2 node that simulates R2D2 in PyBullet.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'sim_node = r2d2_sim.sim_node:main',
            'demo = r2d2_sim.demo:main',
            'drive = r2d2_sim.drive_cmd:main',
            'replay = r2d2_sim.replay:main',
        ],
        'pytest11': ['r2d2_sim.pytest_plugin = r2d2_sim.pytest_plugin'],
    },
)
